//! One task per line: opens its port (and reopens it after a failure), runs the schedule's
//! polls through each device's driver core, and tells what happened as events.

use std::sync::Arc;
use std::time::{Duration, SystemTime};

use optobus_codec::passthrough::{Access, PassPdu};
use optobus_codec::LineFormat;
use optobus_codec::{FrameShape, BROADCAST, EXCEPTION_BIT};
use optobus_device::{RegisterInfo, Table};
use optobus_driver::{CommandWait, Core, Error as DriverError, Finish};
use optobus_inspect::decode_value;
use optobus_transport::{Client, Error, RtuConfig, Stream};
use tokio::sync::{broadcast, mpsc, Mutex};
use tokio::time::Instant;

use crate::event::{DeviceId, ErrorCounts, Event, HealthEvent, LineStats, Sample, Writer, Written};
use crate::file::Writable;
use crate::gateway::{self, GatewayRequest};
use crate::handle::{self, Checked, Job};
use crate::link::{count, DeviceLink, DeviceSettings, LineState};
use crate::policy::{self, Policy, Refusal};
use crate::schedule::{Health, Next, Outcome, Schedule, FIRST_BACKOFF, MAX_BACKOFF};
use crate::source::Source;
use crate::trace::{LineFrames, TracedStream};
use crate::turns::Turns;

/// The gateway's exception for a request the line could not carry out.
fn path_or_target(error: &Error) -> u8 {
    match error {
        Error::Timeout { .. } | Error::Frame(_) | Error::WordCount { .. } => gateway::TARGET_FAILED,
        _ => gateway::PATH_UNAVAILABLE,
    }
}

/// The first address a register request names.
fn pdu_address(pass: &PassPdu<'_>) -> u16 {
    match pass.bytes() {
        [_, high, low, ..] => u16::from_be_bytes([*high, *low]),
        _ => 0,
    }
}

/// Logs a device's change of health (going offline with the reason).
fn log_health(id: &DeviceId, health: Health, reason: Option<&str>) {
    let device = &*id.device;
    let slave = id.slave;
    let why = reason
        .map(|reason| format!(": {reason}"))
        .unwrap_or_default();
    match health {
        Health::Offline => tracing::warn!(
            target: "optobus_bus",
            "device `{device}` (slave {slave}) is offline{why}"
        ),
        Health::Online => tracing::info!(
            target: "optobus_bus",
            "device `{device}` (slave {slave}) is online"
        ),
    }
}

/// How often a line sends its statistics.
const STATS_EVERY: Duration = Duration::from_secs(1);

/// How a line's port is opened.
pub(crate) enum Opener {
    /// A stream handed over once (a test's in-memory line); afterwards the line stays closed.
    Stream(Option<Box<dyn Stream>>),
    /// Simulated devices behind an emulated line, a new connection each time.
    Simulated(optobus_simulator::Slaves, Option<LineFormat>),
    /// A serial port, RTU over TCP or Modbus TCP, opened by the transport (none without the
    /// `serial` and `tcp` features).
    #[cfg(any(feature = "serial", feature = "tcp"))]
    Port(optobus_transport::Port),
}

impl Opener {
    async fn open(
        &mut self,
        format: Option<LineFormat>,
        frames: &Arc<LineFrames>,
    ) -> Result<Client, Error> {
        // The line's frames are kept for its devices' traces.
        let traced = |stream: Box<dyn Stream>| -> Box<dyn Stream> {
            Box::new(TracedStream {
                inner: stream,
                frames: Arc::clone(frames),
            })
        };
        let config = RtuConfig {
            line: format,
            ..RtuConfig::default()
        };
        match self {
            Self::Stream(stream) => stream
                .take()
                .map(|stream| Client::rtu(traced(stream), config))
                .ok_or(Error::Closed),
            Self::Simulated(bus, line) => {
                let (stream, _server) = match line {
                    Some(format) => bus.duplex_line(optobus_simulator::Line::new(*format)),
                    None => bus.duplex(),
                };
                Ok(Client::rtu(traced(Box::new(stream)), config))
            }
            #[cfg(any(feature = "serial", feature = "tcp"))]
            Self::Port(port) => {
                let config = optobus_transport::ClientConfig {
                    rtu: config,
                    ..optobus_transport::ClientConfig::default()
                };
                port.open(config, traced).await
            }
        }
    }
}

