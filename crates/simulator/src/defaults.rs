//! Factory values of the registers.
//!
//! The specs carry no factory defaults, so they are derived: the slave-address register holds
//! the simulator's slave address, baud-rate registers and fields `rtu.default_baud`, parity
//! registers and fields the code named like `rtu.parity`, IPv4 registers `tcp.default_ip`; an
//! enum holds the code whose doc says "default" or whose manual text says 默认, else its first
//! code; an integer with a range holds the value of the range nearest to zero; versions read
//! 1.0.0; everything else 0.

use optobus_device::{CodeInfo, DeviceInfo, FieldInfo, RegisterInfo, ValueKind};

use crate::layout::stored_words;
use crate::names;

/// The code a manual marks as default, else the first one.
fn default_code(codes: &[CodeInfo]) -> u32 {
    codes
        .iter()
        .find(|c| c.doc.to_lowercase().contains("default") || c.meaning.contains("默认"))
        .or_else(|| codes.first())
        .map_or(0, |c| c.code)
}

/// The code standing for `baud` (`meaning: "115200"` or a name ending in `_115200`).
fn baud_code(codes: &[CodeInfo], baud: u32) -> Option<u32> {
    let text = baud.to_string();
    codes
        .iter()
        .find(|c| c.meaning == text || c.name.ends_with(&format!("_{text}")))
        .map(|c| c.code)
}

fn parity_code(codes: &[CodeInfo], device: &DeviceInfo) -> Option<u32> {
    let parity = device.rtu?.parity;
    codes
        .iter()
        .find(|c| c.name == parity.name())
        .map(|c| c.code)
}

/// The value of `range` nearest to zero.
fn nearest_zero(range: Option<(i64, i64)>) -> i64 {
    range.map_or(0, |(min, max)| 0.clamp(min, max.max(min)))
}

fn field_default(device: &DeviceInfo, field: &FieldInfo) -> u32 {
    let baud = device.rtu.map(|rtu| rtu.default_baud);
    match field.name {
        names::BAUD_RATE if field.codes.is_empty() => baud.unwrap_or(0),
        names::BAUD_RATE => baud
            .and_then(|b| baud_code(field.codes, b))
            .unwrap_or_else(|| default_code(field.codes)),
        names::PARITY => {
            parity_code(field.codes, device).unwrap_or_else(|| default_code(field.codes))
        }
        _ if !field.codes.is_empty() => default_code(field.codes),
        _ => nearest_zero(field.range) as u32,
    }
}

/// The factory words of `register` on a device answering at `slave`.
pub(crate) fn default_words(device: &DeviceInfo, register: &RegisterInfo, slave: u8) -> Vec<u16> {
    let words = usize::from(register.words);
    let baud = device.rtu.map(|rtu| rtu.default_baud);
    let raw: u32 = match (register.name, register.kind) {
        (names::SLAVE_ADDRESS, ValueKind::Scalar(_)) => u32::from(slave),
        (names::BAUD_RATE, ValueKind::Scalar(_)) => baud.unwrap_or(0),
        (names::BAUD_RATE, ValueKind::Enum) => baud
            .and_then(|b| baud_code(register.codes, b))
            .unwrap_or_else(|| default_code(register.codes)),
        (names::PARITY, ValueKind::Enum) => {
            parity_code(register.codes, device).unwrap_or_else(|| default_code(register.codes))
        }
        (_, ValueKind::Enum) => default_code(register.codes),
        (_, ValueKind::Packed(fields)) => fields.iter().fold(0, |raw, field| {
            let bits = optobus_codec::value::BitField {
                shift: field.lsb,
                width: field.width,
            };
            bits.set(raw, field_default(device, field)).unwrap_or(raw)
        }),
        (_, ValueKind::Scalar(_)) => nearest_zero(register.range) as u32,
        (_, ValueKind::Ipv4) => {
            let ip = device.tcp.and_then(|tcp| tcp.default_ip).unwrap_or([0; 4]);
            let mut octets: Vec<u16> = ip.iter().map(|&o| u16::from(o)).collect();
            octets.resize(words, 0);
            return octets;
        }
        (_, ValueKind::Version(parts)) => {
            let bytes: Vec<u8> = parts
                .iter()
                .map(|&part| u8::from(part == "major"))
                .collect();
            let mut version: Vec<u16> = bytes
                .chunks(2)
                .map(|pair| u16::from_be_bytes([pair[0], pair.get(1).copied().unwrap_or(0)]))
                .collect();
            version.resize(words, 0);
            return version;
        }
        (_, ValueKind::Bool | ValueKind::Record(_)) => 0,
    };
    let mut out = stored_words(register, raw);
    out.resize(words, 0);
    out
}
