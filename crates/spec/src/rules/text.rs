//! `text`: no control or text-direction characters anywhere in a spec. Spec text reaches the
//! generated code as names, strings and doc comments; a right-to-left override there hides
//! what the code says and fails rustc's default lints (`text_direction_codepoint_in_literal`).
//!
//! This rule reads the parsed tree rather than the model, so that it covers every key and
//! value, including ones added to the spec language later.

use crate::diagnostic::{Diagnostic, Label, Location};
use crate::source::{Node, SourceFile, Span, Value};

/// Rule name.
pub const RULE: &str = "text";

/// Why `c` may not appear in a spec, if it may not.
pub fn forbidden(c: char) -> Option<&'static str> {
    match c {
        '\n' | '\t' => None,
        '\u{202A}'..='\u{202E}'
        | '\u{2066}'..='\u{2069}'
        | '\u{200E}'
        | '\u{200F}'
        | '\u{061C}' => Some("a text-direction control character"),
        c if c.is_control() => Some("a control character"),
        _ => None,
    }
}

/// Checks every scalar of the tree: first all their text in one sweep, and only when that
/// finds a forbidden character, scalar by scalar to place it.
pub fn check(source: &SourceFile) -> Vec<Diagnostic> {
    let mut out = Vec::new();
    if let Some(root) = source.root.as_ref().filter(|_| !clean(source.scalars())) {
        walk(root, &mut out);
    }
    out
}

/// True when `text` holds no character [`forbidden`] refuses. One sweep over the bytes that
/// decodes only the characters that may be refused: ASCII controls, and those whose UTF-8
/// starts like U+0080–U+00BF (`C2`), U+061C (`D8`) or U+2000–U+20BF (`E2`).
fn clean(text: &str) -> bool {
    text.bytes().enumerate().all(|(at, byte)| {
        let suspect = byte < b' ' || byte == 0x7F || matches!(byte, 0xC2 | 0xD8 | 0xE2);
        !suspect || text[at..].chars().next().and_then(forbidden).is_none()
    })
}

fn walk(node: &Node, out: &mut Vec<Diagnostic>) {
    match &node.value {
        Value::Scalar { text, .. } => scalar(text, node.span, out),
        Value::Sequence(items) => items.iter().for_each(|item| walk(item, out)),
        Value::Mapping(entries) => {
            for (key, value) in entries {
                walk(key, out);
                walk(value, out);
            }
        }
    }
}

fn scalar(text: &str, span: Span, out: &mut Vec<Diagnostic>) {
    // Printable ASCII (most of a spec) needs no look at each character.
    if text
        .bytes()
        .all(|b| matches!(b, b' '..=b'~' | b'\n' | b'\t'))
    {
        return;
    }
    let Some((c, why)) = text.chars().find_map(|c| forbidden(c).map(|why| (c, why))) else {
        return;
    };
    out.push(Diagnostic {
        rule: RULE,
        message: format!("this text holds {why} (U+{:04X})", u32::from(c)),
        primary: Label {
            location: Location::Span(span),
            text: "invisible character in here".into(),
        },
        secondary: Vec::new(),
        help: Some(
            "remove it: spec text becomes generated code and documentation; \
             write line breaks with a block scalar (`|`)"
                .into(),
        ),
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sweep_passes_what_the_walk_passes_and_stops_at_what_it_refuses() {
        // Lead bytes C2 and E2 that start allowed characters: `°`, `–`, `€`; and CJK text.
        assert!(clean("寄存器 20 °C – 5 € line\nnext\ttab"));
        for refused in [
            "a\u{202E}b",
            "\u{85}",
            "x\ry",
            "\u{7F}",
            "\u{061C}",
            "\u{2066}",
            "\0",
        ] {
            assert!(!clean(refused), "{refused:?}");
            assert!(
                refused.chars().any(|c| forbidden(c).is_some()),
                "{refused:?}"
            );
        }
    }
}
