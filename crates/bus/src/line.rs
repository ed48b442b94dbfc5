//! One task per line: opens its port (and reopens it after a failure), runs the schedule's
//! polls through each device's driver core, and tells what happened as events.

use std::sync::Arc;
use std::time::{Duration, SystemTime};

use optobus_codec::LineFormat;
use optobus_device::RegisterInfo;
use optobus_driver::{Core, Error as DriverError};
use optobus_inspect::decode_value;
use optobus_transport::{Error, RtuClient, RtuConfig};
use tokio::sync::{broadcast, Mutex};
use tokio::time::Instant;

use crate::event::{DeviceId, ErrorCounts, Event, HealthEvent, LineStats, Sample};
use crate::link::{Client, DeviceLink, LineState, Stream};
use crate::schedule::{Health, Next, Outcome, Schedule, FIRST_BACKOFF, MAX_BACKOFF};

/// How often a line sends its statistics.
const STATS_EVERY: Duration = Duration::from_secs(1);

/// How a line's port is opened.
pub(crate) enum Opener {
    /// A stream handed over once (a test's in-memory line); afterwards the line stays closed.
    Stream(Option<Box<dyn Stream>>),
    /// Simulated devices behind an emulated line, a new connection each time.
    Simulated(optobus_simulator::Bus, Option<LineFormat>),
    /// A serial port.
    #[cfg(feature = "serial")]
    Serial(optobus_transport::SerialSettings),
    /// RTU over a TCP socket (a serial-to-Ethernet converter).
    #[cfg(feature = "tcp")]
    RtuOverTcp(String),
    /// Modbus TCP.
    #[cfg(feature = "tcp")]
    Tcp(String),
}

impl Opener {
    async fn open(&mut self, format: Option<LineFormat>) -> Result<Client, Error> {
        let rtu = |stream: Box<dyn Stream>| {
            Client::Rtu(RtuClient::with_config(
                stream,
                RtuConfig {
                    line: format,
                    ..RtuConfig::default()
                },
            ))
        };
        match self {
            Self::Stream(stream) => stream.take().map(rtu).ok_or(Error::Closed),
            Self::Simulated(bus, line) => {
                let (stream, _server) = match line {
                    Some(format) => bus.duplex_line(optobus_simulator::Line::new(*format)),
                    None => bus.duplex(),
                };
                Ok(rtu(Box::new(stream)))
            }
            #[cfg(feature = "serial")]
            Self::Serial(settings) => Ok(rtu(Box::new(settings.open()?))),
            #[cfg(feature = "tcp")]
            Self::RtuOverTcp(address) => {
                let stream = tokio::net::TcpStream::connect(address.as_str())
                    .await
                    .map_err(|source| Error::Connect {
                        attempts: 1,
                        source,
                    })?;
                let _ = stream.set_nodelay(true);
                Ok(rtu(Box::new(stream)))
            }
            #[cfg(feature = "tcp")]
            Self::Tcp(address) => {
                let address = optobus_transport::resolve(address, 502)
                    .await
                    .map_err(|source| Error::Connect {
                        attempts: 1,
                        source,
                    })?;
                Ok(Client::Tcp(optobus_transport::TcpClient::new(
                    address,
                    optobus_transport::TcpConfig::default(),
                )))
            }
        }
    }
}

/// A device as its line runs it.
pub(crate) struct DeviceRun {
    pub(crate) id: Arc<DeviceId>,
    pub(crate) core: Core<DeviceLink>,
    pub(crate) errors: Arc<std::sync::Mutex<ErrorCounts>>,
}

/// The registers of one poll.
pub(crate) struct PollRun {
    pub(crate) registers: Vec<&'static RegisterInfo>,
}

/// Maps the line's monotonic clock to wall-clock times for samples.
#[derive(Clone, Copy)]
struct Clock {
    instant: Instant,
    system: SystemTime,
}

impl Clock {
    fn now() -> Self {
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
}

impl LineTask {
    /// Runs the line until the task is aborted.
    pub(crate) async fn run(mut self) {
        let clock = Clock::now();
        let mut next_stats = clock.instant + STATS_EVERY;
        let mut reopen_wait = FIRST_BACKOFF;
        loop {
            if !self.ensure_open().await {
                self.send_stats(&clock).await;
                tokio::time::sleep(reopen_wait).await;
                reopen_wait = (reopen_wait * 2).min(MAX_BACKOFF);
                continue;
            }
            reopen_wait = FIRST_BACKOFF;
            let now = Instant::now();
            if now >= next_stats {
                self.send_stats(&clock).await;
                next_stats = now + STATS_EVERY;
            }
            match self.schedule.next(now) {
                Next::Run(poll) => self.run_poll(poll, &clock).await,
                Next::Wait(until) => tokio::time::sleep_until(until.min(next_stats)).await,
                Next::Idle => tokio::time::sleep_until(next_stats).await,
            }
        }
    }

    /// Opens the port if it is closed or broke; false if it cannot be opened now.
    async fn ensure_open(&mut self) -> bool {
        let mut state = self.state.lock().await;
        if state.client.is_some() && !state.broken {
            return true;
        }
        state.client = None;
        state.broken = false;
        match self.opener.open(self.format).await {
            Ok(client) => {
                state.client = Some(client);
                true
            }
            Err(error) => {
                tracing::warn!(target: "optobus_bus", line = &*self.name, "cannot open the line: {error}");
                state.errors.line += 1;
                false
            }
        }
    }

    async fn run_poll(&mut self, poll: usize, clock: &Clock) {
        let device_index = self.schedule.device_of(poll);
        let registers = &self.polls[poll].registers;
        let device = &mut self.devices[device_index];
        let requested = Instant::now();
        let result = device.core.read_group(registers).await;
        let replied = Instant::now();
        let outcome = match &result {
            Ok(readings) => {
                for &register in registers {
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
                Outcome::Answered
            }
            Err(DriverError::Transport(Error::Exception { .. })) => Outcome::Answered,
            Err(_) => Outcome::Failed,
        };
        if let Some(health) = self.schedule.done(poll, replied, outcome) {
            let errors = *device.errors.lock().unwrap_or_else(|e| e.into_inner());
            let reason = match (&result, health) {
                (Err(error), Health::Offline) => Some(error.to_string()),
                _ => None,
            };
            let event = HealthEvent {
                source: Arc::clone(&device.id),
                health,
                errors,
                reason,
            };
            tracing::info!(target: "optobus_bus", device = &*device.id.device, ?health, "device health");
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
