//! Text of bounded length for messages and logs: a refusal never repeats a payload whole.

use std::borrow::Cow;

/// The first `max` bytes of `text` (cut at a character's boundary) and `…` when it is longer.
pub(crate) fn excerpt(text: &str, max: usize) -> Cow<'_, str> {
    if text.len() <= max {
        return Cow::Borrowed(text);
    }
    let mut end = max;
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    Cow::Owned(format!("{}…", &text[..end]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_excerpt_is_cut_at_a_character_boundary_with_an_ellipsis() {
        assert_eq!(excerpt("short", 10), "short");
        // `é` is two bytes: cut before it rather than inside it.
        assert_eq!(excerpt("abcé", 4), "abc…");
        assert_eq!(excerpt("abcdef", 3), "abc…");
    }
}
