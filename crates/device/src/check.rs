//! The one answer to "may this raw value be written to this register?": the driver refuses
//! such a write before sending it, the simulator answers exception 03, tools explain it.

use core::fmt;

use crate::register::{CodeInfo, FieldInfo, RegisterInfo, ValueKind};

/// Why a raw value may not be written to a register (or to a field of a packed one).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Invalid {
    /// The value lies outside `min ..= max`: the spec's range within the wire type's bounds.
    OutOfRange {
        /// The packed field, if the value is a field's.
        field: Option<&'static FieldInfo>,
        /// The value, in raw steps.
        value: i64,
        /// Smallest allowed raw value.
        min: i64,
        /// Largest allowed raw value.
        max: i64,
    },
    /// A code the manual does not define for the register or field.
    UndefinedCode {
        /// The packed field, if the code is a field's.
        field: Option<&'static FieldInfo>,
        /// The code.
        code: u32,
    },
    /// A value within the range that is not one of the values the manual lists for the
    /// register (LC-RS baud rates: 57600 is not one).
    Unlisted {
        /// The value, in raw steps.
        value: i64,
        /// The values the register accepts, in raw steps.
        allowed: &'static [i64],
    },
    /// Bits set outside every field of a packed register (a field value too wide for its
    /// bits).
    StrayBits {
        /// The bits outside the fields.
        bits: u32,
    },
}

impl fmt::Display for Invalid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = |field: &Option<&FieldInfo>| field.map_or("", |field| field.name);
        match self {
            Self::OutOfRange {
                field,
                value,
                min,
                max,
            } => {
                write!(f, "{value} is outside {min} ..= {max}")?;
                match field {
                    Some(field) => write!(f, " (field `{}`)", field.name),
                    None => Ok(()),
                }
            }
            Self::UndefinedCode { field: None, code } => write!(f, "code {code} is not defined"),
            Self::UndefinedCode { field, code } => {
                write!(f, "code {code} is not defined for field `{}`", name(field))
            }
            Self::Unlisted { value, allowed } => {
                write!(f, "{value} is not one of ")?;
                write_list(f, allowed)
            }
            Self::StrayBits { bits } => {
                write!(f, "bits {bits:#X} lie outside every field")
            }
        }
    }
}

/// `a, b or c`.
fn write_list(f: &mut fmt::Formatter<'_>, values: &[i64]) -> fmt::Result {
    for (i, value) in values.iter().enumerate() {
        let separator = match i {
            0 => "",
            _ if i + 1 == values.len() => " or ",
            _ => ", ",
        };
        write!(f, "{separator}{value}")?;
    }
    Ok(())
}

fn defined(codes: &[CodeInfo], raw: u32) -> bool {
    codes.is_empty() || codes.iter().any(|code| code.code == raw)
}

fn check_fields(fields: &'static [FieldInfo], raw: u32) -> Result<(), Invalid> {
    let mut covered = 0u32;
    for field in fields {
        let bits = field.bit_field();
        let value = bits.get(raw);
        if !defined(field.codes, value) {
            return Err(Invalid::UndefinedCode {
                field: Some(field),
                code: value,
            });
        }
        if let Some((min, max)) = field.range {
            let value = i64::from(value);
            if !(min..=max).contains(&value) {
                return Err(Invalid::OutOfRange {
                    field: Some(field),
                    value,
                    min,
                    max,
                });
            }
        }
        covered |= bits.set(0, bits.get(u32::MAX)).unwrap_or(0);
    }
    match raw & !covered {
        0 => Ok(()),
        bits => Err(Invalid::StrayBits { bits }),
    }
}

impl RegisterInfo {
    /// The raw values a write may give: the spec's range within the wire type's bounds (0 ..= 1
    /// for booleans).
    pub const fn allowed(&self) -> (i64, i64) {
        let (type_min, type_max) = match self.kind {
            ValueKind::Bool => (0, 1),
            _ => self.scalar().bounds(),
        };
        match self.range {
            Some((min, max)) => (
                if min > type_min { min } else { type_min },
                if max < type_max { max } else { type_max },
            ),
            None => (type_min, type_max),
        }
    }

    fn out_of_range(&self, value: i64) -> Invalid {
        let (min, max) = self.allowed();
        Invalid::OutOfRange {
            field: None,
            value,
            min,
            max,
        }
    }

    /// Whether `raw` (the register's bits; one word of a multi-word IPv4 register) may be
    /// written: a defined code, packed fields within their codes and ranges and no bit outside
    /// them, within the spec's range and among its allowed values, if it lists them. (P series, CCS and CCF manuals 4.1.1 note 2: an invalid
    /// value is refused and the register keeps its value.)
    pub fn check(&self, raw: u32) -> Result<(), Invalid> {
        match self.kind {
            ValueKind::Bool if raw > 1 => return Err(self.out_of_range(i64::from(raw))),
            ValueKind::Enum if !defined(self.codes, raw) => {
                return Err(Invalid::UndefinedCode {
                    field: None,
                    code: raw,
                })
            }
            ValueKind::Packed(fields) => check_fields(fields, raw)?,
            // One octet per word.
            ValueKind::Ipv4 if raw > 0xFF => {
                return Err(Invalid::OutOfRange {
                    field: None,
                    value: i64::from(raw),
                    min: 0,
                    max: 0xFF,
                })
            }
            _ => {}
        }
        let value = self.scalar().extend(raw);
        let (min, max) = self.allowed();
        if !(min..=max).contains(&value) {
            return Err(self.out_of_range(value));
        }
        if !self.allowed_values.is_empty() && !self.allowed_values.contains(&value) {
            return Err(Invalid::Unlisted {
                value,
                allowed: self.allowed_values,
            });
        }
        Ok(())
    }