/// A device as its line runs it.
pub(crate) struct DeviceRun {
    pub(crate) id: Arc<DeviceId>,
    pub(crate) core: Core<DeviceLink>,
    pub(crate) errors: Arc<std::sync::Mutex<ErrorCounts>>,
    /// How its requests are made (the gateway's requests to it too).
    pub(crate) settings: DeviceSettings,
    /// What the network may write to it (the gateway's writes, where its line allows them).
    pub(crate) writable: Writable,
}

impl DeviceRun {
    /// The write policy for the gateway's requests to this device.
    fn gateway_policy(&self, writes: bool) -> Policy<'_> {
        Policy::new(
            &self.id.device,
            self.core.device(),
            writes.then_some(&self.writable),
        )
    }
}

/// The gateway's side of a line.
pub(crate) struct GatewayQueue {
    pub(crate) requests: mpsc::Receiver<GatewayRequest>,
    /// Whether writes pass.
    pub(crate) writes: bool,
    /// What it counts: the line counts the requests the write policy refuses.
    pub(crate) counters: Arc<gateway::GatewayCounters>,
}

/// The registers of one poll.
pub(crate) struct PollRun {
    pub(crate) registers: Vec<&'static RegisterInfo>,
}

/// Maps the bus's monotonic clock to wall-clock times for samples (one for every line).
#[derive(Clone, Copy)]
pub(crate) struct Clock {
    pub(crate) instant: Instant,
    system: SystemTime,
}

impl Clock {
    pub(crate) fn now() -> Self {
        Self {
            instant: Instant::now(),
            system: SystemTime::now(),
        }
    }

    fn system(&self, at: Instant) -> SystemTime {
        self.system + at.saturating_duration_since(self.instant)
    }
}

/// Everything one line's task owns.
pub(crate) struct LineTask {
    pub(crate) name: Arc<str>,
    pub(crate) format: Option<LineFormat>,
    pub(crate) opener: Opener,
    pub(crate) state: Arc<Mutex<LineState>>,
    pub(crate) devices: Vec<DeviceRun>,
    pub(crate) polls: Vec<PollRun>,
    pub(crate) schedule: Schedule,
    pub(crate) events: broadcast::Sender<Event>,
    pub(crate) gateway: Option<GatewayQueue>,
    /// Writes, commands and reads asked for through a [`crate::Handle`], a queue per
    /// [`Source`].
    pub(crate) jobs: [mpsc::Receiver<Job>; 3],
    /// Whose turn it is among the queues of network work.
    pub(crate) turns: Turns,
    /// The silence owed after a broadcast.
    pub(crate) broadcast_turnaround: Duration,
    /// Commands waiting for their device to show it finished (`done_when`).
    pub(crate) finishing: Vec<Finishing>,
    /// The bus's clock, shared by its lines.
    pub(crate) clock: Clock,
}

/// A command whose register the line reads, between other requests, until it shows the
/// device finished; the device is held from polls meanwhile.
pub(crate) struct Finishing {
    device: usize,
    /// When to read its register next.
    at: Instant,
    wait: CommandWait,
    done: tokio::sync::oneshot::Sender<Result<(), DriverError>>,
}

/// Work asked of the line from outside its schedule.
enum Work {
    Gateway(GatewayRequest),
    /// A job, and the source whose queue it came from.
    Job(Job, Source),
}

/// The next request of the gateway, or never when the line has none.
async fn next_request(gateway: &mut Option<GatewayQueue>) -> Option<GatewayRequest> {
    match gateway {
        Some(gateway) => gateway.requests.recv().await,
        None => std::future::pending().await,
    }
}

