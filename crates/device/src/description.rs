//! The description types: a device, its registers (value kinds, codes, fields, repeat
//! copies), reserved ranges, commands, groups and line settings, and the register facts every
//! side looks up the same way.

use optobus_codec::value::{Scale, WordOrder, WriteOrder};
use optobus_codec::{FrameShape, Parity, ReadFunction};

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

/// What a command does (the simulator acts it out).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Deserialize, serde::Serialize),
    serde(rename_all = "snake_case")
)]
pub enum Effect {
    /// Makes the current reading of the targets their zero.
    Zero,
    /// Removes the targets' zero offset.
    ClearZero,
    /// Resets the targets (statistics, counters).
    Reset,
    /// Stores the parameters in flash.
    Save,
    /// Restarts the device.
    Reboot,
    /// Restores factory settings.
    FactoryReset,
    /// Restores factory network settings.
    NetworkReset,
    /// Locks the data buffer for reading.
    BufferLock,
    /// Unlocks the data buffer.
    BufferUnlock,
    /// Nothing the simulator models.
    None,
}

impl Effect {
    /// Whether the effect stores, restarts or resets the device: what tools ask to confirm.
    pub const fn is_drastic(self) -> bool {
        matches!(
            self,
            Self::Save | Self::Reboot | Self::FactoryReset | Self::NetworkReset
        )
    }
}

/// A write that acts rather than sets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct CommandInfo {
    /// snake_case name.
    pub name: &'static str,
    /// English description.
    pub doc: &'static str,
    /// The register written (a repeat block's base name for per-copy commands).
    pub register: &'static str,
    /// The value written.
    pub value: u32,
    /// Milliseconds the device is busy afterwards.
    pub busy_ms: u32,
    /// What the device does.
    pub effect: Effect,
    /// Registers the effect concerns.
    pub targets: &'static [&'static str],
    /// How the device shows the command finished, where its manual says so (the spec's
    /// `done_when` and `within_ms`): the command is done only once its register reads this.
    pub done_when: Option<Completion>,
}

/// A command's register reading back a value once the device has finished (P series, CCS
/// and CCF `save_parameters`: the flag clears itself when the flash write is over).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct Completion {
    /// The raw value the command's register reads once the device has finished.
    pub value: u32,
    /// How long after the write (busy time included) the device may take; past it the
    /// command counts as not finished.
    pub within_ms: u32,
}

/// Registers read together.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct GroupInfo {
    /// snake_case name.
    pub name: &'static str,
    /// English description.
    pub doc: &'static str,
    /// Member registers (repeat base names stand for every copy).
    pub registers: &'static [&'static str],
}

/// A data buffer the device fills by itself and hands out in pages (the spec's `buffer:`
/// section): which registers, commands and group take part, by name.
///
/// Buffering starts by writing the source (if any) and the count, then unlocking; a download
/// locks, reads `page` until `count` values or an empty page, and unlocks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct BufferInfo {
    /// Manual section describing the buffer.
    pub section: &'static str,
    /// English description.
    pub doc: &'static str,
    /// Enum register choosing what is buffered; its code names are the registers buffered.
    pub source: Option<&'static str>,
    /// Writable register: how many values to buffer (0 turns buffering off).
    pub count: &'static str,
    /// Most values that may be read out.
    pub most: u32,
    /// Command freezing the buffer for read-out.
    pub lock: &'static str,
    /// Command clearing the buffer and buffering anew.
    pub unlock: &'static str,
    /// Group read once per page; reading it turns the page.
    pub page: &'static str,
    /// Page member: values handed out since the lock (this page included, or before it: the
    /// P series manual leaves it open, appendix 3 (3)).
    pub read_count: &'static str,
    /// Page member: valid values in this page.
    pub valid_count: &'static str,
    /// Repeat member of the page: the page's values, oldest first.
    pub values: &'static str,
    /// Enum register whose code meanings are the sampling intervals.
    pub interval: Option<&'static str>,
    /// Unsigned integer register: one value in this many is buffered, so values lie
    /// `interval × ratio` apart (P series appendix 3 (5)); without it, every value.
    pub ratio: Option<&'static str>,
}

/// Serial line settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RtuInfo {
    /// Factory baud rate.
    pub default_baud: u32,
    /// Supported baud rates.
    pub bauds: &'static [u32],
    /// Factory parity.
    pub parity: Parity,
    /// Data bits.
    pub data_bits: u8,
    /// Stop bits.
    pub stop_bits: u8,
}

