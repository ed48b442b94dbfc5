//! The register types: tables, access, value kinds (scalars, codes, fields, repeat copies),
//! roles, reserved ranges and how addresses count (per word or per field), and the register
//! facts every side looks up the same way.

use optobus_codec::value::{Scale, WordOrder, WriteOrder};
use optobus_codec::ReadFunction;

/// A register table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Deserialize, serde::Serialize),
    serde(rename_all = "snake_case")
)]
pub enum Table {
    /// Holding registers: read with FC03, written with FC06.
    Holding,
    /// Input registers: read with FC04.
    Input,
}

impl Table {
    /// `holding` or `input`, as in the specs.
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::Holding => "holding",
            Self::Input => "input",
        }
    }

    /// The function that reads the table: FC03 for holding, FC04 for input registers.
    pub const fn read_function(self) -> ReadFunction {
        match self {
            Self::Holding => ReadFunction::Holding,
            Self::Input => ReadFunction::Input,
        }
    }

    /// The table a read function reads.
    pub const fn read_by(function: ReadFunction) -> Self {
        match function {
            ReadFunction::Holding => Self::Holding,
            ReadFunction::Input => Self::Input,
        }
    }

    /// The table read by function code `code` (03 or 04), if it is a read.
    pub const fn of_function_code(code: u8) -> Option<Self> {
        match ReadFunction::from_code(code) {
            Some(function) => Some(Self::read_by(function)),
            None => None,
        }
    }
}

impl From<Table> for ReadFunction {
    fn from(table: Table) -> Self {
        table.read_function()
    }
}

impl From<ReadFunction> for Table {
    fn from(function: ReadFunction) -> Self {
        Self::read_by(function)
    }
}

/// Who may read and write a register.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Deserialize, serde::Serialize))]
pub enum Access {
    /// Read only.
    #[cfg_attr(feature = "serde", serde(rename = "r"))]
    Read,
    /// Read and write.
    #[cfg_attr(feature = "serde", serde(rename = "rw"))]
    ReadWrite,
    /// Write only.
    #[cfg_attr(feature = "serde", serde(rename = "w"))]
    Write,
}

impl Access {
    /// `r`, `rw` or `w`, as in the specs.
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::Read => "r",
            Self::ReadWrite => "rw",
            Self::Write => "w",
        }
    }

    /// True for read and read-write registers.
    pub const fn readable(self) -> bool {
        !matches!(self, Self::Write)
    }

    /// True for write and read-write registers.
    pub const fn writable(self) -> bool {
        !matches!(self, Self::Read)
    }
}

/// An integer wire type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Scalar {
    /// Unsigned, one word.
    U16,
    /// Signed, one word.
    I16,
    /// Unsigned, two words.
    U32,
    /// Signed, two words.
    I32,
}

impl Scalar {
    /// `u16`, `i16`, `u32` or `i32`, as in the specs.
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::U16 => "u16",
            Self::I16 => "i16",
            Self::U32 => "u32",
            Self::I32 => "i32",
        }
    }

    /// Words on the wire: 1 or 2.
    pub const fn words(self) -> u32 {
        match self {
            Self::U16 | Self::I16 => 1,
            Self::U32 | Self::I32 => 2,
        }
    }

    /// The unsigned type of `words` words (two or more: `U32`).
    pub const fn unsigned(words: u32) -> Self {
        if words >= 2 {
            Self::U32
        } else {
            Self::U16
        }
    }

    /// The smallest and largest value the type holds.
    pub const fn bounds(self) -> (i64, i64) {
        match self {
            Self::U16 => (0, u16::MAX as i64),
            Self::I16 => (i16::MIN as i64, i16::MAX as i64),
            Self::U32 => (0, u32::MAX as i64),
            Self::I32 => (i32::MIN as i64, i32::MAX as i64),
        }
    }

    /// The value of a register's raw bits read as this type (sign-extended when signed).
    pub const fn extend(self, bits: u32) -> i64 {
        match self {
            Self::U16 => bits as u16 as i64,
            Self::I16 => bits as u16 as i16 as i64,
            Self::U32 => bits as i64,
            Self::I32 => bits as i32 as i64,
        }
    }

    /// The raw bits of `value` in the type's width (wrapping: the caller checks the bounds).
    pub const fn to_raw(self, value: i64) -> u32 {
        match self {
            Self::U16 | Self::I16 => value as u16 as u32,
            Self::U32 | Self::I32 => value as u32,
        }
    }

    /// Whether the type holds `value`.
    pub const fn holds(self, value: i64) -> bool {
        let (min, max) = self.bounds();
        min <= value && value <= max
    }
}