impl LineTask {
    /// Runs the line until the task is aborted.
    ///
    /// Polls that are due go first. Between them the line serves the network's work in turns
    /// (see [`Turns`]): after each poll every queue gets one turn (the gateway one per request
    /// that waited through the poll, at most the gateway's `queue`; each [`Source`] one job), then the
    /// next due poll runs; and on a line with polls that work takes at most [`NETWORK_SHARE`](crate::NETWORK_SHARE)
    /// of the line's time. The polls keep their schedule however much work is queued, and
    /// however long it takes.
    pub(crate) async fn run(mut self) {
        let clock = self.clock;
        let mut next_stats = clock.instant + STATS_EVERY;
        let mut reopen_at = clock.instant;
        let mut reopen_wait = FIRST_BACKOFF;
        // Unknown until the first try; then what the log last said.
        let mut was_open = None;
        let mut open_error = None;
        loop {
            let now = Instant::now();
            if now >= next_stats {
                self.send_stats(&clock).await;
                next_stats = now + STATS_EVERY;
            }
            let mut open = self.is_open().await;
            if !open && now >= reopen_at {
                match self.ensure_open().await {
                    Ok(()) => {
                        open = true;
                        reopen_wait = FIRST_BACKOFF;
                    }
                    Err(error) => {
                        open_error = Some(error);
                        reopen_at = now + reopen_wait;
                        reopen_wait = (reopen_wait * 2).min(MAX_BACKOFF);
                    }
                }
            }
            if Some(open) != was_open {
                // Whoever watches the line hears at once that it closed or opened again, and
                // a closed line's devices are down until they answer again.
                self.send_stats(&clock).await;
                if !open {
                    self.line_down(now).await;
                }
                self.log_open(open, was_open, open_error.take());
                was_open = Some(open);
            }
            let next = if open {
                self.schedule.next(now)
            } else {
                Next::Wait(reopen_at)
            };
            // A measurement's polls run back to back: nothing else takes the line between
            // them, and the network's turns come once the whole group has run.
            if let (true, Next::Run(poll)) = (self.schedule.mid_group(), next) {
                self.run_poll(poll, &clock).await;
                self.settle().await;
                self.after_poll();
                continue;
            }
            if let Some(index) = self.finishing.iter().position(|f| f.at <= now) {
                self.check_finished(index).await;
                continue;
            }
            // A line without polls gives its time to whoever asks.
            let budgeted = next != Next::Idle;
            if let Some(work) = self.take_work(matches!(next, Next::Run(_)), budgeted) {
                self.do_work(work).await;
                continue;
            }
            let until = match next {
                Next::Run(poll) => {
                    self.run_poll(poll, &clock).await;
                    self.settle().await;
                    self.after_poll();
                    continue;
                }
                Next::Wait(until) => until.min(next_stats),
                Next::Idle => next_stats,
            };
            let owed = self.turns.back_in_credit().filter(|_| budgeted);
            let until = self
                .finishing
                .iter()
                .map(|f| f.at)
                .chain(owed)
                .fold(until, Instant::min);
            // Beyond its share, work waits in its queues until the polls have paid it back.
            let take = owed.is_none();
            let [api, console, mqtt] = &mut self.jobs;
            let work = tokio::select! {
                () = tokio::time::sleep_until(until) => None,
                Some(job) = api.recv(), if take => Some(Work::Job(job, Source::Api)),
                Some(job) = console.recv(), if take => Some(Work::Job(job, Source::Console)),
                Some(job) = mqtt.recv(), if take => Some(Work::Job(job, Source::Mqtt)),
                Some(request) = next_request(&mut self.gateway), if take => Some(Work::Gateway(request)),
            };
            if let Some(work) = work {
                self.do_work(work).await;
            }
        }
    }

    /// A poll ran: unless its group still has polls to run, the network's queues get their
    /// turns.
    fn after_poll(&mut self) {
        if !self.schedule.mid_group() {
            let waiting = self.gateway.as_ref().map_or(0, |g| g.requests.len());
            self.turns.after_poll(waiting);
        }
    }

