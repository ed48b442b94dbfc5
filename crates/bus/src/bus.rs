//! Starting a bus: a task per line, the devices' driver cores, and the event stream.

use std::collections::HashMap;
use std::sync::Arc;

use optobus_driver::{rtu_config, Core};
use optobus_simulator::Simulator;
use optobus_transport::Stream;
use std::net::SocketAddr;

use tokio::net::TcpListener;
use tokio::sync::{broadcast, mpsc, Mutex};
use tokio::task::JoinHandle;

use crate::event::{DeviceId, ErrorCounts, Event};
use crate::file::{BusFile, Port};
use crate::gateway::{self, GatewayCounters, GatewayCounts};
use crate::handle::{Entry, Handle, LineQueues};
use crate::line::{Clock, DeviceRun, GatewayQueue, LineTask, Opener, PollRun};
use crate::link::{DeviceLink, DeviceSettings, LineState};
use crate::measurement_unit::{self, MeasurementUnit};
use crate::measuring::{self, Measuring};
use crate::schedule::{measurement_groups, Schedule};
use crate::source::Source;
use crate::trace::LineFrames;
use crate::turns::Turns;

/// Events a bus keeps for a slow receiver before it drops the oldest (the receiver learns how
/// many it missed).
pub const DEFAULT_EVENT_CAPACITY: usize = 4096;

/// A bus file made ready to run.
pub struct Bus {
    file: BusFile,
    streams: HashMap<String, Box<dyn Stream>>,
    events: broadcast::Sender<Event>,
    /// Whether a measurement's polls are scheduled as a group (off only to measure what the
    /// groups change).
    grouped: bool,
}

impl std::fmt::Debug for Bus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bus")
            .field("file", &self.file)
            .finish_non_exhaustive()
    }
}

/// A running bus; dropping it stops every line.
#[derive(Debug)]
pub struct Running {
    events: broadcast::Sender<Event>,
    handle: Handle,
    gateways: Vec<(String, SocketAddr, Arc<GatewayCounters>)>,
    tasks: Vec<JoinHandle<()>>,
    simulators: Vec<(String, Simulator)>,
}

impl Bus {
    /// A bus for `file`, keeping [`DEFAULT_EVENT_CAPACITY`] events for slow receivers.
    pub fn new(file: BusFile) -> Self {
        Self {
            file,
            streams: HashMap::new(),
            events: broadcast::channel(DEFAULT_EVENT_CAPACITY).0,
            grouped: true,
        }
    }

    /// Schedules every poll on its own phase, a measurement's polls as any other: the
    /// scheduling before measurement groups, kept for the `skew` bench to measure against.
    #[doc(hidden)]
    pub fn without_measurement_groups(mut self) -> Self {
        self.grouped = false;
        self
    }

    /// Keeps `capacity` events (at least 1) for slow receivers.
    pub fn event_capacity(mut self, capacity: usize) -> Self {
        self.events = broadcast::channel(capacity.max(1)).0;
        self
    }

    /// Runs line `line` over `stream` instead of its port (an in-memory line in tests).
    pub fn with_stream(mut self, line: &str, stream: impl Stream) -> Self {
        self.streams.insert(line.to_owned(), Box::new(stream));
        self
    }

    /// A receiver of the bus's events; subscribe before [`Bus::start`] to miss none.
    pub fn subscribe(&self) -> broadcast::Receiver<Event> {
        self.events.subscribe()
    }

