//! Asking a running bus to write, run a command or read now: jobs that go onto their line
//! between its polls, in turns with the other sources (see the crate README).
//!
//! A write is checked against the register's spec before it is queued (nothing invalid reaches
//! the line), is made once (writes are never retried), and is followed by the device's busy
//! time for commands. A broadcast write reaches every device of a line and is followed by the
//! line's broadcast turnaround before the next request.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use optobus_device::{CommandInfo, DeviceInfo, RegisterInfo};
use optobus_driver::{BufferTiming, Encode, Fixed};
use optobus_inspect::Value;
use optobus_measure::Limits;
use tokio::sync::{mpsc, oneshot};

use crate::event::DeviceId;
use crate::file::Writable;
use crate::measuring::Measuring;
use crate::policy::{Policy, Refusal};
use crate::source::{Source, NETWORK_QUEUE};
use crate::trace::{Frame, LineFrames};

/// A line's job queues, one per [`Source`], and the jobs each source had refused as busy.
#[derive(Debug)]
pub(crate) struct LineQueues {
    pub(crate) senders: [mpsc::Sender<Job>; 3],
    pub(crate) busy: [AtomicU64; 3],
}

impl LineQueues {
    /// The queues, and the receivers the line takes from (in [`Source::ALL`] order).
    pub(crate) fn new() -> (Self, [mpsc::Receiver<Job>; 3]) {
        let [api, console, mqtt] = Source::ALL.map(|source| mpsc::channel(source.queue()));
        let queues = Self {
            senders: [api.0, console.0, mqtt.0],
            busy: Default::default(),
        };
        (queues, [api.1, console.1, mqtt.1])
    }
}

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
    /// Read the data buffer out (lock, pages, unlock) and when its values were taken.
    Buffer {
        device: usize,
        done: oneshot::Sender<Result<Buffered, optobus_driver::Error>>,
    },
}

/// A device's data buffer as [`Handle::download_buffer`] read it out.
#[derive(Clone, Debug, PartialEq)]
pub struct Buffered {
    /// The register the values are copies of (its unit and scale are theirs).
    pub register: &'static RegisterInfo,
    /// The values, oldest first; `None` where the device marks one invalid.
    pub values: Vec<Option<Fixed>>,
    /// When they were taken, where the buffer names its sampling interval.
    pub timing: Option<BufferTiming>,
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
    pub(crate) id: Arc<DeviceId>,
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
    /// The write policy (or, for an API write, the register's spec) refused it; nothing was
    /// sent.
    Refused(Refusal),
    /// The line already has as many jobs of this source queued as it keeps
    /// ([`NETWORK_QUEUE`]); refused at once, nothing was sent.
    Busy {
        /// The line.
        line: String,
        /// Who asked.
        source: Source,
    },
    /// The line's task has stopped.
    Stopped,
    /// The device or the line failed.
    Device(optobus_driver::Error),
}

impl From<Refusal> for JobError {
    fn from(refusal: Refusal) -> Self {
        Self::Refused(refusal)
    }
}

impl std::fmt::Display for JobError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::UnknownDevice(name) => write!(f, "the bus has no device `{name}`"),
            Self::Refused(refusal) => refusal.fmt(f),
            Self::Busy { line, source } => write!(
                f,
                "line `{line}` is busy: {NETWORK_QUEUE} requests of the {} already wait for it; \
                 nothing was sent, try again later",
                source.name()
            ),
            Self::Stopped => f.write_str("the bus has stopped"),
            Self::Device(error) => error.fmt(f),
        }
    }
}

impl std::error::Error for JobError {}

/// The `tracing` target of the audit trail: every write, command and buffer read-out a network
/// source asked for, who asked, and whether it was done or refused (why).
pub const AUDIT_TARGET: &str = "optobus_audit";

