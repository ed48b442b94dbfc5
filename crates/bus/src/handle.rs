//! Asking a running bus to write, run a command or read now: jobs that go onto their line
//! ahead of its polls.
//!
//! A write is checked against the register's spec before it is queued (nothing invalid reaches
//! the line), is made once (writes are never retried), and is followed by the device's busy
//! time for commands. A broadcast write reaches every device of a line and is followed by the
//! line's broadcast turnaround before the next request.

use std::sync::Arc;

use optobus_device::{CommandInfo, DeviceInfo, Invalid, RegisterInfo};
use optobus_driver::Encode;
use optobus_inspect::{decode_value, parse_value, resolve_one, Value};
use tokio::sync::{mpsc, oneshot};

use crate::file::Writable;

/// Jobs a line keeps queued for its API callers.
pub(crate) const JOB_QUEUE: usize = 64;

/// What an API caller asked a line to do.
#[derive(Debug)]
pub(crate) enum Job {
    /// Write checked words to a register of a device (slave 0: a broadcast).
    Write {
        device: usize,
        register: &'static RegisterInfo,
        words: Vec<u16>,
        broadcast: bool,
        done: oneshot::Sender<Result<(), optobus_driver::Error>>,
    },
    /// Run a command.
    Run {
        device: usize,
        command: &'static CommandInfo,
        register: &'static RegisterInfo,
        done: oneshot::Sender<Result<(), optobus_driver::Error>>,
    },
    /// Read registers now.
    Read {
        device: usize,
        registers: Vec<&'static RegisterInfo>,
        done: oneshot::Sender<Result<Vec<Value>, optobus_driver::Error>>,
    },
}

/// Words [`Handle::write`] checked against the register's spec, written as they are.
pub(crate) struct Checked(pub(crate) Vec<u16>);

impl Encode for Checked {
    fn encode(&self, _: &'static RegisterInfo) -> Result<Vec<u16>, optobus_driver::Error> {
        Ok(self.0.clone())
    }
}

/// A device as the handle finds it.
#[derive(Clone, Debug)]
pub(crate) struct Entry {
    pub(crate) name: String,
    pub(crate) line: usize,
    /// Its index among its line's devices.
    pub(crate) index: usize,
    pub(crate) device: &'static DeviceInfo,
    /// What writes from the network may change.
    pub(crate) writable: Writable,
}

/// Why a job was not done.
#[derive(Debug)]
#[non_exhaustive]
pub enum JobError {
    /// No device of that name on the bus.
    UnknownDevice(String),
    /// The register cannot be written (read-only), or the words are not the register's.
    NotWritable(&'static str),
    /// The value is one the register's spec refuses; nothing was sent.
    Invalid {
        /// The register.
        register: &'static str,
        /// Why.
        why: Invalid,
    },
    /// The register or command is not one the bus file's `writable` lists for the device;
    /// nothing was sent.
    NotListed {
        /// The device.
        device: String,
        /// The register or command as asked for.
        name: String,
    },
    /// The name or the value was refused as `optobus set` and `optobus do` refuse it (unknown
    /// name, a value out of range or off its steps, a unit that does not fit); nothing was sent.
    Refused(optobus_inspect::Error),
    /// The line's task has stopped.
    Stopped,
    /// The device or the line failed.
    Device(optobus_driver::Error),
}

impl std::fmt::Display for JobError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::UnknownDevice(name) => write!(f, "the bus has no device `{name}`"),
            Self::NotWritable(register) => write!(f, "`{register}` cannot be written"),
            Self::Invalid { register, why } => write!(f, "`{register}` does not take it: {why}"),
            Self::NotListed { device, name } => write!(
                f,
                "`{name}` of `{device}` is not writable here: the bus file's `writable` does not \
                 list it"
            ),
            Self::Refused(error) => error.fmt(f),
            Self::Stopped => f.write_str("the bus has stopped"),
            Self::Device(error) => error.fmt(f),
        }
    }
}

impl std::error::Error for JobError {}

/// A cloneable handle on a running bus's lines.
#[derive(Clone, Debug)]
pub struct Handle {
    pub(crate) lines: Arc<[mpsc::Sender<Job>]>,
    pub(crate) devices: Arc<[Entry]>,
}

impl Handle {
    fn entry(&self, device: &str) -> Result<&Entry, JobError> {
        self.devices
            .iter()
            .find(|entry| entry.name == device)
            .ok_or_else(|| JobError::UnknownDevice(device.to_owned()))
    }