/// One code of an enumerated value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct CodeInfo {
    /// The raw value.
    pub code: u32,
    /// snake_case English name.
    pub name: &'static str,
    /// The manual's own words for the code.
    pub meaning: &'static str,
    /// English description.
    pub doc: &'static str,
}

/// A bit field of a packed register, or a member of a record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldInfo {
    /// snake_case name.
    pub name: &'static str,
    /// English description.
    pub doc: &'static str,
    /// Lowest bit (packed fields; 0 for record members).
    pub lsb: u8,
    /// Bits (packed fields; 16 or 32 for record members).
    pub width: u8,
    /// Wire type of a record member.
    pub scalar: Scalar,
    /// Codes, when the field is enumerated.
    pub codes: &'static [CodeInfo],
    /// Raw range.
    pub range: Option<(i64, i64)>,
    /// One raw step.
    pub scale: Option<Scale>,
    /// Unit.
    pub unit: Option<&'static str>,
    /// Raw value meaning "invalid".
    pub sentinel: Option<u32>,
}

impl FieldInfo {
    /// The field's bits as a codec bit field.
    pub const fn bit_field(&self) -> optobus_codec::value::BitField {
        optobus_codec::value::BitField {
            shift: self.lsb,
            width: self.width,
        }
    }

    /// The field's raw value in a packed register's bits.
    pub const fn get(&self, bits: u32) -> u32 {
        self.bit_field().get(bits)
    }
}

/// The value type of a register.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ValueKind {
    /// 0 or 1.
    Bool,
    /// An integer, or fixed-point when the register has a scale.
    Scalar(Scalar),
    /// One of `RegisterInfo::codes`.
    Enum,
    /// Bit fields.
    Packed(&'static [FieldInfo]),
    /// Four words, one octet each.
    Ipv4,
    /// Four bytes naming version parts (`ignore` for padding).
    Version(&'static [&'static str; 4]),
    /// Consecutive members.
    Record(&'static [FieldInfo]),
}

impl ValueKind {
    /// The spec's name for the type (`bool`, `u16`, …, `enum`, `packed`, `record`).
    pub const fn name(&self) -> &'static str {
        match self {
            Self::Bool => "bool",
            Self::Scalar(scalar) => scalar.as_str(),
            Self::Enum => "enum",
            Self::Packed(_) => "packed",
            Self::Ipv4 => "ipv4",
            Self::Version(_) => "version",
            Self::Record(_) => "record",
        }
    }
}

/// One register.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegisterInfo {
    /// snake_case name (`channel_2_exposure_time` for repeat copies).
    pub name: &'static str,
    /// English description.
    pub doc: &'static str,
    /// The manual's own name.
    pub zh: &'static str,
    /// Manual section.
    pub section: &'static str,
    /// Table.
    pub table: Table,
    /// First address.
    pub address: u16,
    /// Words a read transfers.
    pub words: u16,
    /// Who may read and write.
    pub access: Access,
    /// Value type.
    pub kind: ValueKind,
    /// Codes of an enum register.
    pub codes: &'static [CodeInfo],
    /// One raw step.
    pub scale: Option<Scale>,
    /// Unit.
    pub unit: Option<&'static str>,
    /// Raw range a write must respect.
    pub range: Option<(i64, i64)>,
    /// The only raw values a write may give, when the manual lists them (LC-RS baud rates);
    /// empty: any value in the range.
    pub allowed_values: &'static [i64],
    /// Raw bits meaning "invalid reading".
    pub sentinel: Option<u32>,
    /// Which word sits at the lower address.
    pub word_order: WordOrder,
    /// Which word of a split write goes first.
    pub write_order: WriteOrder,
    /// Which copy of a repeat block's member the register is (`None` outside repeats).
    pub copy: Option<RepeatCopy>,
    /// What reading the register changes in the device (it turns a buffer page), if
    /// anything: such a read is made once, never retried.
    pub read_side_effect: Option<&'static str>,
    /// Writing it acts and the manual does not say what a read returns (LC-RS factory reset):
    /// it is written, never read.
    pub action: bool,
    /// What the register is to the device as a whole, where the spec says so (`role:`).
    pub role: Option<Role>,
}

