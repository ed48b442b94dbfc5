//! Values typed by people turned into a register's validated words: engineering units
//! (`100us`, `42.5`), code names or the manual's own words for a code, `name=value` fields.

use std::fmt;
use std::net::Ipv4Addr;

use optobus_codec::value::{Fixed, ParseFixedError, Scale};
use optobus_device::{CodeInfo, RegisterInfo, ValueKind};
use optobus_driver::{encode_code, encode_packed, Encode};

use crate::value::range_text;

/// Why [`parse_value`] refused a text; `Display` gives one line for people.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ParseError {
    /// The register cannot be written (`` `distance_1` is read-only ``).
    ReadOnly {
        /// Register name.
        register: &'static str,
    },
    /// A version or record register, written by no one (`` `firmware` cannot be written ``).
    NotWritable {
        /// Register name.
        register: &'static str,
    },
    /// The register does not take `text` (`` `light_power` does not take `100.1`: allowed
    /// 0.5 % ..= 100.0 % ``).
    Refused {
        /// Register name.
        register: &'static str,
        /// The text given.
        text: String,
        /// Why not, and what it takes instead.
        reason: String,
    },
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::ReadOnly { register } => write!(f, "`{register}` is read-only"),
            Self::NotWritable { register } => write!(f, "`{register}` cannot be written"),
            Self::Refused {
                register,
                text,
                reason,
            } => write!(f, "`{register}` does not take `{text}`: {reason}"),
        }
    }
}

impl std::error::Error for ParseError {}

/// The validated words (in address order) that store `text` in `register`, checked as the
/// driver checks a typed write: range, defined codes, packed fields, exact steps.
///
/// `text` is what a person types: `true`/`on`/`1` for a flag; a number with or without the
/// register's unit (`100us`, `100 µs`, `42.5`); a code's name, the manual's meaning or the
/// number (`0x10` too); packed fields as `name=value` pairs; an IPv4 address.
pub fn parse_value(register: &'static RegisterInfo, text: &str) -> Result<Vec<u16>, ParseError> {
    let refuse = |reason: String| ParseError::Refused {
        register: register.name,
        text: text.to_owned(),
        reason,
    };
    if !register.access.writable() {
        return Err(ParseError::ReadOnly {
            register: register.name,
        });
    }
    let result = match register.kind {
        ValueKind::Bool => {
            let value = match text.trim().to_ascii_lowercase().as_str() {
                "1" | "true" | "on" | "yes" => true,
                "0" | "false" | "off" | "no" => false,
                _ => return Err(refuse("use true/false, on/off or 1/0".into())),
            };
            value.encode(register)
        }
        ValueKind::Enum => {
            let Some(code) = parse_code(register.codes, text) else {
                return Err(refuse(format!("codes are {}", code_list(register.codes))));
            };
            encode_code(register, code)
        }
        ValueKind::Scalar(_) => parse_quantity(register, text)
            .map_err(refuse)?
            .encode(register),
        ValueKind::Packed(fields) => {
            let mut bits = 0u32;
            for field in fields {
                let given = text.split([',', ' ']).find_map(|part| {
                    let (name, value) = part.split_once('=')?;
                    (name.trim() == field.name).then_some(value)
                });
                let Some(given) = given else {
                    let names: Vec<&str> = fields.iter().map(|f| f.name).collect();
                    return Err(refuse(format!(
                        "give every field as name=value: {}",
                        names.join(", ")
                    )));
                };
                let raw = if field.codes.is_empty() {
                    parse_integer(given).and_then(|n| u32::try_from(n).ok())
                } else {
                    parse_code(field.codes, given)
                };
                let Some(raw) = raw else {
                    let takes = if field.codes.is_empty() {
                        "a whole number".to_owned()
                    } else {
                        code_list(field.codes)
                    };
                    return Err(refuse(format!("`{}` takes {takes}", field.name)));
                };
                bits |= raw.checked_shl(u32::from(field.lsb)).unwrap_or(u32::MAX);
            }
            encode_packed(register, Some(bits))
        }
        ValueKind::Ipv4 => {
            let address: Ipv4Addr = text
                .trim()
                .parse()
                .map_err(|_| refuse("not an IPv4 address".into()))?;
            address.encode(register)
        }
        ValueKind::Version(_) | ValueKind::Record(_) => {
            return Err(ParseError::NotWritable {
                register: register.name,
            })
        }
    };
    result.map_err(|error| {
        refuse(match error {
            optobus_driver::Error::OutOfRange { .. } => format!(
                "allowed {}",
                range_text(register).unwrap_or_else(|| "values that fit the register".into())
            ),
            optobus_driver::Error::NotRepresentable { scale, .. } => format!(
                "it holds whole steps of {}{}",
                scale.step(),
                register.unit.map(|u| format!(" {u}")).unwrap_or_default()
            ),
            optobus_driver::Error::UndefinedCode {
                field: Some(field), ..
            } => format!("`{field}` has no such code"),
            other => other.to_string(),
        })
    })
}

