//! Register words ⇄ raw values, and the validation of written values.

use optobus_codec::value::{join_u32, split_u32, BitField};
use optobus_device::{CodeInfo, FieldInfo, RegisterInfo, Scalar, ValueKind};

/// The raw value of a one- or two-word register (further words are ignored).
pub(crate) fn join(register: &RegisterInfo, words: &[u16]) -> u32 {
    match words {
        [] => 0,
        [word] => u32::from(*word),
        [first, second, ..] => join_u32([*first, *second], register.word_order),
    }
}

/// The words of a one- or two-word register holding `raw`.
pub(crate) fn split(register: &RegisterInfo, raw: u32) -> Vec<u16> {
    if register.words >= 2 {
        let mut words = split_u32(raw, register.word_order).to_vec();
        words.resize(usize::from(register.words), 0);
        words
    } else {
        // A one-word register keeps the low half.
        vec![raw as u16]
    }
}

/// The raw bits of `value` in `scalar`'s width.
pub(crate) fn to_raw(scalar: Scalar, value: i64) -> u32 {
    match scalar {
        Scalar::U16 | Scalar::I16 => u32::from(value as u16),
        Scalar::U32 | Scalar::I32 => value as u32,
    }
}

fn in_range(range: Option<(i64, i64)>, value: i64) -> bool {
    range.is_none_or(|(min, max)| (min..=max).contains(&value))
}

fn is_code(codes: &[CodeInfo], raw: u32) -> bool {
    codes.is_empty() || codes.iter().any(|code| code.code == raw)
}

fn valid_fields(fields: &[FieldInfo], raw: u32) -> bool {
    let mut covered = 0u32;
    for field in fields {
        let bits = BitField {
            shift: field.lsb,
            width: field.width,
        };
        let value = bits.get(raw);
        if !is_code(field.codes, value) || !in_range(field.range, i64::from(value)) {
            return false;
        }
        covered |= bits.set(0, bits.get(u32::MAX)).unwrap_or(0);
    }
    // Bits outside every field must be clear.
    raw & !covered == 0
}

/// Whether writing `raw` to `register` is accepted (4.1.1 note 2 of the P series, CCS and
/// CCF manuals: an invalid value is refused and the register keeps its value).
pub(crate) fn valid(register: &RegisterInfo, raw: u32) -> bool {
    let kind_ok = match register.kind {
        ValueKind::Bool => raw <= 1,
        ValueKind::Scalar(scalar) => {
            let (min, max) = scalar.bounds();
            (min..=max).contains(&scalar.extend(raw))
        }
        ValueKind::Enum => is_code(register.codes, raw),
        ValueKind::Packed(fields) => valid_fields(fields, raw),
        // One octet per word.
        ValueKind::Ipv4 => raw <= 0xFF,
        ValueKind::Version(_) | ValueKind::Record(_) => true,
    };
    kind_ok && in_range(register.range, register.scalar().extend(raw))
}

#[cfg(test)]
mod tests {
    use super::*;
    use optobus_device::{Access, Table, WordOrder, WriteOrder};

    const fn register(kind: ValueKind, words: u16, range: Option<(i64, i64)>) -> RegisterInfo {
        RegisterInfo {
            name: "r",
            doc: "",
            zh: "",
            section: "",
            table: Table::Holding,
            address: 0,
            words,
            access: Access::ReadWrite,
            kind,
            codes: &[],
            scale: None,
            unit: None,
            range,
            sentinel: None,
            word_order: WordOrder::HighFirst,
            write_order: WriteOrder::HighWordFirst,
            copy: None,
            read_side_effect: None,
        }
    }

    #[test]
    fn signed_ranges() {
        let offset = register(ValueKind::Scalar(Scalar::I16), 1, Some((-20000, 20000)));
        assert!(valid(&offset, 0xFEFC));
        assert!(!valid(&offset, 0x8000));
        let id = register(ValueKind::Scalar(Scalar::U16), 1, Some((1, 247)));
        assert!(!valid(&id, 0) && valid(&id, 247) && !valid(&id, 248));
    }

    #[test]
    fn packed_fields() {
        static FIELDS: [FieldInfo; 1] = [FieldInfo {
            name: "low",
            doc: "",
            lsb: 0,
            width: 8,
            scalar: Scalar::U16,
            codes: &[],
            range: Some((0, 5)),
            scale: None,
            unit: None,
            sentinel: None,
        }];
        let packed = register(ValueKind::Packed(&FIELDS), 1, None);
        assert!(valid(&packed, 5));
        assert!(!valid(&packed, 6));
        assert!(!valid(&packed, 0x0100), "bits outside the fields");
    }

    #[test]
    fn words_round_trip() {
        let long = register(ValueKind::Scalar(Scalar::U32), 2, None);
        assert_eq!(split(&long, 0x0001_C200), vec![0x0001, 0xC200]);
        assert_eq!(join(&long, &[0x0001, 0xC200]), 0x0001_C200);
    }
}
