//! The engine of every generated driver: reads, validated writes, groups, commands.

use std::fmt;
use std::sync::Arc;
use std::time::Duration;

use optobus_codec::{BROADCAST, MAX_SLAVE};
use optobus_device::{Addressing, CommandInfo, DeviceInfo, GroupInfo, RegisterInfo, Table};
use optobus_transport::{ReadRequest, Transport};

use crate::convert::{Decode, Encode};
use crate::error::Error;
use crate::memory::DeviceMemory;
use crate::plan::{plan_write, ReadSpan};

/// The target of the driver's events: register names, words and decoded values at DEBUG.
pub const TRACE_TARGET: &str = "optobus_driver";

/// A register's words and the value decoded from them, for whoever listens.
fn decoded(register: &RegisterInfo, words: &[u16], value: &impl fmt::Debug) {
    tracing::debug!(
        target: TRACE_TARGET,
        register = register.name,
        ?words,
        "{} = {value:?}",
        register.name
    );
}

/// A transport, a slave address and the device description: what a generated driver wraps.
#[derive(Debug)]
pub struct Core<T> {
    transport: T,
    slave: u8,
    device: &'static DeviceInfo,
    /// The requests of each declared group read so far (group name, copy), planned once.
    plans: Vec<GroupPlan>,
    /// What the device has shown about itself (reads it refused).
    memory: DeviceMemory,
}

/// The requests that read one of the device's declared groups (or one copy of it).
#[derive(Clone, Debug)]
struct GroupPlan {
    group: &'static str,
    copy: Option<u8>,
    /// Shared with the reads in progress.
    plan: Arc<Plan>,
}

/// Registers and the requests that read them.
#[derive(Debug)]
struct Plan {
    registers: Box<[&'static RegisterInfo]>,
    spans: Arc<[PlannedRead]>,
}

/// A request of a plan, and whether a failed attempt may be repeated (worked out once per
/// plan, not per read).
type PlannedRead = (ReadSpan, bool);

/// `spans` with their repeatability.
fn planned(device: &DeviceInfo, spans: Vec<ReadSpan>) -> Arc<[PlannedRead]> {
    spans
        .into_iter()
        .map(|span| (span, span.is_repeatable(device)))
        .collect()
}

/// The words a group read fetched, by request.
#[derive(Clone, Debug)]
pub struct Readings {
    /// The first request's words inline: most groups are one request, read without another
    /// allocation.
    first: Option<(ReadSpan, Vec<u16>)>,
    rest: Vec<(ReadSpan, Vec<u16>)>,
    addressing: Addressing,
}

impl Readings {
    /// The words of `register` (empty if the plan did not read it).
    pub fn words(&self, register: &RegisterInfo) -> &[u16] {
        self.first
            .iter()
            .chain(&self.rest)
            .find_map(|(span, words)| {
                let offset = span.offset_of(register, self.addressing)?;
                words.get(offset..offset + usize::from(register.words))
            })
            .unwrap_or(&[])
    }

    /// The value of `register`.
    pub fn get<V: Decode + fmt::Debug>(&self, register: &RegisterInfo) -> V {
        let words = self.words(register);
        let value = V::decode(register, words);
        decoded(register, words, &value);
        value
    }

    fn push(&mut self, span: ReadSpan, words: Vec<u16>) {
        if self.first.is_none() {
            self.first = Some((span, words));
        } else {
            self.rest.push((span, words));
        }
    }

    /// The requests that were made.
    pub fn requests(&self) -> impl Iterator<Item = &ReadSpan> {
        self.first.iter().chain(&self.rest).map(|(span, _)| span)
    }
}

/// A group read of which one request failed: what the requests before it read, which request
/// failed, and why.
#[derive(Debug)]
pub struct PartialRead {
    /// The words of the requests that were answered.
    pub readings: Readings,
    /// The request that failed (`None` when none was made: a register cannot be read).
    pub failed: Option<ReadSpan>,
    /// Why it failed.
    pub error: Error,
}

impl PartialRead {
    fn boxed(readings: Readings, failed: Option<ReadSpan>, error: Error) -> Box<Self> {
        Box::new(Self {
            readings,
            failed,
            error,
        })
    }

