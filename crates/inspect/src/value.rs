//! A register's words decoded for people (`Display`) and scripts (`Serialize`).

use std::borrow::Cow;
use std::fmt;
use std::net::Ipv4Addr;

use optobus_codec::value::{join_u32, Fixed, Scale};
use optobus_device::{CodeInfo, FieldInfo, RegisterInfo, Scalar, ValueKind};
use optobus_driver::shapes::{Code, Quantity};
use optobus_driver::{Decode, Readings};
use serde::ser::{SerializeMap, Serializer};
use serde::Serialize;

/// A decoded register value.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// The device marked the reading invalid (its sentinel).
    Invalid,
    /// A boolean register.
    Bool(bool),
    /// A plain integer.
    Integer(i64),
    /// An exact value with its unit.
    Quantity(Fixed, Option<&'static str>),
    /// An enumerated code and its name (none for codes the manual does not define).
    Code(u32, Option<&'static str>),
    /// Packed fields or record members.
    Fields(Vec<(&'static str, Value)>),
    /// An IPv4 address.
    Ipv4(Ipv4Addr),
    /// A version: its named parts, major first (shown joined with dots).
    Version(Vec<(&'static str, u8)>),
}

impl Value {
    /// The value as a number to draw: a quantity's or an integer's; `None` for any other.
    pub fn number(&self) -> Option<f64> {
        match self {
            Self::Quantity(number, _) => Some(number.to_f64()),
            Self::Integer(number) => Some(*number as f64),
            _ => None,
        }
    }
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
            Self::Version(parts) => {
                let numbers: Vec<String> = parts.iter().map(|(_, n)| n.to_string()).collect();
                f.write_str(&numbers.join("."))
            }
        }
    }
}

/// For scripts, in the shapes of the drivers' `serde` feature ([`optobus_driver::shapes`]):
/// integers as numbers, quantities as exact text with their unit (`{"value": "3.584190",
/// "unit": "mm"}`, a quantity without unit as its text alone), codes with their names,
/// fields and version parts as an object, invalid readings as `null`.
impl Serialize for Value {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match self {
            Self::Invalid => serializer.serialize_none(),
            Self::Bool(value) => serializer.serialize_bool(*value),
            Self::Integer(value) => serializer.serialize_i64(*value),
            Self::Quantity(value, Some(unit)) => Quantity {
                value: *value,
                unit: Cow::Borrowed(unit),
            }
            .serialize(serializer),
            Self::Quantity(value, None) => value.serialize(serializer),
            Self::Code(code, name) => Code {
                code: Some(*code),
                name: name.map(Cow::Borrowed),
            }
            .serialize(serializer),
            Self::Fields(fields) => {
                let mut map = serializer.serialize_map(Some(fields.len()))?;
                for (name, value) in fields {
                    map.serialize_entry(name, value)?;
                }
                map.end()
            }
            Self::Ipv4(address) => serializer.collect_str(address),
            Self::Version(parts) => {
                let mut map = serializer.serialize_map(Some(parts.len()))?;
                for (name, number) in parts {
                    map.serialize_entry(name, number)?;
                }
                map.end()
            }
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

fn field_value(field: &FieldInfo, bits: u32) -> Value {
    let raw = field.get(bits);
    if field.codes.is_empty() {
        number(i64::from(raw), field.scale, field.unit)
    } else {
        code(field.codes, raw)
    }
}

/// The values of `registers` in what a group read read ([`optobus_driver::Core::read_group`]
/// and its partial form), in the order given: the one decoding of a read, for every tool.
pub fn decode_readings(registers: &[&'static RegisterInfo], readings: &Readings) -> Vec<Value> {
    registers
        .iter()
        .map(|register| decode_value(register, readings.words(register)))
        .collect()
}

/// Each of `registers` with its value in what a group read read, in the order given.
pub fn decode_values(
    registers: &[&'static RegisterInfo],
    readings: &Readings,
) -> Vec<(&'static RegisterInfo, Value)> {
    registers
        .iter()
        .copied()
        .zip(decode_readings(registers, readings))
        .collect()
}

/// What `register` holds in `words` (its words in address order; missing words read as 0).
pub fn decode_value(register: &'static RegisterInfo, words: &[u16]) -> Value {
    let bits = register.raw(words);
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
            let named = parts.iter().copied().zip(bytes);
            Value::Version(named.filter(|(part, _)| *part != "ignore").collect())
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

/// Values as `name  value` lines, one per register, the values aligned after the longest
/// name (what `read`, `watch` and a running bus's terminal view show).
pub fn values_text(values: &[(&'static RegisterInfo, Value)]) -> String {
    let width = values.iter().map(|(r, _)| r.name.len()).max().unwrap_or(0);
    values
        .iter()
        .map(|(r, v)| format!("{:<width$}  {v}\n", r.name))
        .collect()
}

/// What a register takes, as the register maps show it: its codes (`idle (0), save (1)`), each
/// packed field's codes, or its range in its units; empty when it has none of them.
pub fn accepted_values_text(register: &RegisterInfo) -> String {
    match register.kind {
        ValueKind::Enum => crate::code_list(register.codes),
        ValueKind::Packed(fields) => fields
            .iter()
            .map(|f| format!("{}: {}", f.name, crate::code_list(f.codes)))
            .collect::<Vec<_>>()
            .join("; "),
        _ => range_text(register).unwrap_or_default(),
    }
}

/// The allowed range of a register in its units (`0.5 % ..= 100.0 %`), if it has one.
pub fn range_text(register: &RegisterInfo) -> Option<String> {
    let (min, max) = register.range?;
    let show = |raw: i64| match (register.scale, register.unit) {
        (None, None) => raw.to_string(),
        (scale, unit) => {
            let value = Fixed::new(raw, scale.unwrap_or(Scale::ONE));
            match unit {
                Some(unit) => format!("{value} {unit}"),
                None => value.to_string(),
            }
        }
    };
    Some(format!("{} ..= {}", show(min), show(max)))
}
