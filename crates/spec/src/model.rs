//! The checked model: what a spec means, with repeats expanded and references resolved.
//!
//! Lowering is lenient (it keeps what was declared so that rules can judge it); a model that
//! passed every rule is what the emitters and `dump --json` see.

use std::collections::BTreeSet;

use foldhash::HashMap;
use std::net::Ipv4Addr;

use optobus_codec::value::{Scale, WordOrder, WriteOrder};
pub use optobus_codec::Parity;

use crate::source::Path;
pub use optobus_device::{Access, Addressing, Effect, LongWrites, Role, Scalar, Table};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
/// How the device frames exception replies.
pub enum ExceptionStyle {
    /// `fc|0x80 code`.
    Standard,
    /// `fc|0x80 02 code_hi code_lo` (LC-RS).
    CountedWord,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
/// When written settings take effect.
pub enum Apply {
    /// As soon as they are written.
    Immediately,
    /// After the save command and a power cycle (LC-RS).
    AfterSaveAndPowerCycle,
}

/// A register address as declared (checked against 16 bits by a rule).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Address(pub u32);

/// How many 16-bit words a read of a register transfers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct WordCount(pub u32);

/// An enum: shared, or declared inline by one register or field.
#[derive(Clone, Debug)]
pub struct EnumDef {
    /// snake_case name (the register's or `<register>_<field>` for inline enums).
    pub name: String,
    /// English doc.
    pub doc: Option<String>,
    /// The codes.
    pub codes: Vec<Code>,
    /// Declared under `enums:` (shared) rather than inline.
    pub shared: bool,
    /// Manual section.
    pub section: Option<String>,
    /// Where it is declared.
    pub path: Path,
}

/// One enum code.
#[derive(Clone, Debug)]
pub struct Code {
    /// The raw value.
    pub code: i64,
    /// snake_case English name.
    pub name: String,
    /// The manual's words.
    pub meaning: Option<String>,
    /// English doc.
    pub doc: Option<String>,
    /// Where it is declared.
    pub path: Path,
}

/// A reference to an enum by name, resolved when it exists.
#[derive(Clone, Debug)]
pub struct EnumRef {
    /// The name referred to.
    pub name: String,
    /// Index into `Model::enums`, when the name resolves.
    pub index: Option<usize>,
    /// Where the reference is written.
    pub path: Path,
}

/// The value type of a register.
#[derive(Clone, Debug)]
pub enum Kind {
    /// 0 or 1.
    Bool,
    /// An integer or fixed-point value.
    Scalar(Scalar),
    /// A coded value.
    Enum(EnumRef),
    /// Bit fields of one value.
    Packed(Vec<Field>),
    /// Four octets, one per word.
    Ipv4,
    /// Version bytes.
    Version(Vec<String>),
    /// Several values in a row.
    Record(Vec<Field>),
}

impl Kind {
    /// The type's name in the spec language.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Bool => "bool",
            Self::Scalar(scalar) => scalar.as_str(),
            Self::Enum(_) => "enum",
            Self::Packed(_) => "packed",
            Self::Ipv4 => "ipv4",
            Self::Version(_) => "version",
            Self::Record(_) => "record",
        }
    }
}

/// A bit field of a packed register or a member of a record.
#[derive(Clone, Debug)]
pub struct Field {
    /// snake_case name.
    pub name: String,
    /// Lowest bit (packed fields).
    pub lsb: Option<u8>,
    /// Bits (packed fields).
    pub width: Option<u8>,
    /// Wire type (record members).
    pub scalar: Option<Scalar>,
    /// Coded values.
    pub enum_ref: Option<EnumRef>,
    /// Raw range.
    pub range: Option<(i64, i64)>,
    /// One raw step, exactly.
    pub scale: Option<ScaleSpec>,
    /// Unit.
    pub unit: Option<String>,
    /// Raw value meaning "invalid".
    pub sentinel: Option<u64>,
    /// English doc.
    pub doc: Option<String>,
    /// Where it is declared.
    pub path: Path,
}

/// A scale as written, and its exact value when well formed.
#[derive(Clone, Debug)]
pub struct ScaleSpec {
    /// The text in the spec (`1e-6`, `1/1048576`).
    pub text: String,
    /// The exact step, or why it is malformed.
    pub value: Result<Scale, String>,
    /// Where it is written.
    pub path: Path,
}

