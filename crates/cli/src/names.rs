//! Registers by name, their words decoded for people and scripts, and values typed by people
//! turned into validated words. Everything here works from a family's `DEVICE` description.

use std::fmt;
use std::net::Ipv4Addr;

use optobus_codec::value::{join_u32, Fixed, Scale};
use optobus_device::{CodeInfo, DeviceInfo, FieldInfo, RegisterInfo, Scalar, ValueKind};
use optobus_driver::{encode_code, encode_packed, raw_bits, Decode, Encode};
use serde_json::{json, Value as Json};

use crate::error::CliError;

/// The registers `name` stands for: a register, a repeat member (all copies, or copy `copy`),
/// or a group (its members, expanded the same way).
pub(crate) fn resolve(
    device: &'static DeviceInfo,
    name: &str,
    copy: Option<u8>,
) -> Result<Vec<&'static RegisterInfo>, CliError> {
    if let Some(group) = device.group(name) {
        let mut registers = Vec::new();
        for member in group.registers {
            registers.extend(resolve_register(device, member, copy)?);
        }
        return Ok(registers);
    }
    resolve_register(device, name, copy)
}

/// The readable registers behind `names`, in order, without repeats.
pub(crate) fn readable(
    device: &'static DeviceInfo,
    names: &[String],
    copy: Option<u8>,
) -> Result<Vec<&'static RegisterInfo>, CliError> {
    let mut registers: Vec<&'static RegisterInfo> = Vec::new();
    for name in names {
        for register in resolve(device, name, copy)? {
            if !register.access.readable() {
                return Err(CliError::new(format!("`{}` is write-only", register.name)));
            }
            if !registers.iter().any(|r| r.name == register.name) {
                registers.push(register);
            }
        }
    }
    Ok(registers)
}

/// The one register `name` (with `copy` for per-channel registers) names.
pub(crate) fn single(
    device: &'static DeviceInfo,
    name: &str,
    copy: Option<u8>,
) -> Result<&'static RegisterInfo, CliError> {
    let registers = resolve(device, name, copy)?;
    match registers.as_slice() {
        [register] => Ok(register),
        [first, ..] => Err(CliError::new(format!(
            "`{name}` stands for {} registers",
            registers.len()
        ))
        .hint(match first.copy {
            Some(copy) => format!("choose one with --{} N… try --channel N", copy.repeat),
            None => "name one register".into(),
        })),
        [] => Err(CliError::new(format!("`{name}` names no register"))),
    }
}

fn resolve_register(
    device: &'static DeviceInfo,
    name: &str,
    copy: Option<u8>,
) -> Result<Vec<&'static RegisterInfo>, CliError> {
    if let Some(register) = device.register(name) {
        return Ok(vec![register]);
    }
    let copies: Vec<&'static RegisterInfo> = device
        .registers
        .iter()
        .filter(|r| r.member_name() == Some(name))
        .collect();
    if copies.is_empty() {
        return Err(unknown(device, name));
    }
    match copy {
        None => Ok(copies),
        Some(number) => copies
            .iter()
            .copied()
            .find(|r| r.copy.is_some_and(|c| c.number == number))
            .map(|r| vec![r])
            .ok_or_else(|| {
                let repeat = copies[0].copy.map_or("copy", |c| c.repeat);
                CliError::new(format!(
                    "`{name}` has no {repeat} {number}: {repeat}s are numbered 1 to {}",
                    copies.len()
                ))
            }),
    }
}

fn unknown(device: &DeviceInfo, name: &str) -> CliError {
    let mut near: Vec<&str> = device
        .registers
        .iter()
        .map(|r| r.member_name().unwrap_or(r.name))
        .chain(device.groups.iter().map(|g| g.name))
        .filter(|n| n.contains(name) || name.contains(n))
        .collect();
    near.dedup();
    near.truncate(5);
    let hint = if near.is_empty() {
        format!("see `optobus registers {}`", device.family)
    } else {
        format!("did you mean {}?", near.join(", "))
    };
    CliError::new(format!(
        "`{name}` is no register or group of {}",
        device.family
    ))
    .hint(hint)
}

