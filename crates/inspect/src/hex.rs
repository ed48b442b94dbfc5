//! Bytes as hex text, both ways: `01 04 0C` for people, and whatever a capture or a person
//! writes back into bytes.

use std::fmt;

use optobus_codec::Hex;

/// `01 04 0C`: bytes in hex, space separated.
pub fn hex(bytes: &[u8]) -> String {
    Hex(bytes).to_string()
}

/// Why [`parse_hex`] refused a text; `Display` gives one line for people.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum HexError {
    /// A token that is not hex digits.
    NotHex(String),
    /// A token of three or more digits, an odd number of them.
    OddDigits(String),
    /// No bytes at all.
    Empty,
}

impl fmt::Display for HexError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotHex(token) => write!(f, "`{token}` is not hex"),
            Self::OddDigits(token) => write!(f, "`{token}` has an odd number of hex digits"),
            Self::Empty => f.write_str("no bytes given"),
        }
    }
}

impl std::error::Error for HexError {}

/// The bytes `text` gives in hex: spaces (or `,`, `:`, `;`) optional, `0x` prefixes allowed;
/// a token of one or two digits is one byte, longer ones are byte pairs (`010400000002 71CB`).
pub fn parse_hex(text: &str) -> Result<Vec<u8>, HexError> {
    let mut bytes = Vec::new();
    let separators = |c: char| c.is_whitespace() || matches!(c, ',' | ':' | ';');
    for token in text.split(separators).filter(|t| !t.is_empty()) {
        let digits = token
            .strip_prefix("0x")
            .or_else(|| token.strip_prefix("0X"))
            .unwrap_or(token);
        let nibbles: Option<Vec<u8>> = digits
            .chars()
            .map(|c| c.to_digit(16).and_then(|d| u8::try_from(d).ok()))
            .collect();
        let nibbles = match nibbles {
            Some(n) if !n.is_empty() => n,
            _ => return Err(HexError::NotHex(token.to_owned())),
        };
        match nibbles.as_slice() {
            [low] => bytes.push(*low),
            _ if nibbles.len() % 2 == 1 => return Err(HexError::OddDigits(token.to_owned())),
            _ => bytes.extend(nibbles.chunks(2).map(|pair| match pair {
                [high, low] => (high << 4) | low,
                _ => 0,
            })),
        }
    }
    if bytes.is_empty() {
        return Err(HexError::Empty);
    }
    Ok(bytes)
}