    /// The next work to do before the next poll, if the work is within its share of the line
    /// (`budgeted`: while the line has polls): any that waits when no poll is due, else only
    /// from queues that still have a turn in this round.
    fn take_work(&mut self, poll_due: bool, budgeted: bool) -> Option<Work> {
        if budgeted && !self.turns.in_credit(Instant::now()) {
            return None;
        }
        let queues: Vec<usize> = self.turns.queues(poll_due).collect();
        for queue in queues {
            let work = match queue.checked_sub(1) {
                None => self
                    .gateway
                    .as_mut()
                    .and_then(|g| g.requests.try_recv().ok())
                    .map(Work::Gateway),
                Some(source) => self.jobs[source]
                    .try_recv()
                    .ok()
                    .map(|job| Work::Job(job, Source::ALL[source])),
            };
            if let Some(work) = work {
                self.turns.served(queue);
                return Some(work);
            }
        }
        None
    }

    async fn do_work(&mut self, work: Work) {
        let started = Instant::now();
        match work {
            Work::Gateway(request) => self.serve(request).await,
            Work::Job(job, source) => self.do_job(job, source).await,
        }
        self.settle().await;
        self.turns.spent(started.elapsed());
    }

    /// Recovers the line now after a fault of the last request, so that the quiet it needs is
    /// counted to that request (a poll's or the network's), not to the next one.
    async fn settle(&mut self) {
        let mut state = self.state.lock().await;
        if let Some(Client::Rtu(rtu)) = state.client.as_mut() {
            if let Err(error) = rtu.settle().await {
                count(&mut state.errors, &error);
                state.broken |= matches!(error, Error::Closed | Error::Io(_));
            }
        }
    }

    /// The port closed: every device of the line that was online is down, told at once.
    async fn line_down(&mut self, now: Instant) {
        let reason = "the line's port is closed".to_owned();
        for device in self.schedule.line_down(now) {
            let device = &self.devices[device];
            let errors = *device.errors.lock().unwrap_or_else(|e| e.into_inner());
            log_health(&device.id, Health::Offline, Some(&reason));
            let event = HealthEvent {
                source: Arc::clone(&device.id),
                health: Health::Offline,
                errors,
                reason: Some(reason.clone()),
            };
            let _ = self.events.send(Event::Health(Arc::new(event)));
        }
    }

    /// Tells the bus's consumers that device `device` (every device of the line, for a
    /// broadcast) took a write of `registers`.
    fn written(
        &self,
        device: usize,
        broadcast: bool,
        registers: impl Fn(&DeviceRun) -> Vec<&'static RegisterInfo>,
        by: Writer,
    ) {
        let devices = if broadcast {
            &self.devices[..]
        } else {
            std::slice::from_ref(&self.devices[device])
        };
        for device in devices {
            let registers = registers(device);
            if registers.is_empty() {
                continue;
            }
            let written = Written {
                source: Arc::clone(&device.id),
                registers,
                by,
            };
            // No receiver is no error, as for samples.
            let _ = self.events.send(Event::Written(Arc::new(written)));
        }
    }