/// Modbus TCP settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TcpInfo {
    /// Listening port.
    pub port: u16,
    /// Factory IP address, as octets.
    pub default_ip: Option<[u8; 4]>,
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

/// How 32-bit values are written.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Deserialize, serde::Serialize),
    serde(rename_all = "snake_case")
)]
pub enum LongWrites {
    /// Two single-register writes.
    Split,
    /// One FC06 carrying four data bytes.
    Wide,
}

/// The name of the register that holds a device's own slave address, in every spec that has
/// one (see [`DeviceInfo::slave_address_register`]).
pub const SLAVE_ADDRESS_REGISTER: &str = "slave_address";

/// Everything the spec says about a device.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeviceInfo {
    /// snake_case family id.
    pub family: &'static str,
    /// Title.
    pub title: &'static str,
    /// Other names tools accept for the model (`lc` for `lc_rs`).
    pub aliases: &'static [&'static str],
    /// Source manual file.
    pub manual: &'static str,
    /// Serial settings, if the device speaks RTU.
    pub rtu: Option<RtuInfo>,
    /// TCP settings, if the device speaks Modbus TCP.
    pub tcp: Option<TcpInfo>,
    /// Factory slave address.
    pub default_slave: u8,
    /// Valid slave addresses.
    pub slaves: (u8, u8),
    /// Function codes the device answers.
    pub functions: &'static [u8],
    /// Most words one read may ask for.
    pub max_read_words: u16,
    /// Milliseconds from power-up until the device answers.
    pub power_up_ms: u32,
    /// Holding registers that exist.
    pub holding_registers: u16,
    /// Input registers that exist.
    pub input_registers: u16,
    /// What one address holds.
    pub addressing: Addressing,
    /// How 32-bit values are written.
    pub long_writes: LongWrites,
    /// Exception frames and 4-byte writes, as the codec needs them.
    pub frame_shape: FrameShape<'static>,
    /// Settings take effect only after the save command and a power cycle.
    pub needs_save_and_power_cycle: bool,
    /// The codes the device sends in exception replies, with their meanings; empty when the
    /// manual lists none (the standard Modbus codes apply).
    pub exception_codes: &'static [CodeInfo],
    /// Register and code that make the device stream readings unasked.
    pub continuous_send: Option<(&'static str, u32)>,
    /// Every register, repeats expanded.
    pub registers: &'static [RegisterInfo],
    /// Reserved ranges.
    pub reserved: &'static [ReservedInfo],
    /// Commands.
    pub commands: &'static [CommandInfo],
    /// Groups.
    pub groups: &'static [GroupInfo],
    /// The data buffer, if the device has one.
    pub buffer: Option<&'static BufferInfo>,
}

/// A family id as people type the model's name: `-` for `_` (`p_series` is `p-series`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModelName<'a>(pub &'a str);

impl core::fmt::Display for ModelName<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        for part in self.0.split('_').enumerate() {
            match part {
                (0, first) => f.write_str(first)?,
                (_, next) => write!(f, "-{next}")?,
            }
        }
        Ok(())
    }
}

