//! The one write policy: what a request from the network (the gateway, the console, MQTT, and
//! any path that comes later) may ask of a device. Every such path asks a [`Policy`] before
//! anything goes to the line, and gets the same answer with the same message as `optobus set`
//! and `optobus do` give:
//!
//! - what is set or run is listed in the device's `writable` ([`Writable`]): a register, or a
//!   command (a write of a command's value to its register is that command);
//! - the register holding the slave address is never written: the bus addresses the device by
//!   it;
//! - a drastic command (store, restart, reset) and the registers it writes only where named
//!   (`writable: all` leaves them out, see [`Writable`]);
//! - every value passes the spec's checks (range, codes, steps);
//! - a read that changes the device (the P series' buffer page) only where the device's
//!   `writable` lists its buffer's lock and unlock commands, since reading out empties the
//!   buffer, as [`Handle::download_buffer`](crate::Handle::download_buffer) needs;
//! - a path may take no writes at all (a gateway without `writes: true`).
//!
//! A [`Refusal`] says which [`RefusalKind`] it is, so that each path answers in its own terms:
//! the gateway with exception 01, 02 or 03, the console with 403 or 422, MQTT on `/error`.

use optobus_codec::passthrough::{words, Access, PassPdu};
use optobus_device::{CommandInfo, DeviceInfo, Invalid, RegisterInfo, Table};
use optobus_inspect::{parse_value, resolve_one};

use crate::file::Writable;

/// What the network may ask of one device.
#[derive(Clone, Copy, Debug)]
pub struct Policy<'a> {
    /// The device's name in the bus file, for messages.
    device: &'a str,
    info: &'static DeviceInfo,
    /// What may be written; `None` on a path that takes no writes.
    writable: Option<&'a Writable>,
}