    /// Carries out an API job, of `source`; its caller gets the outcome (if it still waits).
    async fn do_job(&mut self, job: Job, source: Source) {
        let by = Writer::Job(source);
        match job {
            Job::Write {
                device,
                register,
                words,
                broadcast,
                done,
            } => {
                let core = &mut self.devices[device].core;
                let result = if broadcast {
                    let slave = core.slave();
                    // Slave 0 is always accepted; the device's own address was checked.
                    let _ = core.set_slave(BROADCAST);
                    let result = core.write(register, &Checked(words)).await;
                    let _ = core.set_slave(slave);
                    let mut state = self.state.lock().await;
                    state.owed = state.owed.max(self.broadcast_turnaround);
                    result
                } else {
                    core.write(register, &Checked(words)).await
                };
                if result.is_ok() {
                    // A broadcast wrote the same words at the same address of every other
                    // device of the line, whatever register each of them has there.
                    let addressed = Arc::clone(&self.devices[device].id);
                    let registers = |run: &DeviceRun| {
                        let words = usize::from(register.words);
                        match register.table {
                            _ if Arc::ptr_eq(&run.id, &addressed) => vec![register],
                            Table::Holding => {
                                policy::written(run.core.device(), register.address, words)
                            }
                            _ => Vec::new(),
                        }
                    };
                    self.written(device, broadcast, registers, by);
                }
                let _ = done.send(result);
            }
            Job::Run {
                device,
                command,
                register,
                done,
            } => {
                let core = &mut self.devices[device].core;
                let written = Instant::now();
                let result =
                    match optobus_driver::encode_integer(register, i64::from(command.value)) {
                        Ok(words) => core.write(register, &Checked(words)).await,
                        Err(error) => Err(error),
                    };
                if result.is_ok() {
                    self.written(device, false, |_| vec![register], by);
                }
                let busy = Duration::from_millis(u64::from(command.busy_ms));
                if result.is_ok() && command.done_when.is_some() {
                    // Its register is read between other requests once the busy time is
                    // over, until it shows the device finished.
                    let at = Instant::now() + busy;
                    self.schedule.hold(device, at);
                    self.finishing.push(Finishing {
                        device,
                        at,
                        wait: CommandWait::new(command, register, written),
                        done,
                    });
                    return;
                }
                if result.is_err() || command.busy_ms == 0 {
                    let _ = done.send(result);
                    return;
                }
                // The device is busy: the line serves the others meanwhile, and the caller
                // hears back when the busy time is over.
                self.schedule.hold(device, Instant::now() + busy);
                tokio::spawn(async move {
                    tokio::time::sleep(busy).await;
                    let _ = done.send(Ok(()));
                });
            }
            Job::Read {
                device,
                registers,
                done,
            } => {
                let result = self.devices[device].core.read_group(&registers).await;
                let _ = done.send(
                    result.map(|readings| optobus_inspect::decode_readings(&registers, &readings)),
                );
            }
            Job::Buffer { device, done } => {
                let _ = done.send(handle::download(&mut self.devices[device].core).await);
            }
        }
    }

    /// Reads the register of the `index`th command waiting to finish, once.
    async fn check_finished(&mut self, index: usize) {
        let Some(finishing) = self.finishing.get_mut(index) else {
            return;
        };
        let device = finishing.device;
        let step = finishing.wait.poll(&mut self.devices[device].core).await;
        match step {
            Finish::Again(at) => {
                finishing.at = at;
                self.schedule.hold(device, at);
            }
            Finish::Done => {
                let finishing = self.finishing.swap_remove(index);
                let _ = finishing.done.send(Ok(()));
            }
            Finish::Failed(error) => {
                let finishing = self.finishing.swap_remove(index);
                let _ = finishing.done.send(Err(error));
            }
        }
    }

    async fn is_open(&mut self) -> bool {
        let state = self.state.lock().await;
        state.client.is_some() && !state.broken
    }

    /// Passes a gateway request to the line and sends its reply back; a write is told in the
    /// audit trail.
    async fn serve(&mut self, request: GatewayRequest) {
        let (reply, refusal) = self.pass(request.unit, &request.pdu).await;
        let pass = PassPdu::new(&request.pdu);
        if let (Ok(Access::WriteRegisters { address, data }), None) =
            (pass.as_ref().map(PassPdu::access), &refusal)
        {
            let taken = match &reply {
                // A broadcast went out: nobody answers one.
                None => true,
                Some(reply) => reply.first().is_some_and(|f| f & EXCEPTION_BIT == 0),
            };
            if taken {
                let broadcast = request.unit == BROADCAST;
                let index = self.devices.iter().position(|d| d.id.slave == request.unit);
                if let Some(index) = index.or(broadcast.then_some(0)) {
                    let words = data.len() / 2;
                    let registers =
                        |device: &DeviceRun| policy::written(device.core.device(), address, words);
                    self.written(index, broadcast, registers, Writer::Gateway);
                }
            }
        }
        if pass.is_ok_and(|pass| pass.writes()) {
            let why = refusal.map(|refusal| refusal.to_string());
            gateway::audit_write(
                request.client,
                request.unit,
                &request.pdu,
                reply.as_deref(),
                why.as_deref(),
            );
        }
        // The client may have gone meanwhile: nothing to do then.
        let _ = request.reply.send(reply);
    }