impl DeviceInfo {
    /// The model's name as people type it (`p-series`); see [`ModelName`].
    pub fn model_name(&self) -> ModelName<'static> {
        ModelName(self.family)
    }

    /// Whether people mean this model by `name`: its family id or one of its aliases, in any
    /// case, with or without `-`, `_` and spaces (`P-Series`, `p_series`, `pseries`).
    pub fn is_called(&self, name: &str) -> bool {
        fn letters(text: &str) -> impl Iterator<Item = char> + '_ {
            text.chars()
                .filter(char::is_ascii_alphanumeric)
                .map(|c| c.to_ascii_lowercase())
        }
        let same = |known: &str| letters(known).eq(letters(name));
        same(self.family) || self.aliases.iter().any(|alias| same(alias))
    }

    /// The register called `name`.
    pub fn register(&self, name: &str) -> Option<&'static RegisterInfo> {
        self.registers.iter().find(|r| r.name == name)
    }

    /// The registers `name` stands for in groups and commands: the register of that name, or
    /// every copy of the repeat member of that name, in copy order.
    pub fn members<'a>(&self, name: &'a str) -> impl Iterator<Item = &'static RegisterInfo> + 'a {
        let registers = self.registers;
        let single = self.register(name);
        let copies = registers
            .iter()
            .filter(move |r| single.is_none() && r.member_name() == Some(name));
        single.into_iter().chain(copies)
    }

    /// The registers a full read of the device (a dump) asks for: every register that may be
    /// read (see [`RegisterInfo::readable`]).
    pub fn readable_registers(&self) -> impl Iterator<Item = &'static RegisterInfo> {
        self.registers.iter().filter(|r| r.readable())
    }

    /// The registers a dump of the device reads: every readable one whose read changes
    /// nothing (a buffer page that a read turns is left to be read by name).
    pub fn dump_registers(&self) -> impl Iterator<Item = &'static RegisterInfo> {
        self.readable_registers().filter(|r| r.read_is_repeatable())
    }

    /// Whether `address` of `table` lies in a reserved range the spec marks readable.
    pub fn reserved_readable(&self, table: Table, address: u16) -> bool {
        self.reserved
            .iter()
            .any(|r| r.readable && r.contains(table, address))
    }

    /// The command called `name`.
    pub fn command(&self, name: &str) -> Option<&'static CommandInfo> {
        self.commands.iter().find(|c| c.name == name)
    }

    /// The group called `name`.
    pub fn group(&self, name: &str) -> Option<&'static GroupInfo> {
        self.groups.iter().find(|g| g.name == name)
    }

    /// The register the spec gives `role` (see [`Role`]).
    pub fn register_with_role(&self, role: Role) -> Option<&'static RegisterInfo> {
        self.registers.iter().find(|r| r.role == Some(role))
    }

    /// The register holding the device's own Modbus slave address: by convention of the
    /// specs, the register named `slave_address` (P series, rangefinder, LC-RS). `None` for
    /// devices whose address is not a register (or not one a spec names so).
    pub fn slave_address_register(&self) -> Option<&'static RegisterInfo> {
        self.register(SLAVE_ADDRESS_REGISTER)
    }

    /// The register `address` of `table` belongs to, and which of its addresses it is (0 for
    /// its first; always 0 with one address per field). A register starting at `address` is
    /// preferred to one it lies inside of (aliases overlap).
    pub fn register_at(&self, table: Table, address: u16) -> Option<(&'static RegisterInfo, u16)> {
        let starting = self
            .registers
            .iter()
            .find(|r| r.table == table && r.address == address);
        if let Some(register) = starting {
            return Some((register, 0));
        }
        self.registers.iter().find_map(|r| {
            let offset = address.checked_sub(r.address)?;
            (r.table == table && offset < r.span(self.addressing)).then_some((r, offset))
        })
    }

    /// The command that writes `raw` to `register` (a register of its own, or a repeat copy of
    /// the command's register), if one does.
    pub fn command_writing(
        &self,
        register: &RegisterInfo,
        raw: u32,
    ) -> Option<&'static CommandInfo> {
        self.commands.iter().find(|c| {
            c.value == raw
                && (c.register == register.name || register.member_name() == Some(c.register))
        })
    }

    /// The commands that write `register` (a register of their own, or a repeat copy of the
    /// command's register) and store, restart or reset the device: a write there needs the
    /// confirmation a drastic command needs.
    pub fn drastic_commands_on(
        &self,
        register: &RegisterInfo,
    ) -> impl Iterator<Item = &'static CommandInfo> + '_ {
        let member = register.member_name();
        let name = register.name;
        self.commands.iter().filter(move |c| {
            c.effect.is_drastic() && (c.register == name || member == Some(c.register))
        })
    }

    /// How many registers `table` has.
    pub const fn table_size(&self, table: Table) -> u16 {
        match table {
            Table::Holding => self.holding_registers,
            Table::Input => self.input_registers,
        }
    }
}

#[cfg(all(test, feature = "serde"))]
mod tests {
    use super::*;

    #[test]
    fn descriptions_serialise_in_the_spec_language() {
        let command = CommandInfo {
            name: "zero_position",
            doc: "Zeroes.",
            register: "position_zero",
            value: 1,
            busy_ms: 0,
            effect: Effect::Zero,
            targets: &["distance_1"],
            done_when: Some(Completion {
                value: 0,
                within_ms: 2000,
            }),
        };
        assert_eq!(
            serde_json::to_string(&command).unwrap(),
            r#"{"name":"zero_position","doc":"Zeroes.","register":"position_zero","value":1,"busy_ms":0,"effect":"zero","targets":["distance_1"],"done_when":{"value":0,"within_ms":2000}}"#
        );
        assert_eq!(
            serde_json::to_string(&Access::ReadWrite).unwrap(),
            r#""rw""#
        );
        assert_eq!(serde_json::to_string(&Table::Input).unwrap(), r#""input""#);
    }
}