/// A cloneable handle on a running bus's lines.
#[derive(Clone, Debug)]
pub struct Handle {
    pub(crate) lines: Arc<[LineQueues]>,
    /// Whose jobs this handle queues.
    pub(crate) source: Source,
    /// Who in the source asked (a client's address), for the audit trail.
    pub(crate) origin: Option<Arc<str>>,
    pub(crate) devices: Arc<[Entry]>,
    /// Each line's frame rings.
    pub(crate) frames: Arc<[Arc<LineFrames>]>,
    /// The bus file's measurements, where it has any.
    pub(crate) measuring: Option<Arc<Measuring>>,
    /// Each measurement's limits, by name, where it has limits: what outputs draw its values
    /// against.
    pub(crate) limits: Arc<[(Arc<str>, Limits)]>,
}

impl Handle {
    /// The bus file's measurements, by name with their unit, in the order they are computed.
    pub fn measurements(&self) -> Vec<(&str, &str)> {
        self.measuring.iter().flat_map(|m| m.names()).collect()
    }

    /// The limits of measurement `name`, in its unit, as the bus file gives them; `None` for a
    /// measurement without limits, or none of that name.
    pub fn measurement_limits(&self, name: &str) -> Option<&Limits> {
        self.limits
            .iter()
            .find(|(measurement, _)| &**measurement == name)
            .map(|(_, limits)| limits)
    }

    /// The judgement counts of measurement `name` since the bus started or the counts were
    /// last reset, lowest first (ll, lo, go, hi, hh: OK is `go`, the rest NG); `None` for a
    /// measurement without limits, or none of that name.
    pub fn judgement_counts(&self, name: &str) -> Option<[u64; 5]> {
        self.measuring.as_ref()?.counts(name)
    }

    /// Every measurement's judgement counts back to zero and its statistics window emptied
    /// (the OK/NG counters' reset).
    pub fn reset_measurements(&self) {
        if let Some(measuring) = &self.measuring {
            measuring.reset();
        }
    }

    /// The same handle, its jobs queued as `source`'s: a network source's jobs beyond
    /// [`NETWORK_QUEUE`] on a line are refused at once with [`JobError::Busy`].
    pub fn for_source(&self, source: Source) -> Self {
        Self {
            source,
            ..self.clone()
        }
    }

    /// The same handle, its jobs told in the audit trail as asked by `origin` (a client's
    /// address, a topic).
    pub fn from_origin(&self, origin: impl std::fmt::Display) -> Self {
        Self {
            origin: Some(Arc::from(origin.to_string())),
            ..self.clone()
        }
    }

    /// Tells the audit trail ([`AUDIT_TARGET`]) what a network source asked for and how it
    /// went; the program's own jobs ([`Source::Api`]) are not told.
    fn audit<T>(
        &self,
        what: std::fmt::Arguments<'_>,
        outcome: &Result<T, JobError>,
        done: impl FnOnce(&T) -> String,
    ) {
        if self.source == Source::Api {
            return;
        }
        let who = match &self.origin {
            Some(origin) => format!("{} {origin}", self.source.name()),
            None => self.source.name().to_owned(),
        };
        match outcome {
            Ok(value) => tracing::info!(target: AUDIT_TARGET, "{who}: {what}: {}", done(value)),
            Err(error) => tracing::warn!(target: AUDIT_TARGET, "{who}: {what}: not done: {error}"),
        }
    }

    /// How many jobs of `source` the bus's lines refused as busy.
    pub fn busy_refusals(&self, source: Source) -> u64 {
        self.lines
            .iter()
            .map(|queues| queues.busy[source.index()].load(Ordering::Relaxed))
            .sum()
    }

    fn line_name(&self, line: usize) -> String {
        self.devices
            .iter()
            .find(|entry| entry.line == line)
            .map(|entry| entry.id.line.to_string())
            .unwrap_or_default()
    }

    fn entry(&self, device: &str) -> Result<&Entry, JobError> {
        self.devices
            .iter()
            .find(|entry| *entry.id.device == *device)
            .ok_or_else(|| JobError::UnknownDevice(device.to_owned()))
    }