    /// The raw bits of the integer `value` (a number in raw steps, or a code), checked as
    /// [`RegisterInfo::check`] does, and against the wire type's bounds first.
    pub fn check_integer(&self, value: i64) -> Result<u32, Invalid> {
        let scalar = self.scalar();
        if !scalar.holds(value) {
            return Err(match (self.kind, u32::try_from(value)) {
                (ValueKind::Enum, Ok(code)) if !defined(self.codes, code) => {
                    Invalid::UndefinedCode { field: None, code }
                }
                _ => self.out_of_range(value),
            });
        }
        let raw = scalar.to_raw(value);
        self.check(raw)?;
        Ok(raw)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Access, Scalar, Table, WordOrder, WriteOrder};

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
            allowed_values: &[],
            action: false,
            role: None,
        }
    }

    #[test]
    fn signed_ranges() {
        let offset = register(ValueKind::Scalar(Scalar::I16), 1, Some((-20000, 20000)));
        assert_eq!(offset.check(0xFEFC), Ok(()));
        assert_eq!(
            offset.check(0x8000),
            Err(Invalid::OutOfRange {
                field: None,
                value: -32768,
                min: -20000,
                max: 20000
            })
        );
        assert_eq!(offset.check_integer(-260), Ok(0xFEFC));
        let id = register(ValueKind::Scalar(Scalar::U16), 1, Some((1, 247)));
        assert!(id.check(0).is_err() && id.check(247).is_ok() && id.check(248).is_err());
        assert!(id.check_integer(-1).is_err() && id.check_integer(70_000).is_err());
    }

    #[test]
    fn booleans_and_codes() {
        let flag = register(ValueKind::Bool, 1, None);
        assert!(flag.check(1).is_ok() && flag.check(2).is_err());
        static CODES: [CodeInfo; 1] = [CodeInfo {
            code: 3,
            name: "three",
            meaning: "",
            doc: "",
        }];
        let mut mode = register(ValueKind::Enum, 1, None);
        mode.codes = &CODES;
        assert_eq!(mode.check_integer(3), Ok(3));
        let undefined = Err(Invalid::UndefinedCode {
            field: None,
            code: 70_000,
        });
        assert_eq!(mode.check_integer(70_000), undefined);
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
        assert!(packed.check(5).is_ok());
        assert!(matches!(
            packed.check(6),
            Err(Invalid::OutOfRange { field: Some(_), .. })
        ));
        assert_eq!(
            packed.check(0x0100),
            Err(Invalid::StrayBits { bits: 0x0100 })
        );
    }

    #[test]
    fn listed_values_only() {
        let mut baud = register(ValueKind::Scalar(Scalar::U32), 2, Some((2400, 115_200)));
        baud.allowed_values = &[2400, 4800, 9600, 19200, 38400, 115_200];
        assert_eq!(baud.check(0x0001_C200), Ok(()));
        assert_eq!(baud.check_integer(9600), Ok(9600));
        let unlisted = Invalid::Unlisted {
            value: 57600,
            allowed: baud.allowed_values,
        };
        assert_eq!(baud.check_integer(57600), Err(unlisted));
        // No allocator here: the message is written into a fixed buffer.
        struct Text([u8; 96], usize);
        impl fmt::Write for Text {
            fn write_str(&mut self, s: &str) -> fmt::Result {
                let end = self.1 + s.len();
                let room = self.0.get_mut(self.1..end).ok_or(fmt::Error)?;
                room.copy_from_slice(s.as_bytes());
                self.1 = end;
                Ok(())
            }
        }
        let mut text = Text([0; 96], 0);
        fmt::write(&mut text, format_args!("{unlisted}")).unwrap();
        assert_eq!(
            &text.0[..text.1],
            b"57600 is not one of 2400, 4800, 9600, 19200, 38400 or 115200"
        );
        // The range is judged first: a value outside it says so.
        assert!(matches!(
            baud.check_integer(1200),
            Err(Invalid::OutOfRange { min: 2400, .. })
        ));
    }

    #[test]
    fn words_round_trip() {
        let long = register(ValueKind::Scalar(Scalar::U32), 2, None);
        assert_eq!(&*long.raw_words(0x0001_C200), &[0x0001, 0xC200]);
        assert_eq!(long.raw(&[0x0001, 0xC200]), 0x0001_C200);
        let short = register(ValueKind::Scalar(Scalar::U16), 1, None);
        assert_eq!(&*short.raw_words(0x0001_C200), &[0xC200]);
    }
}