/// Which copy of a repeat block a register is.
#[derive(Clone, Debug)]
pub struct RepeatCopy {
    /// Index into `Model::repeats`.
    pub repeat: usize,
    /// 1-based copy number.
    pub number: u32,
    /// The register's name inside the block.
    pub base: String,
    /// Address distance between copies, if known.
    pub stride: Option<u32>,
}

/// A register (repeat copies are expanded, one `Register` per copy).
#[derive(Clone, Debug)]
pub struct Register {
    /// snake_case name; copies are `<repeat>_<n>_<name>`.
    pub name: String,
    /// Table.
    pub table: Table,
    /// First address.
    pub address: Address,
    /// Who may read and write.
    pub access: Access,
    /// Value type.
    pub kind: Kind,
    /// Words a read transfers.
    pub words: WordCount,
    /// Words as declared, if declared.
    pub declared_words: Option<u32>,
    /// English doc.
    pub doc: Option<String>,
    /// The manual's name.
    pub zh: Option<String>,
    /// Manual section.
    pub section: Option<String>,
    /// Errata.
    pub note: Option<String>,
    /// One raw step.
    pub scale: Option<ScaleSpec>,
    /// Unit.
    pub unit: Option<String>,
    /// Raw range.
    pub range: Option<(i64, i64)>,
    /// The only raw values a write may give, if the manual lists them, and where they are
    /// written.
    pub allowed_values: Option<(Vec<i64>, Path)>,
    /// Raw bits meaning "invalid".
    pub sentinel: Option<u64>,
    /// Which word is at the lower address.
    pub word_order: WordOrder,
    /// Which word of a split write goes first, if declared.
    pub write_order: Option<WriteOrder>,
    /// The register this one deliberately overlaps.
    pub alias_of: Option<String>,
    /// What reading the register changes in the device (a read that turns a buffer page):
    /// such a read is never retried.
    pub read_side_effect: Option<String>,
    /// Writing it acts and the manual does not say what a read returns: it is never read.
    pub action: bool,
    /// What it is to the device as a whole (firmware version, serial number), if declared.
    pub role: Option<Role>,
    /// Set for repeat copies.
    pub repeat: Option<RepeatCopy>,
    /// Where it is declared (for copies: the block's entry).
    pub path: Path,
}

impl Register {
    /// The scalar a read decodes to, for types that have one.
    pub fn scalar(&self) -> Option<Scalar> {
        match &self.kind {
            Kind::Scalar(scalar) => Some(*scalar),
            Kind::Bool => Some(Scalar::U16),
            Kind::Enum(_) | Kind::Packed(_) => Some(Scalar::unsigned(self.words.0)),
            _ => None,
        }
    }

    /// Whether the register may be read: not write-only and not an action register.
    pub fn readable(&self) -> bool {
        self.access.readable() && !self.action
    }
}

/// An address range the device reserves.
#[derive(Clone, Debug)]
pub struct Reserved {
    /// Table.
    pub table: Table,
    /// First address.
    pub from: u32,
    /// Last address (inclusive).
    pub to: u32,
    /// Reads may cover it (inferred from the manual's table sizes, see `specs/README.md`).
    pub readable: bool,
    /// Where it is declared.
    pub path: Path,
}

/// A write that acts.
#[derive(Clone, Debug)]
pub struct Command {
    /// snake_case name; the driver method.
    pub name: String,
    /// The register written (a register or a repeat block's base name).
    pub register: String,
    /// The value written.
    pub value: i64,
    /// How long the device is busy afterwards.
    pub busy_ms: Option<u32>,
    /// The value the register reads once the device has finished (`done_when`).
    pub done_when: Option<i64>,
    /// How long after the write the device may take to finish (`within_ms`).
    pub within_ms: Option<u32>,
    /// What the device does.
    pub effect: Effect,
    /// Registers the effect concerns.
    pub targets: Vec<String>,
    /// English doc.
    pub doc: Option<String>,
    /// Manual section.
    pub section: Option<String>,
    /// Where it is declared.
    pub path: Path,
}