/// A decoded register value.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Value {
    /// The device marked the reading invalid (its sentinel).
    Invalid,
    Bool(bool),
    Integer(i64),
    /// An exact value with its unit.
    Quantity(Fixed, Option<&'static str>),
    /// An enumerated code and its name (none for codes the manual does not define).
    Code(u32, Option<&'static str>),
    /// Packed fields or record members.
    Fields(Vec<(&'static str, Value)>),
    Ipv4(Ipv4Addr),
    Version(String),
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Invalid => f.write_str("invalid"),
            Self::Bool(value) => write!(f, "{value}"),
            Self::Integer(value) => write!(f, "{value}"),
            Self::Quantity(value, Some(unit)) => write!(f, "{value} {unit}"),
            Self::Quantity(value, None) => write!(f, "{value}"),
            Self::Code(code, Some(name)) => write!(f, "{name} ({code})"),
            Self::Code(code, None) => write!(f, "undefined code {code}"),
            Self::Fields(fields) => {
                for (i, (name, value)) in fields.iter().enumerate() {
                    if i > 0 {
                        f.write_str(", ")?;
                    }
                    write!(f, "{name}={value}")?;
                }
                Ok(())
            }
            Self::Ipv4(address) => write!(f, "{address}"),
            Self::Version(text) => f.write_str(text),
        }
    }
}

impl Value {
    /// The value for scripts: numbers as numbers (exact text alongside), codes with names.
    pub(crate) fn to_json(&self) -> Json {
        match self {
            Self::Invalid => Json::Null,
            Self::Bool(value) => json!(value),
            Self::Integer(value) => json!(value),
            Self::Quantity(value, unit) => {
                json!({"value": value.to_f64(), "exact": value.to_string(), "unit": unit})
            }
            Self::Code(code, name) => json!({"code": code, "name": name}),
            Self::Fields(fields) => Json::Object(
                fields
                    .iter()
                    .map(|(name, value)| ((*name).to_owned(), value.to_json()))
                    .collect(),
            ),
            Self::Ipv4(address) => json!(address.to_string()),
            Self::Version(text) => json!(text),
        }
    }
}

fn code(codes: &'static [CodeInfo], raw: u32) -> Value {
    Value::Code(raw, codes.iter().find(|c| c.code == raw).map(|c| c.name))
}

fn number(raw: i64, scale: Option<Scale>, unit: Option<&'static str>) -> Value {
    match (scale, unit) {
        (None, None) => Value::Integer(raw),
        (scale, unit) => Value::Quantity(Fixed::new(raw, scale.unwrap_or(Scale::ONE)), unit),
    }
}

/// What `register` holds in `words`.
pub(crate) fn decode(register: &'static RegisterInfo, words: &[u16]) -> Value {
    let bits = raw_bits(register, words);
    if register.sentinel == Some(bits) {
        return Value::Invalid;
    }
    match register.kind {
        ValueKind::Bool => Value::Bool(bits != 0),
        ValueKind::Scalar(scalar) => number(scalar.extend(bits), register.scale, register.unit),
        ValueKind::Enum => code(register.codes, bits),
        ValueKind::Packed(fields) => Value::Fields(
            fields
                .iter()
                .map(|field| (field.name, field_value(field, bits)))
                .collect(),
        ),
        ValueKind::Ipv4 => Value::Ipv4(Ipv4Addr::decode(register, words)),
        ValueKind::Version(parts) => {
            let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_be_bytes()).collect();
            let shown: Vec<String> = parts
                .iter()
                .zip(&bytes)
                .filter(|(part, _)| **part != "ignore")
                .map(|(_, byte)| byte.to_string())
                .collect();
            Value::Version(shown.join("."))
        }
        ValueKind::Record(members) => {
            let mut at = 0usize;
            let mut fields = Vec::new();
            for member in members {
                let word = |i: usize| words.get(at + i).copied().unwrap_or(0);
                let (bits, width) = match member.scalar {
                    Scalar::U16 | Scalar::I16 => (u32::from(word(0)), 1),
                    Scalar::U32 | Scalar::I32 => {
                        (join_u32([word(0), word(1)], register.word_order), 2)
                    }
                };
                at += width;
                let value = if member.sentinel == Some(bits) {
                    Value::Invalid
                } else if member.codes.is_empty() {
                    number(member.scalar.extend(bits), member.scale, member.unit)
                } else {
                    code(member.codes, bits)
                };
                fields.push((member.name, value));
            }
            Value::Fields(fields)
        }
    }
}

fn field_value(field: &FieldInfo, bits: u32) -> Value {
    let raw = field.get(bits);
    if field.codes.is_empty() {
        number(i64::from(raw), field.scale, field.unit)
    } else {
        code(field.codes, raw)
    }
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

fn parse_integer(text: &str) -> Option<i64> {
    let text = text.trim();
    match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => i64::from_str_radix(hex, 16).ok(),
        None => text.parse().ok(),
    }
}