/// Why the policy refused a request; nothing of it was sent.
#[derive(Debug)]
#[non_exhaustive]
pub enum Refusal {
    /// The path takes no writes (a gateway whose line does not say `writes: true`).
    ReadOnly,
    /// The bus file's `writable` does not list the register or command for the device.
    NotListed {
        /// The device.
        device: String,
        /// The register or command as asked for.
        name: String,
        /// Whether it stores, restarts or resets the device (or is the register of such a
        /// command): `writable: all` leaves those out, they must be named.
        drastic: bool,
    },
    /// The register holds the device's slave address, which the bus addresses it by.
    SlaveAddress(&'static str),
    /// The register cannot be written (read-only), or the words are not the register's.
    NotWritable(&'static str),
    /// The register cannot be read.
    NotReadable(&'static str),
    /// Reading the register changes the device, and the device's `writable` does not list
    /// the commands that make such a read allowed.
    ChangesDevice {
        /// The device.
        device: String,
        /// The register.
        register: &'static str,
        /// What a read does, in the spec's words.
        effect: &'static str,
    },
    /// No register starts at the address, or a write covers part of a register.
    NoRegisterAt {
        /// The device.
        device: String,
        /// The holding register address asked for.
        address: u16,
    },
    /// The device's spec does not take the function for writing.
    FunctionNotTaken {
        /// The device.
        device: String,
        /// The function code.
        function: u8,
        /// The functions its spec lists.
        taken: &'static [u8],
    },
    /// A request to a slave that is no device of the bus file: nothing lists what it may take.
    UnknownSlave(u8),
    /// The value is one the register's spec refuses.
    Invalid {
        /// The register.
        register: &'static str,
        /// Why.
        why: Invalid,
    },
    /// The name or the value was refused as `optobus set` and `optobus do` refuse it (unknown
    /// name, a value out of range or off its steps, a unit that does not fit).
    Text(optobus_inspect::Error),
    /// A broadcast reaches every device of the line, and this one refuses it.
    Broadcast {
        /// The device that refuses.
        device: String,
        /// Why it does.
        refusal: Box<Refusal>,
    },
}

/// How a path answers a [`Refusal`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RefusalKind {
    /// Not allowed here: gateway exception 01, HTTP 403.
    NotAllowed,
    /// No such register: gateway exception 02.
    Address,
    /// A value (or a name) the device's spec refuses: gateway exception 03, HTTP 422.
    Value,
    /// No device of the bus file at that slave address: gateway exception 0B, at once.
    NoDevice,
}

impl Refusal {
    /// How a path answers it.
    pub fn kind(&self) -> RefusalKind {
        match self {
            Self::NoRegisterAt { .. } => RefusalKind::Address,
            Self::Invalid { .. } | Self::Text(_) => RefusalKind::Value,
            Self::Broadcast { refusal, .. } => refusal.kind(),
            Self::UnknownSlave(slave) if *slave != 0 => RefusalKind::NoDevice,
            _ => RefusalKind::NotAllowed,
        }
    }
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::ReadOnly => f.write_str(
                "writes are off here: the bus file's line does not say `writes: true` for its \
                 gateway",
            ),
            Self::NotListed {
                device,
                name,
                drastic,
            } => {
                write!(
                    f,
                    "`{name}` of `{device}` is not writable here: the bus file's `writable` does \
                     not list it"
                )?;
                if *drastic {
                    f.write_str(
                        " (it stores, restarts or resets the device: `all` leaves it out, it must \
                         be named)",
                    )?;
                }
                Ok(())
            }
            Self::SlaveAddress(register) => write!(
                f,
                "`{register}` is never written on a bus: the bus addresses the device by it"
            ),
            Self::NotWritable(register) => write!(f, "`{register}` cannot be written"),
            Self::NotReadable(register) => write!(f, "`{register}` cannot be read"),
            Self::ChangesDevice {
                device,
                register,
                effect,
            } => write!(
                f,
                "reading `{register}` of `{device}` changes the device ({effect}): it is read \
                 only where the bus file's `writable` lists the buffer's lock and unlock commands"
            ),
            Self::NoRegisterAt { device, address } => write!(
                f,
                "`{device}` has no writable register starting at holding address {address}, or \
                 the write covers part of one"
            ),
            Self::FunctionNotTaken {
                device,
                function,
                taken,
            } => {
                let taken: Vec<String> = taken.iter().map(|f| format!("{f:#04x}")).collect();
                write!(
                    f,
                    "`{device}` does not take function {function:#04x} for writing: its manual \
                     lists {}",
                    taken.join(", ")
                )
            }
            Self::UnknownSlave(0) => f.write_str(
                "a broadcast on a line where the bus file names no device: nothing lists what it \
                 may take",
            ),
            Self::UnknownSlave(slave) => write!(
                f,
                "slave {slave} is no device of the bus file: nothing lists what it may take"
            ),
            Self::Invalid { register, why } => write!(f, "`{register}` does not take it: {why}"),
            Self::Text(error) => error.fmt(f),
            Self::Broadcast { device, refusal } => write!(
                f,
                "a broadcast reaches every device of the line, and `{device}` refuses it: \
                 {refusal}"
            ),
        }
    }
}

impl std::error::Error for Refusal {}

impl<'a> Policy<'a> {
    /// The policy for device `device` of model `info`: what `writable` lists may be written,
    /// nothing where it is `None`.
    pub fn new(device: &'a str, info: &'static DeviceInfo, writable: Option<&'a Writable>) -> Self {
        Self {
            device,
            info,
            writable,
        }
    }

    /// Whether `register` may be set from `text` (read as `optobus set` reads it): the words
    /// to write.
    pub fn set(
        &self,
        register: &str,
        text: &str,
    ) -> Result<(&'static RegisterInfo, Vec<u16>), Refusal> {
        let found = resolve_one(self.info, register, None).map_err(Refusal::Text)?;
        let words = parse_value(found, text)
            .map_err(|error| Refusal::Text(optobus_inspect::Error::from(error)));
        let raw = words.as_ref().ok().map(|words| found.raw(words));
        self.may_write(found, raw)?;
        Ok((found, words?))
    }