/// Lower case, alphanumerics only: `100 us`, `100us` and `US_100` compare alike once sorted.
fn tokens(text: &str) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let mut current = String::new();
    let mut last_digit = None;
    for c in text.chars() {
        let digit = c.is_ascii_digit() || c == '.';
        if !c.is_alphanumeric() && c != '.' {
            if !current.is_empty() {
                out.push(std::mem::take(&mut current));
            }
            last_digit = None;
            continue;
        }
        if last_digit.is_some_and(|d| d != digit) && !current.is_empty() {
            out.push(std::mem::take(&mut current));
        }
        current.extend(c.to_lowercase());
        last_digit = Some(digit);
    }
    if !current.is_empty() {
        out.push(current);
    }
    out.sort();
    out
}

/// The code a person means by `text`: its name, the manual's words, or the number.
fn parse_code(codes: &'static [CodeInfo], text: &str) -> Option<u32> {
    let text = text.trim();
    if let Some(found) = codes
        .iter()
        .find(|c| c.name.eq_ignore_ascii_case(text) || c.meaning == text)
    {
        return Some(found.code);
    }
    let wanted = tokens(&text.replace('_', "."));
    if let Some(found) = codes
        .iter()
        .find(|c| tokens(&c.name.replace('_', ".")) == wanted || tokens(c.meaning) == wanted)
    {
        return Some(found.code);
    }
    parse_integer(text).and_then(|n| u32::try_from(n).ok())
}

/// `42` or `0x2A`.
fn parse_integer(text: &str) -> Option<i64> {
    let text = text.trim();
    match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => i64::from_str_radix(hex, 16).ok(),
        None => text.parse().ok(),
    }
}

/// `name (code), …`: the codes of a register or field, as messages list them.
pub fn code_list(codes: &[CodeInfo]) -> String {
    let names: Vec<String> = codes
        .iter()
        .map(|c| format!("{} ({})", c.name, c.code))
        .collect();
    names.join(", ")
}

/// Unit spellings people type for the unit a spec names.
fn unit_spellings(unit: &str) -> &'static [&'static str] {
    match unit {
        "us" => &["us", "µs", "μs"],
        "mm" => &["mm"],
        "%" => &["%"],
        "degC" => &["degC", "°C", "℃", "C"],
        "uV" => &["uV", "µV"],
        _ => &[],
    }
}

/// SI prefixes people type, with their powers of ten (`u` and both micro signs alike).
const PREFIXES: [(&str, i8); 8] = [
    ("n", -9),
    ("u", -6),
    ("µ", -6),
    ("μ", -6),
    ("m", -3),
    ("k", 3),
    ("M", 6),
    ("", 0),
];

/// SI units whose prefixed forms convert into one another (`ms` into `us`, `um` into `mm`).
const SI_BASES: [&str; 5] = ["s", "m", "V", "A", "Hz"];

/// `unit` as a power of ten of an SI base unit: `us` is (-6, `s`), `mm` (-3, `m`).
fn si_parts(unit: &str) -> Option<(i8, &str)> {
    PREFIXES.iter().find_map(|(prefix, power)| {
        let base = unit.strip_prefix(prefix)?;
        SI_BASES.contains(&base).then_some((*power, base))
    })
}