/// The codes of a register, for error messages.
fn code_list(codes: &[CodeInfo]) -> String {
    let names: Vec<String> = codes
        .iter()
        .map(|c| format!("{} ({})", c.name, c.code))
        .collect();
    names.join(", ")
}

/// The allowed range of a register in its units, for error messages.
pub(crate) fn range_text(register: &RegisterInfo) -> Option<String> {
    let (min, max) = register.range?;
    let show = |raw: i64| number(raw, register.scale, register.unit);
    Some(format!("{} ..= {}", show(min), show(max)))
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

/// `text` without a trailing unit the register is in.
fn strip_unit<'t>(register: &RegisterInfo, text: &'t str) -> &'t str {
    let text = text.trim();
    let Some(unit) = register.unit else {
        return text;
    };
    for spelling in unit_spellings(unit).iter().copied().chain([unit]) {
        if let Some(number) = text.strip_suffix(spelling) {
            return number.trim_end();
        }
    }
    text
}

/// The validated words that store `text` in `register`; nothing is sent on error.
pub(crate) fn parse(register: &'static RegisterInfo, text: &str) -> Result<Vec<u16>, CliError> {
    let refuse =
        |why: String| CliError::new(format!("`{}` does not take `{text}`: {why}", register.name));
    if !register.access.writable() {
        return Err(CliError::new(format!("`{}` is read-only", register.name)));
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
        ValueKind::Scalar(_) => {
            let number = strip_unit(register, text);
            let value: Fixed = number.parse().map_err(|_| {
                refuse(format!(
                    "not a number{}",
                    register
                        .unit
                        .map(|u| format!(" in {u}"))
                        .unwrap_or_default()
                ))
            })?;
            value.encode(register)
        }
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
                    return Err(refuse(format!(
                        "`{}` takes {}",
                        field.name,
                        if field.codes.is_empty() {
                            "a whole number".to_owned()
                        } else {
                            code_list(field.codes)
                        }
                    )));
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
            return Err(CliError::new(format!(
                "`{}` cannot be written",
                register.name
            )))
        }
    };
    result.map_err(|error| match error {
        optobus_driver::Error::OutOfRange { .. } => refuse(format!(
            "allowed {}",
            range_text(register).unwrap_or_else(|| "values that fit the register".into())
        )),
        optobus_driver::Error::NotRepresentable { scale, .. } => refuse(format!(
            "it holds whole steps of {scale}{}",
            register.unit.map(|u| format!(" {u}")).unwrap_or_default()
        )),
        optobus_driver::Error::UndefinedCode {
            field: Some(field), ..
        } => refuse(format!("`{field}` has no such code")),
        other => refuse(other.to_string()),
    })
}

/// The registers of `device` readable in a terminal or as JSON: name, table, address,
/// access, type, unit, range or codes.
pub(crate) fn describe(register: &RegisterInfo) -> (String, Json) {
    let kind = register.kind.name();
    let values = match register.kind {
        ValueKind::Enum => code_list(register.codes),
        ValueKind::Packed(fields) => fields
            .iter()
            .map(|f| format!("{}: {}", f.name, code_list(f.codes)))
            .collect::<Vec<_>>()
            .join("; "),
        _ => range_text(register).unwrap_or_default(),
    };
    let text = format!(
        "{:<34} {:<7} {:>5} {:<2} {:<7} {:<4} {}",
        register.name,
        register.table.as_str(),
        register.address,
        register.access.as_str(),
        kind,
        register.unit.unwrap_or(""),
        values
    );
    let json = json!({
        "name": register.name,
        "table": register.table.as_str(),
        "address": register.address,
        "words": register.words,
        "access": register.access.as_str(),
        "type": kind,
        "unit": register.unit,
        "scale": register.scale.map(|s| s.to_string()),
        "range": register.range.map(|(a, b)| [a, b]),
        "codes": register.codes.iter().map(|c| json!({"code": c.code, "name": c.name, "meaning": c.meaning})).collect::<Vec<_>>(),
        "sentinel": register.sentinel,
        "doc": register.doc,
        "section": register.section,
    });
    (text, json)
}

/// Words [`parse`] already validated, written as they are.
pub(crate) struct Validated(pub(crate) Vec<u16>);

impl Encode for Validated {
    fn encode(&self, _: &'static RegisterInfo) -> Result<Vec<u16>, optobus_driver::Error> {
        Ok(self.0.clone())
    }
}