    /// Those of `registers` (the group asked for) that the failed request was to read; when
    /// no request was made, those that cannot be read.
    pub fn failed_registers<'r>(&self, registers: &[&'r RegisterInfo]) -> Vec<&'r RegisterInfo> {
        let failed = |register: &RegisterInfo| match &self.failed {
            Some(span) => span.offset_of(register, self.readings.addressing).is_some(),
            None => !register.readable(),
        };
        registers.iter().copied().filter(|r| failed(r)).collect()
    }

    /// Whether `register` was read.
    pub fn has(&self, register: &RegisterInfo) -> bool {
        self.readings
            .requests()
            .any(|span| span.offset_of(register, self.readings.addressing).is_some())
    }
}

/// Refuses the reserved slave addresses 248 to 255.
fn check_slave(slave: u8) -> Result<u8, Error> {
    if slave > MAX_SLAVE {
        return Err(Error::Slave {
            slave,
            reason: "248 to 255 are reserved; slaves are 1 to 247, 0 broadcasts writes",
        });
    }
    Ok(slave)
}

impl<T: Transport> Core<T> {
    /// A driver core talking to slave `slave` of `device` through `transport`; 0 broadcasts
    /// (writes and commands only), 248 to 255 are refused.
    pub fn new(transport: T, slave: u8, device: &'static DeviceInfo) -> Result<Self, Error> {
        Ok(Self {
            transport,
            slave: check_slave(slave)?,
            device,
            plans: Vec::new(),
            memory: DeviceMemory::default(),
        })
    }

    /// A driver core talking to `device` at its factory slave address.
    pub fn with_default_slave(transport: T, device: &'static DeviceInfo) -> Self {
        Self {
            transport,
            slave: device.default_slave,
            device,
            plans: Vec::new(),
            memory: DeviceMemory::default(),
        }
    }

    /// The slave address requests go to.
    pub fn slave(&self) -> u8 {
        self.slave
    }

    /// Sends later requests to another slave address (refused like in [`Core::new`]). What
    /// was learned about the device at the old address ([`Core::memory`]) is forgotten.
    pub fn set_slave(&mut self, slave: u8) -> Result<(), Error> {
        let slave = check_slave(slave)?;
        if slave != self.slave {
            self.forget(DeviceMemory::default());
        }
        self.slave = slave;
        Ok(())
    }