    /// The reply PDU to a gateway request (an exception where it cannot be passed), or `None`
    /// for a broadcast; and the write policy's refusal, where it refused.
    async fn pass(&mut self, unit: u8, pdu: &[u8]) -> (Option<Vec<u8>>, Option<Refusal>) {
        let function = pdu[0];
        let refused = |code| (Some(gateway::exception(function, code)), None);
        let pass = match PassPdu::new(pdu) {
            Ok(pass) => pass,
            Err(optobus_codec::EncodeError::MalformedRequest { .. }) => {
                return refused(gateway::ILLEGAL_VALUE)
            }
            Err(_) => return refused(gateway::ILLEGAL_FUNCTION),
        };
        let index = self.devices.iter().position(|d| d.id.slave == unit);
        if let Err(refusal) = self.allowed(unit, index, &pass) {
            if let Some(gateway) = &self.gateway {
                gateway::add(&gateway.counters.policy_refused);
            }
            let code = gateway::refused(&refusal);
            return (Some(gateway::exception(function, code)), Some(refusal));
        }
        let (settings, shape) = match index {
            Some(index) => {
                let device = &self.devices[index];
                (device.settings, device.core.device().frame_shape)
            }
            None => (DeviceSettings::standard(), FrameShape::STANDARD),
        };
        // A write whose width does not fit the device's framing at that address.
        if pass.check_shape(&shape).is_err() {
            return refused(gateway::ILLEGAL_VALUE);
        }
        let mut state = self.state.lock().await;
        let started = Instant::now();
        let result = match state.client_for(index, &settings) {
            Ok(Client::Rtu(rtu)) => rtu.transact_pdu(unit, &pass, &shape).await,
            #[allow(unreachable_patterns)]
            Ok(_) => Err(Error::Unsupported("a gateway serves RTU lines")),
            Err(error) => return refused(path_or_target(&error)),
        };
        state.record(&settings, started, &result);
        match result {
            Ok(Some(reply)) => (Some(reply), None),
            Ok(None) => {
                state.owed = state.owed.max(self.broadcast_turnaround);
                (None, None)
            }
            Err(error) => refused(path_or_target(&error)),
        }
    }

    /// What the write policy says of a gateway request to `unit` (the device at `index` of
    /// the line, if it is one): a broadcast only where every device of the line allows it
    /// and frames it alike, nothing to a slave the bus file does not name.
    fn allowed(&self, unit: u8, index: Option<usize>, pass: &PassPdu<'_>) -> Result<(), Refusal> {
        let writes = self.gateway.as_ref().is_some_and(|g| g.writes);
        if unit == BROADCAST {
            if self.devices.is_empty() {
                return Err(Refusal::UnknownSlave(unit));
            }
            for device in &self.devices {
                let refuses = |refusal| Refusal::Broadcast {
                    device: device.id.device.to_string(),
                    refusal: Box::new(refusal),
                };
                device.gateway_policy(writes).pass(pass).map_err(refuses)?;
                // An FC06 of a width this device does not take at that address.
                if pass.check_shape(&device.core.device().frame_shape).is_err() {
                    let address = pdu_address(pass);
                    return Err(refuses(Refusal::NoRegisterAt {
                        device: device.id.device.to_string(),
                        address,
                    }));
                }
            }
            return Ok(());
        }
        match index {
            Some(index) => self.devices[index].gateway_policy(writes).pass(pass),
            None => Err(Refusal::UnknownSlave(unit)),
        }
    }