    /// The model of device `name`.
    pub fn device_info(&self, name: &str) -> Option<&'static DeviceInfo> {
        self.entry(name).ok().map(|entry| entry.device)
    }

    async fn send<T>(
        &self,
        line: usize,
        job: impl FnOnce(oneshot::Sender<Result<T, optobus_driver::Error>>) -> Job,
    ) -> Result<T, JobError> {
        let (done, result) = oneshot::channel();
        self.lines[line]
            .send(job(done))
            .await
            .map_err(|_| JobError::Stopped)?;
        result
            .await
            .map_err(|_| JobError::Stopped)?
            .map_err(JobError::Device)
    }

    /// Writes `words` (the register's whole value, as `optobus_inspect::parse_value` gives
    /// them) to `register` of device `device`, ahead of the line's polls; with `broadcast`,
    /// to every device of its line (slave 0).
    pub async fn write(
        &self,
        device: &str,
        register: &'static RegisterInfo,
        words: Vec<u16>,
        broadcast: bool,
    ) -> Result<(), JobError> {
        let entry = self.entry(device)?;
        if !register.access.writable() || words.len() != usize::from(register.words) {
            return Err(JobError::NotWritable(register.name));
        }
        register
            .check(register.raw(&words))
            .map_err(|why| JobError::Invalid {
                register: register.name,
                why,
            })?;
        let index = entry.index;
        self.send(entry.line, |done| Job::Write {
            device: index,
            register,
            words,
            broadcast,
            done,
        })
        .await
    }

    /// Runs `command` of device `device` (on the copy `register` of its register), ahead of
    /// the line's polls, and waits out its busy time.
    pub async fn run(
        &self,
        device: &str,
        command: &'static CommandInfo,
        register: &'static RegisterInfo,
    ) -> Result<(), JobError> {
        let entry = self.entry(device)?;
        let index = entry.index;
        self.send(entry.line, |done| Job::Run {
            device: index,
            command,
            register,
            done,
        })
        .await
    }

    /// Sets `register` of device `device` from `text` as `optobus set` does (units and SI
    /// prefixes, code names, range, steps), if the bus file lists it as writable, and reads it
    /// back: what writes from the network use. Nothing is sent when it is refused. Returns the
    /// value read back (`None` for a register that cannot be read).
    pub async fn set_listed(
        &self,
        device: &str,
        register: &str,
        text: &str,
    ) -> Result<Option<Value>, JobError> {
        let entry = self.entry(device)?;
        let info = entry.device;
        let found = resolve_one(info, register, None).map_err(JobError::Refused)?;
        if !entry.writable.allows_register(found) {
            return Err(JobError::NotListed {
                device: device.to_owned(),
                name: register.to_owned(),
            });
        }
        let words = parse_value(found, text)
            .map_err(|error| JobError::Refused(optobus_inspect::Error::from(error)))?;
        self.write(device, found, words, false).await?;
        if !found.readable() {
            return Ok(None);
        }
        let mut back = self.read(device, vec![found]).await?;
        Ok(back.pop())
    }

    /// Runs `command` of device `device` as `optobus do` does, if the bus file lists it as
    /// writable (a drastic one only when named there), and waits out its busy time.
    pub async fn do_listed(&self, device: &str, command: &str) -> Result<(), JobError> {
        let entry = self.entry(device)?;
        let info = entry.device;
        let found = info.command(command).ok_or_else(|| {
            let names: Vec<&str> = info.commands.iter().map(|c| c.name).collect();
            JobError::Refused(
                optobus_inspect::Error::new(format!(
                    "`{command}` is no command of {}",
                    info.model_name()
                ))
                .hint(format!("commands: {}", names.join(", "))),
            )
        })?;
        if !entry.writable.allows_command(found) {
            return Err(JobError::NotListed {
                device: device.to_owned(),
                name: command.to_owned(),
            });
        }
        let register = resolve_one(info, found.register, None).map_err(JobError::Refused)?;
        self.run(device, found, register).await
    }

    /// What writes from the network may change on device `device`.
    pub fn writable(&self, device: &str) -> Option<&Writable> {
        self.entry(device).ok().map(|entry| &entry.writable)
    }

    /// Reads `registers` of device `device` now, ahead of the line's polls.
    pub async fn read(
        &self,
        device: &str,
        registers: Vec<&'static RegisterInfo>,
    ) -> Result<Vec<Value>, JobError> {
        let entry = self.entry(device)?;
        let index = entry.index;
        self.send(entry.line, |done| Job::Read {
            device: index,
            registers,
            done,
        })
        .await
    }
}

/// Decodes what a read job read, register by register.
pub(crate) fn values(
    registers: &[&'static RegisterInfo],
    readings: &optobus_driver::Readings,
) -> Vec<Value> {
    registers
        .iter()
        .map(|register| decode_value(register, readings.words(register)))
        .collect()
}