    /// Whether command `command` may be run: the command and the register it writes.
    pub fn run(
        &self,
        command: &str,
    ) -> Result<(&'static CommandInfo, &'static RegisterInfo), Refusal> {
        let info = self.info;
        let found = info.command(command).ok_or_else(|| {
            let names: Vec<&str> = info.commands.iter().map(|c| c.name).collect();
            Refusal::Text(
                optobus_inspect::Error::new(format!(
                    "`{command}` is no command of {}",
                    info.model_name()
                ))
                .hint(format!("commands: {}", names.join(", "))),
            )
        })?;
        let writable = self.writable.ok_or(Refusal::ReadOnly)?;
        if !writable.allows_command(found) {
            return Err(self.not_listed(command, found.effect.is_drastic()));
        }
        let register = resolve_one(info, found.register, None).map_err(Refusal::Text)?;
        Ok((found, register))
    }

    /// Whether `register` may be read now.
    pub fn read(&self, register: &'static RegisterInfo) -> Result<(), Refusal> {
        if !register.readable() {
            return Err(Refusal::NotReadable(register.name));
        }
        match register.read_side_effect {
            None => Ok(()),
            Some(effect) => self.may_read_changing(register, effect),
        }
    }

    /// Whether the device's data buffer may be read out (lock, pages, unlock): its lock and
    /// unlock commands must be listed, since reading out empties it.
    pub fn buffer(&self) -> Result<(), Refusal> {
        let buffer = self.info.buffer.ok_or_else(|| {
            Refusal::Text(optobus_inspect::Error::new(format!(
                "{} has no data buffer",
                self.info.model_name()
            )))
        })?;
        for name in [buffer.lock, buffer.unlock] {
            self.run(name)?;
        }
        Ok(())
    }

    /// Whether a gateway's request may go to the device: a write only of listed registers
    /// (or listed commands) with values the spec accepts, a read only of registers whose read
    /// changes nothing or is allowed ([`Policy::read`]).
    pub fn pass(&self, pdu: &PassPdu<'_>) -> Result<(), Refusal> {
        match pdu.access() {
            Access::ReadRegisters {
                input,
                address,
                count,
            } => {
                let table = if input { Table::Input } else { Table::Holding };
                let end = u32::from(address) + u32::from(count);
                let changing = self.info.registers.iter().filter(|register| {
                    let start = u32::from(register.address);
                    let span = u32::from(register.span(self.info.addressing));
                    register.table == table
                        && start < end
                        && start + span > u32::from(address)
                        && !register.read_is_repeatable()
                });
                for register in changing {
                    self.read(register)?;
                }
                Ok(())
            }
            Access::WriteRegisters { address, data } => {
                self.writable.ok_or(Refusal::ReadOnly)?;
                if !self.info.functions.contains(&pdu.function()) {
                    return Err(self.function_not_taken(pdu.function()));
                }
                let words: Vec<u16> = words(data).collect();
                self.write_words(address, &words)
            }
            Access::Other { writes: false } => Ok(()),
            // Bits, files, masks: no register of a spec is written that way.
            Access::Other { writes: true } => {
                self.writable.ok_or(Refusal::ReadOnly)?;
                Err(self.function_not_taken(pdu.function()))
            }
        }
    }

    /// Every register `words` cover from `address` must be written whole and may be written
    /// with its value.
    fn write_words(&self, address: u16, words: &[u16]) -> Result<(), Refusal> {
        let mut at = Some(address);
        let mut offset = 0;
        while offset < words.len() {
            let no_register = || Refusal::NoRegisterAt {
                device: self.device.to_owned(),
                address: at.unwrap_or(u16::MAX),
            };
            let Some((register, 0)) = at.and_then(|at| self.info.register_at(Table::Holding, at))
            else {
                return Err(no_register());
            };
            let width = usize::from(register.words);
            let Some(own) = words.get(offset..offset + width) else {
                return Err(no_register());
            };
            self.may_write(register, Some(register.raw(own)))?;
            offset += width;
            at = at.and_then(|a| a.checked_add(register.span(self.info.addressing)));
        }
        Ok(())
    }