/// `unit` as a power of ten of its base unit, for outputs that take base units (Prometheus):
/// `mm` is 10^-3 `m`, `us` 10^-6 `s`, `%` 10^-2 of a plain ratio (`""`), `degC` is `degC`.
/// `None` for a unit with no base unit known here.
pub fn base_unit(unit: &str) -> Option<(i8, &'static str)> {
    match unit {
        "%" => Some((-2, "")),
        "degC" | "°C" | "℃" => Some((0, "degC")),
        _ => {
            let (power, base) = si_parts(unit)?;
            SI_BASES.iter().find(|b| **b == base).map(|b| (power, *b))
        }
    }
}

/// `value` in `unit` converted to its [`base_unit`], rounded once to the nearest `f64`
/// (`4.969234` mm is `0.004969234` m), with the base unit.
pub fn in_base_unit(value: Fixed, unit: &str) -> Option<(f64, &'static str)> {
    let (power, base) = base_unit(unit)?;
    let shifted = match value.scale() {
        Scale::Decimal { exponent } => exponent
            .checked_add(power)
            .map(|exponent| Fixed::new(value.raw(), Scale::Decimal { exponent }).to_f64()),
        Scale::Ratio { .. } => None,
    };
    let number = shifted.unwrap_or_else(|| value.to_f64() * 10f64.powi(i32::from(power)));
    Some((number, base))
}

/// The number in `text` in the register's unit, exactly: bare, with the register's own unit
/// (`100us`, `100 µs`), or with another SI prefix of the same base unit (`0.2ms` for a `us`
/// register, `1500 um` for a `mm` one). A result the register's steps cannot hold exactly is
/// refused later, by the encoding.
fn parse_quantity(register: &RegisterInfo, text: &str) -> Result<Fixed, String> {
    let text = text.trim();
    let split = text
        .find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | '-' | '+')))
        .unwrap_or(text.len());
    let (number, unit) = (text[..split].trim(), text[split..].trim());
    let exponent = unit.strip_prefix(['e', 'E']).is_some_and(|rest| {
        rest.trim_start_matches(['-', '+'])
            .starts_with(|c: char| c.is_ascii_digit())
    });
    if exponent && !number.is_empty() {
        return Err(format!(
            "write the number as a plain decimal (`10`, `0.001`), not with an exponent (`{text}`)"
        ));
    }
    let not_a_number = |error: ParseFixedError| match error {
        // Too long for 64 bits at its own last digit: the register's steps say what fits.
        ParseFixedError::TooManyDigits | ParseFixedError::OutOfRange => match register.scale {
            Some(scale) => format!(
                "it holds whole steps of {}{}",
                scale.step(),
                register.unit.map(|u| format!(" {u}")).unwrap_or_default()
            ),
            None => format!("`{number}` has too many digits to be held exactly"),
        },
        _ => {
            let unit = register.unit.map(|u| format!(" in {u}"));
            format!("not a number{}", unit.unwrap_or_default())
        }
    };
    let value: Fixed = number.parse().map_err(not_a_number)?;
    let own = register.unit.unwrap_or("");
    if unit.is_empty() || unit == own || unit_spellings(own).contains(&unit) {
        return Ok(value);
    }
    let converted = match (si_parts(unit), si_parts(own), value.scale()) {
        (Some((given, base)), Some((wanted, own_base)), Scale::Decimal { exponent })
            if base == own_base =>
        {
            exponent
                .checked_add(given)
                .and_then(|e| e.checked_sub(wanted))
                .map(|exponent| Fixed::new(value.raw(), Scale::Decimal { exponent }))
        }
        _ => None,
    };
    converted.ok_or_else(|| match (register.unit, si_parts(own)) {
        (None, _) => format!("`{unit}` given, but the register has no unit"),
        (Some(own), Some((_, base))) => format!(
            "`{unit}` is not a unit of the register: it is in {own} (other prefixes of {base} \
             convert, e.g. m{base}, u{base})"
        ),
        (Some(own), None) => format!("`{unit}` is not a unit of the register: it is in {own}"),
    })
}