    /// Starts a task per line (within a tokio runtime), and each line's gateway. Ports are
    /// opened by their line's task, which retries with backoff: a missing port never stops the
    /// other lines. Fails only when a gateway cannot listen on its address.
    pub fn start(mut self) -> Result<Running, StartError> {
        let mut tasks = Vec::new();
        let mut simulators = Vec::new();
        let mut gateways = Vec::new();
        let mut job_queues = Vec::new();
        let mut entries = Vec::new();
        let mut line_frames = Vec::new();
        // One clock for every line: the request times of two lines' samples compare exactly,
        // and the measurement groups tick from this start on every line.
        let clock = Clock::now();
        let start = clock.instant;
        let groups = if self.grouped {
            measurement_groups(&self.file)
        } else {
            Vec::new()
        };
        // Subscribed before any line runs, so that no input's first sample is missed.
        let measuring = (!self.file.measurements.is_empty()).then(|| {
            let measuring = Arc::new(Measuring::new(self.file.measurements.clone()));
            tasks.push(tokio::spawn(measuring::follow(
                Arc::clone(&measuring),
                self.events.subscribe(),
                self.events.clone(),
            )));
            measuring
        });
        // The measurements as registers of each gateway's measurements unit, followed from
        // before any line runs.
        let has_gateway = self.file.lines.iter().any(|line| line.gateway.is_some());
        let measurement_unit = (has_gateway && !self.file.measurements.is_empty()).then(|| {
            let unit = Arc::new(MeasurementUnit::new(&self.file.measurements));
            tasks.push(tokio::spawn(measurement_unit::follow(
                Arc::clone(&unit),
                self.events.subscribe(),
            )));
            unit
        });
        for (index, line) in self.file.lines.iter().enumerate() {
            let name: Arc<str> = Arc::from(line.name.as_str());
            let frames = Arc::new(LineFrames::new(self.file.devices_on(index).count()));
            line_frames.push(Arc::clone(&frames));
            let state = Arc::new(Mutex::new(LineState::new(
                line.format
                    .map_or(std::time::Duration::ZERO, |f| f.frame_gap()),
                frames,
            )));
            let mut schedule = Schedule::default();
            let mut devices = Vec::new();
            let mut polls = Vec::new();
            let mut line_simulators = Vec::new();
            // Each poll of the file's devices on this line: (device in the file, its poll) to
            // the line's poll.
            let mut line_polls = HashMap::new();
            for (file_index, config) in self.file.devices_on(index) {
                let id = Arc::new(DeviceId {
                    device: Arc::from(config.name.as_str()),
                    model: Arc::from(config.device.model_name().to_string()),
                    line: Arc::clone(&name),
                    slave: config.slave,
                });
                entries.push(Entry {
                    id: Arc::clone(&id),
                    line: index,
                    index: devices.len(),
                    device: config.device,
                    writable: config.writable.clone(),
                });
                let errors = Arc::new(std::sync::Mutex::new(ErrorCounts::default()));
                let settings = DeviceSettings {
                    timeout: config.timeout,
                    retries: config.retries,
                    exception: rtu_config(config.device).exception,
                    silence_before: config.silence_before,
                    silence_after: config.silence_after,
                };
                let link = DeviceLink {
                    line: Arc::clone(&state),
                    settings,
                    index: devices.len(),
                    errors: Arc::clone(&errors),
                };
                let core = Core::new(link, config.slave, config.device)
                    .expect("bus files hold slaves 1 to 247");
                let device = schedule.add_device(start + config.power_up);
                for (poll_index, poll) in config.polls.iter().enumerate() {
                    let added = schedule.add_poll(device, poll.every, poll.priority);
                    line_polls.insert((file_index, poll_index), added);
                    polls.push(PollRun {
                        registers: poll.registers.clone(),
                    });
                }
                devices.push(DeviceRun {
                    settings,
                    id,
                    core,
                    errors,
                    writable: config.writable.clone(),
                });
                if line.port == Port::Simulated {
                    let simulator = config.simulator();
                    line_simulators.push(simulator.clone());
                    simulators.push((config.name.clone(), simulator));
                }
            }
            for group in &groups {
                let members: Vec<usize> = group
                    .polls
                    .iter()
                    .filter_map(|poll| line_polls.get(poll).copied())
                    .collect();
                if !members.is_empty() {
                    schedule.add_group(members, group.every, start);
                }
            }
            let opener = match self.streams.remove(&line.name) {
                Some(stream) => Opener::Stream(Some(stream)),
                None => port_opener(&line.port, line.format, line_simulators),
            };
            let gateway = match &line.gateway {
                Some(config) => {
                    let listener = bind(config.listen).map_err(|source| StartError {
                        line: line.name.clone(),
                        address: config.listen,
                        source,
                    })?;
                    let (queue, requests) = mpsc::channel(config.queue);
                    let counters = Arc::new(GatewayCounters::default());
                    if let Ok(address) = listener.local_addr() {
                        gateways.push((line.name.clone(), address, Arc::clone(&counters)));
                    }
                    let slaves = self.file.devices_on(index).map(|(_, device)| device.slave);
                    tasks.push(tokio::spawn(gateway::serve(
                        listener,
                        config.clone(),
                        gateway::Slaves::of(slaves),
                        measurement_unit.clone(),
                        queue,
                        Arc::clone(&counters),
                    )));
                    Some(GatewayQueue {
                        requests,
                        writes: config.writes,
                        counters,
                    })
                }
                None => None,
            };
            let (queues, jobs) = LineQueues::new();
            job_queues.push(queues);
            let task = LineTask {
                jobs,
                gateway,
                broadcast_turnaround: line.broadcast_turnaround,
                name,
                format: line.format,
                opener,
                state,
                devices,
                polls,
                schedule,
                events: self.events.clone(),
                finishing: Vec::new(),
                turns: Turns::default(),
                clock,
            };
            tasks.push(tokio::spawn(task.run()));
        }
        let measurements = &self.file.measurements;
        let limits = (measurements.plan.formulas.iter())
            .zip(&measurements.settings)
            .filter_map(|(formula, settings)| {
                Some((Arc::from(formula.name.as_str()), settings.limits?))
            })
            .collect();
        Ok(Running {
            handle: Handle {
                lines: job_queues.into(),
                source: Source::Api,
                origin: None,
                devices: entries.into(),
                frames: line_frames.into(),
                measuring,
                limits,
            },
            events: self.events,
            gateways,
            tasks,
            simulators,
        })
    }
}