    /// Opens the port if it is closed or broke; why not, if it cannot be opened now.
    async fn ensure_open(&mut self) -> Result<(), Error> {
        let mut state = self.state.lock().await;
        if state.client.is_some() && !state.broken {
            return Ok(());
        }
        state.client = None;
        state.broken = false;
        let frames = Arc::clone(&state.frames);
        match self.opener.open(self.format, &frames).await {
            Ok(client) => {
                state.client = Some(client);
                Ok(())
            }
            Err(error) => {
                tracing::debug!(target: "optobus_bus", line = &*self.name, "cannot open the line: {error}");
                state.errors.line += 1;
                Err(error)
            }
        }
    }

    /// Logs that the line opened or closed (a change only, never each retry).
    fn log_open(&self, open: bool, was_open: Option<bool>, error: Option<Error>) {
        let line = &*self.name;
        let why = error.map(|error| format!(": {error}")).unwrap_or_default();
        match (open, was_open) {
            (true, None) => tracing::info!(target: "optobus_bus", "line `{line}` is open"),
            (true, Some(_)) => tracing::info!(target: "optobus_bus", "line `{line}` is open again"),
            (false, None) => tracing::warn!(
                target: "optobus_bus",
                "line `{line}` cannot be opened{why}; trying again with backoff (up to {}s)",
                MAX_BACKOFF.as_secs()
            ),
            (false, Some(_)) => tracing::warn!(
                target: "optobus_bus",
                "line `{line}` closed{why}; its devices are down; trying again with backoff"
            ),
        }
    }

    /// Runs one poll: a sample for every register read (those of the requests answered
    /// before a failed one too), and the device's health from how it went.
    async fn run_poll(&mut self, poll: usize, clock: &Clock) {
        let device_index = self.schedule.device_of(poll);
        let registers = &self.polls[poll].registers;
        let device = &mut self.devices[device_index];
        let requested = Instant::now();
        let result = device.core.read_group_partly(registers).await;
        let replied = Instant::now();
        let (readings, error) = match &result {
            Ok(readings) => (readings, None),
            Err(partial) => (&partial.readings, Some(&partial.error)),
        };
        let read = |register: &RegisterInfo| match &result {
            Ok(_) => true,
            Err(partial) => partial.has(register),
        };
        for &register in registers.iter().filter(|r| read(r)) {
            let sample = Sample {
                source: Arc::clone(&device.id),
                register,
                value: decode_value(register, readings.words(register)),
                requested: clock.system(requested),
                replied: clock.system(replied),
            };
            // No receiver is no error: the bus runs whether anyone listens or not.
            let _ = self.events.send(Event::Sample(Arc::new(sample)));
        }
        let outcome = match error {
            None | Some(DriverError::Transport(Error::Exception { .. })) => Outcome::Answered,
            Some(_) => Outcome::Failed,
        };
        self.schedule
            .measured(poll, requested, replied.duration_since(requested));
        if let Some(health) = self.schedule.done(poll, replied, outcome) {
            let errors = *device.errors.lock().unwrap_or_else(|e| e.into_inner());
            let reason = match (error, health) {
                (Some(error), Health::Offline) => Some(error.to_string()),
                _ => None,
            };
            let event = HealthEvent {
                source: Arc::clone(&device.id),
                health,
                errors,
                reason,
            };
            log_health(&device.id, health, event.reason.as_deref());
            let _ = self.events.send(Event::Health(Arc::new(event)));
        }
    }

    async fn send_stats(&mut self, clock: &Clock) {
        let state = self.state.lock().await;
        let stats = LineStats {
            line: Arc::clone(&self.name),
            transactions: state.transactions,
            errors: state.errors,
            busy: state.busy,
            elapsed: clock.instant.elapsed(),
            open: state.client.is_some() && !state.broken,
        };
        let _ = self.events.send(Event::Line(Arc::new(stats)));
    }
}