    /// Whether `register` may be written with `raw` (`None`: a value that did not parse, whose
    /// refusal the caller gives once the register may be written at all).
    fn may_write(&self, register: &'static RegisterInfo, raw: Option<u32>) -> Result<(), Refusal> {
        if self
            .info
            .slave_address_register()
            .is_some_and(|own| own.name == register.name)
        {
            return Err(Refusal::SlaveAddress(register.name));
        }
        if !register.access.writable() {
            return Err(Refusal::NotWritable(register.name));
        }
        let writable = self.writable.ok_or(Refusal::ReadOnly)?;
        if writable.allows_register(register) {
            let Some(raw) = raw else { return Ok(()) };
            return register.check(raw).map_err(|why| Refusal::Invalid {
                register: register.name,
                why,
            });
        }
        let command = raw.and_then(|raw| self.info.command_writing(register, raw));
        match command {
            Some(command) if writable.allows_command(command) => Ok(()),
            _ => {
                let drastic = self.info.drastic_commands_on(register).next().is_some();
                Err(self.not_listed(register.name, drastic))
            }
        }
    }

    /// A read that changes the device is allowed where it is the buffer's, and the buffer's
    /// lock and unlock commands are listed.
    fn may_read_changing(
        &self,
        register: &'static RegisterInfo,
        effect: &'static str,
    ) -> Result<(), Refusal> {
        let of_buffer = self.info.buffer.is_some_and(|buffer| {
            register.name == buffer.values || register.member_name() == Some(buffer.values)
        });
        if of_buffer && self.buffer().is_ok() {
            return Ok(());
        }
        Err(Refusal::ChangesDevice {
            device: self.device.to_owned(),
            register: register.name,
            effect,
        })
    }

    fn not_listed(&self, name: &str, drastic: bool) -> Refusal {
        Refusal::NotListed {
            device: self.device.to_owned(),
            name: name.to_owned(),
            drastic,
        }
    }

    fn function_not_taken(&self, function: u8) -> Refusal {
        Refusal::FunctionNotTaken {
            device: self.device.to_owned(),
            function,
            taken: self.info.functions,
        }
    }
}

/// The holding registers of `info` that a write of `words` words from `address` covers, in
/// address order (a register covered in part too; the policy lets only whole ones through).
pub(crate) fn written(
    info: &'static DeviceInfo,
    address: u16,
    words: usize,
) -> Vec<&'static RegisterInfo> {
    let mut registers = Vec::new();
    let mut at = Some(address);
    let mut offset = 0;
    while offset < words {
        let Some((register, inside)) = at.and_then(|at| info.register_at(Table::Holding, at))
        else {
            // No register there: the next word's address.
            offset += 1;
            at = at.and_then(|a| a.checked_add(1));
            continue;
        };
        registers.push(register);
        let span = register.span(info.addressing);
        let left = usize::from(register.words.saturating_sub(inside.min(register.words)));
        offset += left.max(1);
        at = at.and_then(|a| a.checked_add(span.saturating_sub(inside).max(1)));
    }
    registers
}

#[cfg(test)]
mod tests {
    use super::written;

    fn names(registers: Vec<&'static optobus_device::RegisterInfo>) -> Vec<&'static str> {
        registers.into_iter().map(|r| r.name).collect()
    }

    #[test]
    fn a_write_is_told_as_the_registers_it_covers() {
        let p = &optobus_p_series::DEVICE;
        // Word addressing: thickness_zero (26, one word), then the two words of the u32
        // position_1_slope (27) and position_1_offset (29).
        assert_eq!(
            names(written(p, 26, 5)),
            ["thickness_zero", "position_1_slope", "position_1_offset"]
        );
        // The second word of a u32 alone (the policy refuses it; told all the same).
        assert_eq!(names(written(p, 28, 1)), ["position_1_slope"]);
        // Field addressing: one address per field, a 4-byte field is two words at one address.
        let ranger = &optobus_rangefinder::DEVICE;
        let field = ranger.register("dac_range_min").unwrap();
        assert_eq!(names(written(ranger, field.address, 2)), ["dac_range_min"]);
    }
}