/// A gateway that cannot listen.
#[derive(Debug)]
pub struct StartError {
    /// The line it serves.
    pub line: String,
    /// Its address.
    pub address: SocketAddr,
    /// Why.
    pub source: std::io::Error,
}

impl std::fmt::Display for StartError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "the gateway of line `{}` cannot listen on {}: {}",
            self.line, self.address, self.source
        )
    }
}

impl std::error::Error for StartError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&self.source)
    }
}

/// A listening socket, made without waiting (`start` is not async).
fn bind(address: SocketAddr) -> std::io::Result<TcpListener> {
    let listener = std::net::TcpListener::bind(address)?;
    listener.set_nonblocking(true)?;
    TcpListener::from_std(listener)
}

fn port_opener(
    port: &Port,
    format: Option<optobus_codec::LineFormat>,
    simulators: Vec<Simulator>,
) -> Opener {
    match port {
        Port::Simulated => Opener::Simulated(optobus_simulator::Slaves::new(simulators), format),
        #[cfg(feature = "serial")]
        Port::Serial(path) => Opener::Port(optobus_transport::Port::Serial(
            optobus_transport::SerialSettings {
                path: path.clone(),
                line: format.unwrap_or(optobus_codec::LineFormat::new(115_200)),
            },
        )),
        #[cfg(feature = "tcp")]
        Port::RtuOverTcp(address) => {
            Opener::Port(optobus_transport::Port::RtuOverTcp(address.clone()))
        }
        #[cfg(feature = "tcp")]
        Port::Tcp(address) => Opener::Port(optobus_transport::Port::Tcp {
            address: address.clone(),
            default_port: 502,
        }),
        #[allow(unreachable_patterns)]
        _ => Opener::Stream(None),
    }
}

impl Running {
    /// Another receiver of the bus's events (from now on).
    pub fn subscribe(&self) -> broadcast::Receiver<Event> {
        self.events.subscribe()
    }

    /// The simulator of device `name`, on a `simulated: true` line.
    pub fn simulator(&self, name: &str) -> Option<&Simulator> {
        self.simulators
            .iter()
            .find(|(device, _)| device == name)
            .map(|(_, simulator)| simulator)
    }

    /// A handle to write, run commands and read through the bus's lines.
    pub fn handle(&self) -> Handle {
        self.handle.clone()
    }

    /// Each line's gateway and where it listens.
    pub fn gateways(&self) -> impl Iterator<Item = (&str, SocketAddr)> {
        self.gateways
            .iter()
            .map(|(line, address, _)| (line.as_str(), *address))
    }

    /// Where the gateway of line `line` listens (its port, when the file asked for port 0).
    pub fn gateway_address(&self, line: &str) -> Option<SocketAddr> {
        self.gateways
            .iter()
            .find(|(name, ..)| name == line)
            .map(|(_, address, _)| *address)
    }

    /// What the gateway of line `line` has passed, refused and closed.
    pub fn gateway_counts(&self, line: &str) -> Option<GatewayCounts> {
        self.gateways
            .iter()
            .find(|(name, ..)| name == line)
            .map(|(_, _, counters)| counters.counts())
    }

    /// Stops every line.
    pub fn stop(self) {}
}

impl Drop for Running {
    fn drop(&mut self) {
        for task in &self.tasks {
            task.abort();
        }
    }
}