impl Command {
    /// How the device shows it finished: `done_when` read back within `within_ms` (both
    /// given, the value a `u32`; the `command` rule reports anything else).
    pub fn completion(&self) -> Option<optobus_device::Completion> {
        Some(optobus_device::Completion {
            value: u32::try_from(self.done_when?).ok()?,
            within_ms: self.within_ms?,
        })
    }
}

/// Registers read together.
#[derive(Clone, Debug)]
pub struct Group {
    /// snake_case name; the driver method is `read_<name>`.
    pub name: String,
    /// Member names (registers or repeat base names), with where each is written.
    pub registers: Vec<(String, Path)>,
    /// English doc.
    pub doc: Option<String>,
    /// Where it is declared.
    pub path: Path,
}

/// A name the spec refers to, and where it is written.
#[derive(Clone, Debug)]
pub struct NameRef {
    /// The name.
    pub name: String,
    /// Where it is written.
    pub path: Path,
}

/// The data buffer (`buffer:`): which registers, commands and group take part.
#[derive(Clone, Debug)]
pub struct Buffer {
    /// Manual section.
    pub section: Option<String>,
    /// English doc.
    pub doc: Option<String>,
    /// Enum register choosing what is buffered.
    pub source: Option<NameRef>,
    /// Writable register: how many values to buffer.
    pub count: NameRef,
    /// Most values that may be read out, and where it is written.
    pub most: (u32, Path),
    /// Command locking the buffer for read-out.
    pub lock: NameRef,
    /// Command unlocking (clearing) it.
    pub unlock: NameRef,
    /// Group read once per page.
    pub page: NameRef,
    /// Page member: values handed out since the lock.
    pub read_count: NameRef,
    /// Page member: valid values in this page.
    pub valid_count: NameRef,
    /// Repeat member of the page: the values.
    pub values: NameRef,
    /// Enum register whose code meanings are durations.
    pub interval: Option<NameRef>,
    /// Unsigned integer register: measurements per buffered value (the interval's multiple).
    pub ratio: Option<NameRef>,
    /// Where it is declared.
    pub path: Path,
}

/// A repeat block.
#[derive(Clone, Debug)]
pub struct Repeat {
    /// The index name (`channel`).
    pub name: String,
    /// Number of copies.
    pub count: u32,
    /// Stride of holding registers.
    pub holding_stride: Option<u32>,
    /// Stride of input registers.
    pub input_stride: Option<u32>,
    /// English doc.
    pub doc: Option<String>,
    /// Base names of its registers.
    pub members: Vec<String>,
    /// Where it is declared.
    pub path: Path,
}

/// RTU line settings.
#[derive(Clone, Debug)]
pub struct Rtu {
    /// Factory baud rate.
    pub default_baud: u32,
    /// Baud rates the device supports.
    pub bauds: Vec<u32>,
    /// Parity.
    pub parity: Parity,
    /// Data bits.
    pub data_bits: u8,
    /// Stop bits.
    pub stop_bits: u8,
}

/// Modbus TCP settings.
#[derive(Clone, Debug)]
pub struct Tcp {
    /// Listening port.
    pub port: u16,
    /// Factory IP address.
    pub default_ip: Option<Ipv4Addr>,
}

/// Device facts.
#[derive(Clone, Debug)]
pub struct Device {
    /// RTU, if supported.
    pub rtu: Option<Rtu>,
    /// TCP, if supported.
    pub tcp: Option<Tcp>,
    /// Factory slave address.
    pub default_slave: u8,
    /// Lowest slave address.
    pub min_slave: u8,
    /// Highest slave address.
    pub max_slave: u8,
    /// Function codes answered.
    pub functions: Vec<u8>,
    /// Most words per read.
    pub max_read_words: u16,
    /// Power-up delay.
    pub power_up_ms: Option<u32>,
    /// Holding registers that exist.
    pub holding_size: u32,
    /// Input registers that exist.
    pub input_size: u32,
}

impl Device {
    /// How many registers `table` has.
    pub fn table_size(&self, table: Table) -> u32 {
        match table {
            Table::Holding => self.holding_size,
            Table::Input => self.input_size,
        }
    }
}

