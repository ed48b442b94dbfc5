//! The device types: a device and what it holds besides its registers (commands, groups, the
//! data buffer, line settings, addressing), and the lookups every side makes the same way.

use optobus_codec::{FrameShape, Parity};

use crate::register::*;

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