/// What a register is to the device as a whole (the spec's `role:`), so that tools find it
/// without matching its name; each role is given to at most one register of a spec, one that
/// can be read without changing the device.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Deserialize, serde::Serialize),
    serde(rename_all = "snake_case")
)]
#[non_exhaustive]
pub enum Role {
    /// The version of the device's firmware.
    FirmwareVersion,
    /// The device's serial number.
    SerialNumber,
}

impl Role {
    /// Its name in specs.
    pub const fn name(self) -> &'static str {
        match self {
            Self::FirmwareVersion => "firmware_version",
            Self::SerialNumber => "serial_number",
        }
    }
}

impl RegisterInfo {
    /// Whether the register may be read: not write-only, and not an action register whose
    /// read the manual leaves undefined.
    pub const fn readable(&self) -> bool {
        self.access.readable() && !self.action
    }

    /// Whether a failed read may simply be made again: false when reading changes the device.
    pub const fn read_is_repeatable(&self) -> bool {
        self.read_side_effect.is_none()
    }

    /// The integer type the register's raw bits are read as (unsigned for enums, packed and
    /// boolean registers).
    pub const fn scalar(&self) -> Scalar {
        match self.kind {
            ValueKind::Scalar(scalar) => scalar,
            _ if self.words >= 2 => Scalar::U32,
            _ => Scalar::U16,
        }
    }

    /// How many addresses the register takes: one per word, or one in all with one address
    /// per field.
    pub const fn span(&self, addressing: Addressing) -> u16 {
        match addressing {
            Addressing::Word => self.words,
            Addressing::Field => 1,
        }
    }

    /// For a repeat copy, the repeat member it is a copy of (`channel_2_exposure_time` →
    /// `exposure_time`), the name commands and groups use for all copies.
    pub const fn member_name(&self) -> Option<&'static str> {
        match self.copy {
            Some(copy) => Some(copy.member),
            None => None,
        }
    }
}

/// Where a register sits in a repeat block: `channel_2_exposure_time` is copy 2 of the
/// `channel` block's member `exposure_time`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RepeatCopy {
    /// The repeat block (`channel`), also the name of its index type.
    pub repeat: &'static str,
    /// 1-based copy number, as in the manual.
    pub number: u8,
    /// The member's name, shared by every copy (`exposure_time`).
    pub member: &'static str,
}

/// One address per word, or per field.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Deserialize, serde::Serialize),
    serde(rename_all = "snake_case")
)]
pub enum Addressing {
    /// Standard: one address per 16-bit word.
    Word,
    /// One address per field, whatever its width (the rangefinder).
    Field,
}

/// An address range the device reserves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReservedInfo {
    /// Table.
    pub table: Table,
    /// First address.
    pub from: u16,
    /// Last address, inclusive.
    pub to: u16,
    /// Reading it is expected to work (inferred: it lies inside the table the manual says may
    /// be read, and the manual says nothing against it): reads answer zeros, and a read plan
    /// may ask for it to join two reads in one.
    pub readable: bool,
}

impl ReservedInfo {
    /// Whether `address` of `table` lies in the range.
    pub fn contains(&self, table: Table, address: u16) -> bool {
        self.table == table && (self.from..=self.to).contains(&address)
    }
}