/// Protocol quirks.
#[derive(Clone, Debug)]
pub struct Protocol {
    /// One address per word or per field.
    pub addressing: Addressing,
    /// How 32-bit values are written.
    pub long_writes: LongWrites,
    /// Exception frame shape.
    pub exception: ExceptionStyle,
    /// When changes take effect.
    pub apply: Apply,
    /// The enum of the device's exception codes, if the manual lists them.
    pub exception_codes: Option<EnumRef>,
    /// Register and code that switch on unsolicited sending.
    pub continuous_send: Option<(String, i64, Path)>,
}

/// The manual a spec comes from.
#[derive(Clone, Debug)]
pub struct Manual {
    /// File name in `shared/manuals`.
    pub file: String,
    /// Protocol version.
    pub version: Option<String>,
    /// Date.
    pub date: Option<String>,
}

/// A whole spec, lowered.
#[derive(Clone, Debug)]
pub struct Model {
    /// snake_case family id.
    pub family: String,
    /// Title.
    pub title: String,
    /// Other names the model answers to in tools.
    pub aliases: Vec<String>,
    /// Source manual.
    pub manual: Manual,
    /// Device facts.
    pub device: Device,
    /// Protocol quirks.
    pub protocol: Protocol,
    /// Shared and inline enums.
    pub enums: Vec<EnumDef>,
    /// Registers, repeats expanded.
    pub registers: Vec<Register>,
    /// Reserved ranges.
    pub reserved: Vec<Reserved>,
    /// Commands.
    pub commands: Vec<Command>,
    /// Groups.
    pub groups: Vec<Group>,
    /// Repeat blocks.
    pub repeats: Vec<Repeat>,
    /// The data buffer, if the device has one.
    pub buffer: Option<Buffer>,
    /// Names of items a reading error left out (already reported): references to them, or
    /// to names they start (a block's copies), are not reported again.
    pub unread: BTreeSet<String>,
}

impl Model {
    /// The register called `name`.
    pub fn register(&self, name: &str) -> Option<&Register> {
        self.registers.iter().find(|r| r.name == name)
    }

    /// The register called `name`, or for a repeat block's member name its first copy
    /// (commands and groups may name a member for all its copies).
    pub fn resolve(&self, name: &str) -> Option<&Register> {
        self.register(name).or_else(|| {
            self.registers
                .iter()
                .find(|r| r.repeat.as_ref().is_some_and(|c| c.base == name))
        })
    }

    /// Number of addresses a register occupies.
    pub fn extent(&self, register: &Register) -> u32 {
        match self.protocol.addressing {
            Addressing::Word => register.words.0,
            Addressing::Field => 1,
        }
    }

    /// True when `name` may be an item a reading error left out: an unread name, or one it
    /// starts followed by `_` (a block's copies). One set lookup per `_` in `name`.
    pub fn is_unread(&self, name: &str) -> bool {
        self.unread.contains(name)
            || name
                .match_indices('_')
                .any(|(at, _)| self.unread.contains(&name[..at]))
    }

    /// The registers by name, for a pass that looks up many ([`Model::register`] walks the
    /// list): built once in linear time, each lookup a hash.
    pub fn register_names(&self) -> RegisterNames<'_> {
        let mut names = RegisterNames::default();
        for register in &self.registers {
            names.by_name.entry(&register.name).or_insert(register);
            if let Some(copy) = &register.repeat {
                names.by_member.entry(&copy.base).or_insert(register);
            }
        }
        names
    }

    /// The enum a reference resolves to.
    pub fn enum_def(&self, reference: &EnumRef) -> Option<&EnumDef> {
        reference.index.and_then(|i| self.enums.get(i))
    }
}

/// The registers of a model by name ([`Model::register_names`]); the first of a name wins, as
/// in [`Model::register`].
#[derive(Debug, Default)]
pub struct RegisterNames<'m> {
    by_name: HashMap<&'m str, &'m Register>,
    /// A repeat block's member name to its first copy.
    by_member: HashMap<&'m str, &'m Register>,
}

impl<'m> RegisterNames<'m> {
    /// The register called `name` ([`Model::register`]).
    pub fn register(&self, name: &str) -> Option<&'m Register> {
        self.by_name.get(name).copied()
    }

    /// The register called `name`, or a repeat member's first copy ([`Model::resolve`]).
    pub fn resolve(&self, name: &str) -> Option<&'m Register> {
        self.register(name)
            .or_else(|| self.by_member.get(name).copied())
    }
}
