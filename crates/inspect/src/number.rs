//! 16-bit numbers (addresses, raw register values, counts) as people write them: decimal or
//! `0x` hex.

use crate::error::Error;

/// `text` as a 16-bit number: decimal (`16`) or hex with a `0x` prefix (`0x10`, `0X0010`);
/// `what` names it in the error (`a register address`).
pub fn parse_number(text: &str, what: &str) -> Result<u16, Error> {
    let text = text.trim();
    let hex = text.strip_prefix("0x").or_else(|| text.strip_prefix("0X"));
    let digits_ok = match hex {
        Some(digits) => !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_hexdigit()),
        None => !text.is_empty() && text.bytes().all(|b| b.is_ascii_digit()),
    };
    let range = "0 to 65535, or 0x0000 to 0xFFFF";
    if !digits_ok {
        return Err(Error::new(format!("`{text}` is not {what}")).hint(range));
    }
    let digits = hex.unwrap_or(text).trim_start_matches('0');
    let parsed = match hex {
        Some(_) if digits.len() <= 4 => u16::from_str_radix(digits, 16).ok(),
        None if digits.len() <= 5 => digits
            .parse::<u32>()
            .ok()
            .and_then(|n| u16::try_from(n).ok()),
        _ => None,
    };
    let parsed = if digits.is_empty() { Some(0) } else { parsed };
    parsed.ok_or_else(|| {
        Error::new(format!(
            "`{text}` is too large for {what}: a register holds 16 bits"
        ))
        .hint(range)
    })
}

/// `0x0010 (16)`: a 16-bit number in hex and decimal, as the tool prints addresses and raw
/// words.
pub fn hex_and_decimal(number: u16) -> String {
    format!("{number:#06X} ({number})")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimal_and_hex_read_the_same_number() {
        assert_eq!(parse_number("16", "an address"), Ok(16));
        assert_eq!(parse_number("0x10", "an address"), Ok(16));
        assert_eq!(parse_number("0X0010", "an address"), Ok(16));
        assert_eq!(parse_number("65535", "an address"), Ok(0xFFFF));
        assert_eq!(parse_number("0xffff", "an address"), Ok(0xFFFF));
        assert_eq!(parse_number("000000000000012", "an address"), Ok(12));
        assert_eq!(parse_number("0x0", "an address"), Ok(0));
    }

    #[test]
    fn non_numbers_negatives_and_overflows_are_refused_with_the_range() {
        for text in ["", "0x", "-1", "1.5", "ten", "0x1g", "+3"] {
            let error = parse_number(text, "a value").unwrap_err();
            assert_eq!(error.message, format!("`{}` is not a value", text.trim()));
        }
        for text in ["65536", "0x10000", "99999999999999999999"] {
            let error = parse_number(text, "a value").unwrap_err();
            assert!(error.message.contains("too large"), "{error}");
            assert_eq!(
                error.hint.as_deref(),
                Some("0 to 65535, or 0x0000 to 0xFFFF")
            );
        }
    }

    #[test]
    fn numbers_print_in_hex_and_decimal() {
        assert_eq!(hex_and_decimal(16), "0x0010 (16)");
        assert_eq!(hex_and_decimal(0xFFFF), "0xFFFF (65535)");
    }
}
