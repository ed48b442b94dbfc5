//! `text`: no control or text-direction characters anywhere in a spec. Spec text reaches the
//! generated code as names, strings and doc comments; a right-to-left override there hides
//! what the code says and fails rustc's default lints (`text_direction_codepoint_in_literal`).
//!
//! This rule reads the parsed tree rather than the model, so that it covers every key and
//! value, including ones added to the spec language later.

use crate::diagnostic::{Diagnostic, Label, Location};
use crate::source::{Node, Span, Value};

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

/// Checks every scalar of the tree.
pub fn check(root: Option<&Node>) -> Vec<Diagnostic> {
    let mut out = Vec::new();
    if let Some(root) = root {
        walk(root, &mut out);
    }
    out
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