    /// The device's first readable register, which a probe reads; a model with none is
    /// [`Error::NotAllowed`] with `register` and `what`.
    fn probe_register(
        &self,
        register: &'static str,
        what: &'static str,
    ) -> Result<&'static RegisterInfo, Error> {
        self.device
            .registers
            .iter()
            .find(|r| r.readable())
            .ok_or(Error::NotAllowed { register, what })
    }

    /// Whether anything answers at `slave` (a scan's probe, which then talks to it): a read
    /// of the device's first readable register, where an exception is an answer too
    /// (something lives at that address). A device with no readable register is
    /// [`Error::NotAllowed`].
    pub async fn answers_at(&mut self, slave: u8) -> Result<bool, Error> {
        let probe =
            self.probe_register("any register", "read (the model has no readable register)")?;
        self.set_slave(slave)?;
        Ok(match self.read_words(probe).await {
            Ok(_) => true,
            Err(error) => error.exception().is_some(),
        })
    }

    /// What the driver has learned about its device from the device's answers (for example
    /// that it refuses reads crossing reserved ranges), used by every read plan.
    pub fn memory(&self) -> &DeviceMemory {
        &self.memory
    }

    /// Takes `memory` as what is known about the device, and plans groups anew with it.
    fn forget(&mut self, memory: DeviceMemory) {
        self.memory = memory;
        self.plans.clear();
    }

    /// The slave address for a request that expects a reply.
    fn replying_slave(&self) -> Result<u8, Error> {
        match check_slave(self.slave)? {
            BROADCAST => Err(Error::Slave {
                slave: BROADCAST,
                reason: "a broadcast gets no reply, so nothing can be read from it",
            }),
            slave => Ok(slave),
        }
    }

    /// Makes one read at the driver's slave: once if reading any of its registers changes
    /// the device, else with the transport's retries.
    async fn read_span(
        &mut self,
        table: Table,
        address: u16,
        count: u16,
        repeatable: bool,
    ) -> Result<Vec<u16>, Error> {
        let slave = self.replying_slave()?;
        let read = ReadRequest {
            function: table.read_function(),
            address,
            count,
            repeatable,
        };
        Ok(self.transport.read_words(slave, read).await?)
    }

    /// The device description.
    pub fn device(&self) -> &'static DeviceInfo {
        self.device
    }

    /// The transport.
    pub fn transport_mut(&mut self) -> &mut T {
        &mut self.transport
    }

    /// Gives the transport back.
    pub fn into_transport(self) -> T {
        self.transport
    }

    /// Reads the words of one register.
    pub async fn read_words(&mut self, register: &'static RegisterInfo) -> Result<Vec<u16>, Error> {
        if !register.readable() {
            return Err(Error::unreadable(register));
        }
        self.read_span(
            register.table,
            register.address,
            register.words,
            register.read_is_repeatable(),
        )
        .await
    }

    /// Reads one register as `V`.
    pub async fn read<V: Decode + fmt::Debug>(
        &mut self,
        register: &'static RegisterInfo,
    ) -> Result<V, Error> {
        let words = self.read_words(register).await?;
        let value = V::decode(register, &words);
        decoded(register, &words, &value);
        Ok(value)
    }

    /// Reads several registers in the fewest requests (see [`crate::plan_reads`]). A device
    /// that refuses a read crossing a reserved range (exception 02) is read without crossing
    /// one, at once and from then on ([`DeviceMemory`]).
    pub async fn read_group(
        &mut self,
        registers: &[&'static RegisterInfo],
    ) -> Result<Readings, Error> {
        if let Some(unreadable) = registers.iter().find(|r| !r.readable()) {
            return Err(Error::unreadable(unreadable));
        }
        let plan = planned(self.device, self.memory.plan_reads(self.device, registers));
        self.read_plan(registers, &plan).await
    }

    /// Reads a group the device declares (every copy of a repeat member it names), in the
    /// fewest requests: planned on the first call, the requests are kept for the next.
    pub async fn read_declared_group(
        &mut self,
        group: &'static GroupInfo,
    ) -> Result<Readings, Error> {
        self.read_declared(group, None).await
    }

    /// Like [`Core::read_declared_group`], for a group of repeat members read one copy at a
    /// time: copy `copy` (1-based) of each (CCF's measurements of one channel).
    pub async fn read_declared_group_copy(
        &mut self,
        group: &'static GroupInfo,
        copy: u8,
    ) -> Result<Readings, Error> {
        self.read_declared(group, Some(copy)).await
    }

    async fn read_declared(
        &mut self,
        group: &'static GroupInfo,
        copy: Option<u8>,
    ) -> Result<Readings, Error> {
        let known = self
            .plans
            .iter()
            .position(|plan| plan.group == group.name && plan.copy == copy);
        let index = match known {
            Some(index) => index,
            None => {
                let device = self.device;
                let registers: Vec<&'static RegisterInfo> = group
                    .registers
                    .iter()
                    .flat_map(|name| device.members(name))
                    .filter(|r| copy.is_none() || r.copy.map(|c| c.number) == copy)
                    .collect();
                if let Some(unreadable) = registers.iter().find(|r| !r.readable()) {
                    return Err(Error::unreadable(unreadable));
                }
                let spans = planned(device, self.memory.plan_reads(device, &registers));
                self.plans.push(GroupPlan {
                    group: group.name,
                    copy,
                    plan: Arc::new(Plan {
                        registers: registers.into(),
                        spans,
                    }),
                });
                self.plans.len() - 1
            }
        };
        let plan = Arc::clone(&self.plans[index].plan);
        self.read_plan(&plan.registers, &plan.spans).await
    }

    /// Makes the requests of `plan` (planned for `registers`). A request the device refuses
    /// for crossing a reserved range is replaced by requests that do not, and the group plans
    /// are made anew for the next reads.
    async fn read_plan(
        &mut self,
        registers: &[&'static RegisterInfo],
        plan: &[PlannedRead],
    ) -> Result<Readings, Error> {
        self.read_plan_partly(registers, plan)
            .await
            .map_err(|partial| partial.error)
    }

    /// Makes the requests of `plan` in order until one fails; what was read stays.
    async fn read_plan_partly(
        &mut self,
        registers: &[&'static RegisterInfo],
        plan: &[PlannedRead],
    ) -> Result<Readings, Box<PartialRead>> {
        let mut readings = Readings {
            first: None,
            rest: Vec::new(),
            addressing: self.device.addressing,
        };
        for &(span, repeatable) in plan {
            match self
                .read_span(span.table, span.address, span.count, repeatable)
                .await
            {
                Ok(words) => readings.push(span, words),
                Err(error) => {
                    let mut memory = self.memory;
                    let Some(instead) = memory.fallback(self.device, registers, &span, &error)
                    else {
                        return Err(PartialRead::boxed(readings, Some(span), error));
                    };
                    tracing::debug!(
                        target: TRACE_TARGET,
                        table = span.table.as_str(),
                        address = span.address,
                        count = span.count,
                        "the device refused a read crossing a reserved range; reading around it"
                    );
                    self.forget(memory);
                    for &(span, repeatable) in planned(self.device, instead).iter() {
                        match self
                            .read_span(span.table, span.address, span.count, repeatable)
                            .await
                        {
                            Ok(words) => readings.push(span, words),
                            Err(error) => {
                                return Err(PartialRead::boxed(readings, Some(span), error))
                            }
                        }
                    }
                }
            }
        }
        Ok(readings)
    }

    /// Like [`Core::read_group`], but when a request fails the words of the requests made
    /// before it are kept: [`PartialRead`] holds them, the failed request and the error, so a
    /// caller can use what was read and name the registers that were not.
    pub async fn read_group_partly(
        &mut self,
        registers: &[&'static RegisterInfo],
    ) -> Result<Readings, Box<PartialRead>> {
        if let Some(unreadable) = registers.iter().find(|r| !r.readable()) {
            let readings = Readings {
                first: None,
                rest: Vec::new(),
                addressing: self.device.addressing,
            };
            return Err(PartialRead::boxed(
                readings,
                None,
                Error::unreadable(unreadable),
            ));
        }
        let plan = planned(self.device, self.memory.plan_reads(self.device, registers));
        self.read_plan_partly(registers, &plan).await
    }

    /// Validates `value` and writes it: nothing is sent if it is invalid.
    pub async fn write<V: Encode + ?Sized>(
        &mut self,
        register: &'static RegisterInfo,
        value: &V,
    ) -> Result<(), Error> {
        if !register.access.writable() {
            return Err(Error::NotAllowed {
                register: register.name,
                what: "written (it is read-only)",
            });
        }
        let words = value.encode(register)?;
        self.write_words(register, &words).await
    }

    /// Writes already validated words, as [`plan_write`] plans them.
    pub(crate) async fn write_words(
        &mut self,
        register: &'static RegisterInfo,
        words: &[u16],
    ) -> Result<(), Error> {
        tracing::debug!(
            target: TRACE_TARGET,
            register = register.name,
            ?words,
            slave = self.slave,
            "write {}",
            register.name
        );
        for step in plan_write(self.device, register, words) {
            self.transport
                .write(self.slave, step.address, step.value)
                .await?;
        }
        Ok(())
    }

    /// Runs `command` (writes its value to `register`, the command's register or the chosen
    /// copy of it) and waits out the time the device is busy afterwards; for a command whose
    /// spec says how the device shows it finished (`done_when`), polls `register` until it
    /// does, or fails with [`Error::CommandNotFinished`] once the spec's bound has passed.
    pub async fn run(
        &mut self,
        command: &'static CommandInfo,
        register: &'static RegisterInfo,
    ) -> Result<(), Error> {
        let words = crate::convert::encode_integer(register, i64::from(command.value))?;
        tracing::debug!(target: TRACE_TARGET, command = command.name, "run {}", command.name);
        let written = tokio::time::Instant::now();
        self.write_words(register, &words).await?;
        if command.busy_ms > 0 {
            tokio::time::sleep(Duration::from_millis(u64::from(command.busy_ms))).await;
        }
        let mut wait = CommandWait::new(command, register, written);
        loop {
            match wait.poll(self).await {
                Finish::Done => return Ok(()),
                Finish::Again(at) => tokio::time::sleep_until(at).await,
                Finish::Failed(error) => return Err(error),
            }
        }
    }

    /// Polls until the device answers, for at most `limit`; gives the time it took.
    pub async fn wait_ready(&mut self, limit: Duration) -> Result<Duration, Error> {
        const POLL_INTERVAL: Duration = Duration::from_millis(100);
        let started = tokio::time::Instant::now();
        let probe = self.probe_register("", "polled (the device has no readable register)")?;
        loop {
            match self.read_words(probe).await {
                Ok(_) => return Ok(started.elapsed()),
                Err(Error::Transport(error)) if started.elapsed() + POLL_INTERVAL >= limit => {
                    return Err(Error::NotReady {
                        waited: started.elapsed(),
                        last: Box::new(error),
                    })
                }
                Err(Error::Transport(_)) => tokio::time::sleep(POLL_INTERVAL).await,
                Err(other) => return Err(other),
            }
        }
    }
}

/// How often a command's register is read while the device finishes it.
pub const COMPLETION_POLL: Duration = Duration::from_millis(50);

/// Waiting for a command to finish, where its spec says how the device shows it
/// ([`CommandInfo::done_when`]): one read of its register per [`CommandWait::poll`]. The bus
/// polls the same way between other devices' requests.
#[derive(Debug)]
pub struct CommandWait {
    command: &'static CommandInfo,
    register: &'static RegisterInfo,
    written: tokio::time::Instant,
    last_read: Option<u32>,
    last_error: Option<Box<optobus_transport::Error>>,
}

/// What a [`CommandWait::poll`] found.
#[derive(Debug)]
pub enum Finish {
    /// The device has finished (or the command shows no completion).
    Done,
    /// Not yet: poll again at this instant.
    Again(tokio::time::Instant),
    /// It did not finish within its bound, or the read failed otherwise than on the wire.
    Failed(Error),
}

impl CommandWait {
    /// The wait for `command`, written to `register` at `written`.
    pub fn new(
        command: &'static CommandInfo,
        register: &'static RegisterInfo,
        written: tokio::time::Instant,
    ) -> Self {
        Self {
            command,
            register,
            written,
            last_read: None,
            last_error: None,
        }
    }

    /// Reads the register once through `core` (nothing for a command without `done_when`):
    /// finished only when it reads the value that says so. A failed read (the device may not
    /// answer while it writes its flash) counts as not yet, until the bound has passed.
    pub async fn poll<T: Transport>(&mut self, core: &mut Core<T>) -> Finish {
        let Some(done) = self.command.done_when else {
            return Finish::Done;
        };
        match core.read_words(self.register).await {
            Ok(words) if self.register.raw(&words) == done.value => return Finish::Done,
            Ok(words) => {
                self.last_read = Some(self.register.raw(&words));
                self.last_error = None;
            }
            Err(Error::Transport(error)) => self.last_error = Some(Box::new(error)),
            Err(other) => return Finish::Failed(other),
        }
        let bound = crate::transport::timing::deadline_from(
            self.written,
            Duration::from_millis(u64::from(done.within_ms)),
        );
        let next = tokio::time::Instant::now() + COMPLETION_POLL;
        if next <= bound {
            return Finish::Again(next);
        }
        Finish::Failed(Error::CommandNotFinished {
            command: self.command.name,
            register: self.register.name,
            expected: done.value,
            last_read: self.last_read,
            waited: self.written.elapsed(),
            last_error: self.last_error.take(),
        })
    }
}