    /// The bus's devices in file order, each with its model.
    pub fn devices(&self) -> impl Iterator<Item = (&Arc<DeviceId>, &'static DeviceInfo)> {
        self.devices.iter().map(|entry| (&entry.id, entry.device))
    }

    /// The recent frames of device `device` (at most [`FRAMES_KEPT`](crate::FRAMES_KEPT)),
    /// oldest first; frames are kept on RTU lines (serial, RTU over TCP, simulated).
    pub fn frames(&self, device: &str) -> Result<Vec<Frame>, JobError> {
        let entry = self.entry(device)?;
        Ok(self.frames[entry.line].of(entry.index))
    }

    /// The model of device `name`.
    pub fn device_info(&self, name: &str) -> Option<&'static DeviceInfo> {
        self.entry(name).ok().map(|entry| entry.device)
    }

    /// Queues the job `job` makes for device `device` (its index on its line, and where to
    /// send the outcome) on the device's line, and waits for the outcome.
    async fn send<T>(
        &self,
        device: &str,
        job: impl FnOnce(usize, oneshot::Sender<Result<T, optobus_driver::Error>>) -> Job,
    ) -> Result<T, JobError> {
        let entry = self.entry(device)?;
        let (line, index) = (entry.line, entry.index);
        let (done, result) = oneshot::channel();
        let queues = &self.lines[line];
        let queue = &queues.senders[self.source.index()];
        if self.source == Source::Api {
            queue
                .send(job(index, done))
                .await
                .map_err(|_| JobError::Stopped)?;
        } else {
            match queue.try_send(job(index, done)) {
                Ok(()) => {}
                Err(mpsc::error::TrySendError::Full(_)) => {
                    queues.busy[self.source.index()].fetch_add(1, Ordering::Relaxed);
                    return Err(JobError::Busy {
                        line: self.line_name(line),
                        source: self.source,
                    });
                }
                Err(mpsc::error::TrySendError::Closed(_)) => return Err(JobError::Stopped),
            }
        }
        result
            .await
            .map_err(|_| JobError::Stopped)?
            .map_err(JobError::Device)
    }

    /// Writes `words` (the register's whole value, as `optobus_inspect::parse_value` gives
    /// them) to `register` of device `device`, between the line's polls; with `broadcast`,
    /// to every device of its line (slave 0).
    pub async fn write(
        &self,
        device: &str,
        register: &'static RegisterInfo,
        words: Vec<u16>,
        broadcast: bool,
    ) -> Result<(), JobError> {
        // An unknown device is said before anything about the register.
        self.entry(device)?;
        if !register.access.writable() || words.len() != usize::from(register.words) {
            return Err(Refusal::NotWritable(register.name).into());
        }
        register
            .check(register.raw(&words))
            .map_err(|why| Refusal::Invalid {
                register: register.name,
                why,
            })?;
        self.send(device, |index, done| Job::Write {
            device: index,
            register,
            words,
            broadcast,
            done,
        })
        .await
    }

    /// Runs `command` of device `device` (on the copy `register` of its register), between
    /// the line's polls, and waits out its busy time.
    pub async fn run(
        &self,
        device: &str,
        command: &'static CommandInfo,
        register: &'static RegisterInfo,
    ) -> Result<(), JobError> {
        self.send(device, |index, done| Job::Run {
            device: index,
            command,
            register,
            done,
        })
        .await
    }

    /// The write policy for device `device` as the network sees it: what the bus file's
    /// `writable` lists for it.
    pub fn policy(&self, device: &str) -> Result<Policy<'_>, JobError> {
        let entry = self.entry(device)?;
        Ok(Policy::new(
            &entry.id.device,
            entry.device,
            Some(&entry.writable),
        ))
    }

    /// Sets `register` of device `device` from `text` as `optobus set` does (units and SI
    /// prefixes, code names, range, steps), if the write policy allows it, and reads it back:
    /// what writes from the network use. Nothing is sent when it is refused. Returns the value
    /// read back (`None` for a register that cannot be read).
    pub async fn set_listed(
        &self,
        device: &str,
        register: &str,
        text: &str,
    ) -> Result<Option<Value>, JobError> {
        let outcome = async {
            let (found, words) = self.policy(device)?.set(register, text)?;
            self.write(device, found, words, false).await?;
            if !found.readable() {
                return Ok(None);
            }
            let mut back = self.read(device, vec![found]).await?;
            Ok(back.pop())
        }
        .await;
        self.audit(
            format_args!("set `{register}` of `{device}` to {text:?}"),
            &outcome,
            |back| match back {
                Some(value) => format!("done, reads back {value}"),
                None => "done".to_owned(),
            },
        );
        outcome
    }

    /// Runs `command` of device `device` as `optobus do` does, if the write policy allows it
    /// (a drastic one only when named in `writable`), and waits out its busy time.
    pub async fn do_listed(&self, device: &str, command: &str) -> Result<(), JobError> {
        let outcome = async {
            let (found, register) = self.policy(device)?.run(command)?;
            self.run(device, found, register).await
        }
        .await;
        self.audit(
            format_args!("run `{command}` of `{device}`"),
            &outcome,
            |_| "done".to_owned(),
        );
        outcome
    }

    /// Reads `register` of device `device` now, between the line's polls, if the write policy
    /// allows it: what reads from the network use (a read that changes the device only where
    /// the policy allows it).
    pub async fn read_checked(
        &self,
        device: &str,
        register: &'static RegisterInfo,
    ) -> Result<Value, JobError> {
        self.policy(device)?.read(register)?;
        let mut values = self.read(device, vec![register]).await?;
        Ok(values.pop().unwrap_or(Value::Invalid))
    }

    /// Reads out the data buffer of device `device` (where its spec has one) between the
    /// line's polls: its sampling timing, then the buffer locked, read a page at a time and
    /// unlocked, as `optobus buffer` does. The lock and unlock are commands: the bus file's
    /// `writable` must list them (`all` does), since reading out empties the buffer.
    pub async fn download_buffer(&self, device: &str) -> Result<Buffered, JobError> {
        let outcome = async {
            self.policy(device)?.buffer()?;
            self.send(device, |index, done| Job::Buffer {
                device: index,
                done,
            })
            .await
        }
        .await;
        self.audit(
            format_args!("read out the data buffer of `{device}`"),
            &outcome,
            |buffered| format!("done, {} values", buffered.values.len()),
        );
        outcome
    }

    /// What writes from the network may change on device `device`.
    pub fn writable(&self, device: &str) -> Option<&Writable> {
        self.entry(device).ok().map(|entry| &entry.writable)
    }

    /// Reads `registers` of device `device` now, between the line's polls.
    pub async fn read(
        &self,
        device: &str,
        registers: Vec<&'static RegisterInfo>,
    ) -> Result<Vec<Value>, JobError> {
        self.send(device, |index, done| Job::Read {
            device: index,
            registers,
            done,
        })
        .await
    }
}

/// Reads the data buffer of `core`'s device out: its timing first, then the values.
pub(crate) async fn download<T: optobus_transport::Transport>(
    core: &mut optobus_driver::Core<T>,
) -> Result<Buffered, optobus_driver::Error> {
    let device = core.device();
    let buffer = device.buffer.ok_or(optobus_driver::Error::NotAllowed {
        register: "buffer",
        what: "read out (the device has no data buffer)",
    })?;
    let register =
        device
            .members(buffer.values)
            .next()
            .ok_or(optobus_driver::Error::NotAllowed {
                register: buffer.values,
                what: "read out (the spec lacks it)",
            })?;
    let timing = core.read_buffer_timing().await?;
    let values = core.download_buffer(|_| {}).await?;
    Ok(Buffered {
        register,
        values,
        timing,
    })
}
