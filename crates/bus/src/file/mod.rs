//! The bus file: which lines there are, which devices sit on them, what to poll.
//!
//! [`BusFile::parse`] reads the YAML with the spec compiler's positioned parse and reports
//! every problem at once, located like rustc ([`Rejected`]); nothing is opened before the
//! whole file passes. The schema is [`SCHEMA`] (the crate's README shows it, with a tour).
//! The `outputs` are not the bus's: [`BusFile::parse_with`] hands their sections to the
//! outputs' readers ([`ReadOutputs`]), which read them with the file's [`reading`] kit.

mod check;
mod measurements;
mod outputs;
mod pick;
mod read;
mod read_device;
pub mod reading;

pub use measurements::Measurements;
pub use outputs::{OutputSettings, Outputs, ReadOutputs};
pub use pick::{GatewayMoveError, LinePickError};
pub use read_device::{resolve, writable};

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use optobus_codec::LineFormat;
use optobus_device::{CommandInfo, DeviceInfo, RegisterInfo};
use optobus_spec::source::{read_yaml, ReadError};
use optobus_spec::{Diagnostic, SourceFile};

use optobus_spec::Catalogue;

/// The bus file's schema: every key a bus file takes, with its default or an example value
/// and what it means, as YAML comments (the crate's README shows the same text;
/// `optobus bus schema` prints it).
pub const SCHEMA: &str = include_str!("../../schema.yaml");

/// The longest interval, timeout or wait a bus file may give.
pub const MAX_DURATION: Duration = Duration::from_secs(24 * 60 * 60);

/// A checked bus file.
#[derive(Clone, Debug)]
pub struct BusFile {
    /// The lines, in file order.
    pub lines: Vec<LineConfig>,
    /// The devices, in file order.
    pub devices: Vec<DeviceConfig>,
    /// What the file computes from the registers the devices' polls read.
    pub measurements: Measurements,
}

/// One line: a port and the character format on it.
#[derive(Clone, Debug, PartialEq)]
pub struct LineConfig {
    /// The name devices refer to.
    pub name: String,
    /// Where the line is.
    pub port: Port,
    /// The serial character format (which sets t3.5); `None` on a Modbus TCP line.
    pub format: Option<LineFormat>,
    /// The silence after a broadcast before the next request (the Modbus serial-line
    /// specification's turnaround delay).
    pub broadcast_turnaround: Duration,
    /// A Modbus TCP gateway onto the line for other masters.
    pub gateway: Option<GatewayConfig>,
}

/// A Modbus TCP server whose requests go onto an RTU line between the bus's own polls.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GatewayConfig {
    /// Where it listens (127.0.0.1 unless the file names another address).
    pub listen: SocketAddr,
    /// Most clients connected at once; a new one closes the client idle the longest (no
    /// request in flight), and is closed at once only when every client has one in flight.
    pub clients: usize,
    /// Most requests waiting for the line (the most the line serves between two polls);
    /// one more is answered busy (exception 06) at once.
    pub queue: usize,
    /// A client that sends no whole request for this long, or does not take its reply
    /// within it, is closed.
    pub idle: Duration,
    /// Whether writes pass (Modbus TCP carries no credentials, so they are off by default);
    /// writes to the bus's devices are checked against their specs first.
    pub writes: bool,
    /// The unit id at which the bus file's measurements are input registers (the map is in
    /// the crate's README); a unit id of no device of the line.
    pub measurements_unit: u8,
}

impl GatewayConfig {
    /// A gateway listening on `listen` with the defaults a bus file's `gateway: ADDRESS`
    /// gets: [`DEFAULT_GATEWAY_CLIENTS`] clients, as many requests queued, idle after
    /// [`DEFAULT_GATEWAY_IDLE`], no writes, the measurements at [`DEFAULT_MEASUREMENTS_UNIT`].
    pub fn new(listen: SocketAddr) -> Self {
        Self {
            listen,
            clients: DEFAULT_GATEWAY_CLIENTS,
            queue: DEFAULT_GATEWAY_CLIENTS,
            idle: DEFAULT_GATEWAY_IDLE,
            writes: false,
            measurements_unit: DEFAULT_MEASUREMENTS_UNIT,
        }
    }
}

/// The unit id of the measurements' virtual unit unless the file says otherwise: 255, which
/// Modbus TCP gives the server itself and no RTU device can have (slaves are 1 to 247).
pub const DEFAULT_MEASUREMENTS_UNIT: u8 = 255;

/// Clients a gateway serves at once unless the file says otherwise.
pub const DEFAULT_GATEWAY_CLIENTS: usize = 8;

/// How long a gateway keeps a client that sends nothing unless the file says otherwise
/// (mbusd's default connection timeout).
pub const DEFAULT_GATEWAY_IDLE: Duration = Duration::from_secs(60);

/// Where a line is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Port {
    /// A serial port (`/dev/ttyUSB0`, `COM3`).
    Serial(String),
    /// A Modbus TCP server (`host:port`); each device is a unit id behind it.
    Tcp(String),
    /// RTU frames tunnelled over TCP (a serial-to-Ethernet converter, `host:port`).
    RtuOverTcp(String),
    /// Simulators of the line's devices, in memory, timed as the line's format.
    Simulated,
}

impl Port {
    /// The port's address as the file gives it (empty for a simulated line).
    pub fn address(&self) -> &str {
        match self {
            Self::Serial(path) => path,
            Self::Tcp(address) | Self::RtuOverTcp(address) => address,
            Self::Simulated => "",
        }
    }

    /// Whether requests travel as RTU frames with t3.5 between them.
    pub fn is_rtu(&self) -> bool {
        !matches!(self, Self::Tcp(_))
    }
}

/// One device on a line.
#[derive(Clone, Debug)]
pub struct DeviceConfig {
    /// The name samples carry.
    pub name: String,
    /// The model's description.
    pub device: &'static DeviceInfo,
    /// The model as the file names it (`p-series`, or the spec file's path).
    pub model: String,
    /// Index of its line in [`BusFile::lines`].
    pub line: usize,
    /// Its slave address (1 to 247).
    pub slave: u8,
    /// How long to wait for each reply.
    pub timeout: Duration,
    /// How many times a failed repeatable read is tried again.
    pub retries: u8,
    /// Extra silence before each of its requests, beyond t3.5.
    pub silence_before: Duration,
    /// Extra silence after each of its replies, before the next request to anyone.
    pub silence_after: Duration,
    /// How long after the bus starts the device is first asked.
    pub power_up: Duration,
    /// What to read, and how often.
    pub polls: Vec<PollConfig>,
    /// On a simulated line: seeded faults in the simulated device's replies.
    pub faults: Option<optobus_simulator::Faults>,
    /// What writes from the network (MQTT, the console) may change: nothing unless listed.
    pub writable: Writable,
}

/// The registers and commands of a device that writes from the network may use: what the bus
/// file lists under the device's `writable`, nothing by default.
///
/// `all` stands for every writable register and every command that does not store, restart or
/// reset the device; a drastic command (and a register it writes) is writable only when named,
/// as naming it is the confirmation `optobus do … --yes` asks for. The register holding the
/// device's slave address is never writable on a bus, which addresses the device by it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Writable {
    /// Registers that may be set, in address order.
    pub registers: Vec<&'static RegisterInfo>,
    /// Commands that may be run.
    pub commands: Vec<&'static CommandInfo>,
}

impl Writable {
    /// Whether `register` may be set.
    pub fn allows_register(&self, register: &RegisterInfo) -> bool {
        self.registers
            .iter()
            .any(|r| r.name == register.name && r.address == register.address)
    }

    /// Whether `command` may be run.
    pub fn allows_command(&self, command: &CommandInfo) -> bool {
        self.commands.iter().any(|c| c.name == command.name)
    }

    /// Whether nothing may be written.
    pub fn is_empty(&self) -> bool {
        self.registers.is_empty() && self.commands.is_empty()
    }
}

/// A set of registers read together, periodically or as fast as the line allows.
#[derive(Clone, Debug)]
pub struct PollConfig {
    /// What the file names (groups and registers), for messages.
    pub names: Vec<String>,
    /// The registers, in the device's address order, repeats expanded.
    pub registers: Vec<&'static RegisterInfo>,
    /// The period; `None` polls as fast as the line allows (sharing it with the other such polls).
    pub every: Option<Duration>,
    /// Among polls due at once, the higher goes first.
    pub priority: u8,
}

/// A bus file that did not pass: its source and every problem found, rendered like rustc.
pub use optobus_spec::Rejected;

impl BusFile {
    /// Reads and checks a bus file's text. `name` is shown in diagnostics; spec files the
    /// devices name are found relative to `base` (the bus file's folder). Its `outputs` are
    /// left unread (only their shape is checked): [`BusFile::parse_with`] reads them.
    pub fn parse(
        name: &str,
        text: &str,
        base: &Path,
        catalogue: &Catalogue,
    ) -> Result<Self, Box<Rejected>> {
        Self::read(name, text, base, catalogue, None)
    }

    /// [`BusFile::parse`], the sections of `outputs` read by `outputs` as the file is read:
    /// their problems are the file's, reported in the one [`Rejected`] with the others.
    pub fn parse_with(
        name: &str,
        text: &str,
        base: &Path,
        catalogue: &Catalogue,
        outputs: &mut dyn ReadOutputs,
    ) -> Result<Self, Box<Rejected>> {
        Self::read(name, text, base, catalogue, Some(outputs))
    }

    fn read(
        name: &str,
        text: &str,
        base: &Path,
        catalogue: &Catalogue,
        outputs: Option<&mut dyn ReadOutputs>,
    ) -> Result<Self, Box<Rejected>> {
        let source = SourceFile::of_kind(reading::BUS_FILE, name, text);
        let mut diagnostics = Vec::new();
        let bus = match (&source.syntax_error, &source.root) {
            (Some(error), _) => {
                diagnostics.push(Diagnostic::from(error));
                None
            }
            (None, Some(root)) => {
                let mut reader = reading::FileReader::new(base, catalogue);
                let bus = reader.bus(root, outputs);
                diagnostics.append(&mut reader.kit.diagnostics);
                bus
            }
            (None, None) => {
                diagnostics.push(reading::empty());
                None
            }
        };
        let mut bus = bus;
        if let Some(bus) = &mut bus {
            diagnostics.append(&mut check::check(bus));
        }
        match bus.and_then(read::Parsed::file) {
            Some(bus) if diagnostics.is_empty() => Ok(bus),
            file => {
                if diagnostics.is_empty() && file.is_none() {
                    // Every item that does not read says why; a safety net all the same.
                    diagnostics.push(reading::incomplete());
                }
                Err(Box::new(Rejected {
                    source,
                    diagnostics,
                }))
            }
        }
    }

    /// Reads and checks the bus file at `path`: a regular file (or a pipe) of at most
    /// [`YAML_LIMIT`](optobus_spec::source::YAML_LIMIT) bytes of UTF-8, read as specs are.
    /// Its `outputs` are left unread, as [`BusFile::parse`] leaves them.
    pub fn load(path: &Path, catalogue: &Catalogue) -> Result<Self, LoadError> {
        Self::load_from(path, catalogue, None)
    }

    /// [`BusFile::load`], the sections of `outputs` read by `outputs` as
    /// [`BusFile::parse_with`] reads them.
    pub fn load_with(
        path: &Path,
        catalogue: &Catalogue,
        outputs: &mut dyn ReadOutputs,
    ) -> Result<Self, LoadError> {
        Self::load_from(path, catalogue, Some(outputs))
    }

    fn load_from(
        path: &Path,
        catalogue: &Catalogue,
        outputs: Option<&mut dyn ReadOutputs>,
    ) -> Result<Self, LoadError> {
        let text = read_yaml(path).map_err(|source| LoadError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let base = path.parent().unwrap_or(Path::new("."));
        Self::read(&path.display().to_string(), &text, base, catalogue, outputs)
            .map_err(LoadError::Rejected)
    }

    /// A bus of one line and one device on it (its line index 0), with no measurements and no
    /// outputs: a tool's bus for a single device.
    pub fn one_device(line: LineConfig, device: DeviceConfig) -> Self {
        Self {
            lines: vec![line],
            devices: vec![DeviceConfig { line: 0, ..device }],
            measurements: Measurements::default(),
        }
    }

    /// The devices on line `line`.
    pub fn devices_on(&self, line: usize) -> impl Iterator<Item = (usize, &DeviceConfig)> {
        self.devices
            .iter()
            .enumerate()
            .filter(move |(_, device)| device.line == line)
    }
}

impl LineConfig {
    /// A line called `name` on `port` with what a bus file's line gets by default: `format`
    /// on a serial line (none on Modbus TCP), the default broadcast turnaround, no gateway.
    /// Nothing is checked against the devices' manuals: check the format before.
    pub fn new(name: impl Into<String>, port: Port, format: LineFormat) -> Self {
        Self {
            name: name.into(),
            format: port.is_rtu().then_some(format),
            port,
            broadcast_turnaround: read::DEFAULT_BROADCAST_TURNAROUND,
            gateway: None,
        }
    }
}

impl Port {
    /// A Modbus TCP server at `address`, which must be `host:port` (as a bus file's `tcp`).
    pub fn tcp(address: &str) -> Result<Self, String> {
        if reading::has_port(address) {
            Ok(Self::Tcp(address.to_owned()))
        } else {
            Err(format!("`tcp` needs host:port, not `{address}`"))
        }
    }
}

impl PollConfig {
    /// A poll of `name` (a register, a field's register or a group of `device`) every
    /// `every` (`None`: as fast as the line allows), at priority 0, as a bus file's
    /// `{ read: name, every: … }`.
    pub fn new(
        device: &'static DeviceInfo,
        name: &str,
        every: Option<Duration>,
    ) -> Result<Self, String> {
        let mut registers = resolve(device, name)?;
        registers.sort_by_key(|r| (r.table, r.address));
        registers.dedup_by_key(|r| (r.table, r.address, r.name));
        Ok(Self {
            names: vec![name.to_owned()],
            registers,
            every,
            priority: 0,
        })
    }
}

impl DeviceConfig {
    /// Device `name`, of the model `device` describes, at `slave` on the line of index `line`,
    /// with what a bus file's device gets by default: the transport's default timeout, no
    /// retries, silences or power-up wait, no polls, no faults, nothing writable. `model` is
    /// the model's name; set it to a spec file's path for a device described by one.
    pub fn new(
        name: impl Into<String>,
        device: &'static DeviceInfo,
        line: usize,
        slave: u8,
    ) -> Self {
        Self {
            name: name.into(),
            device,
            model: device.model_name().to_string(),
            line,
            slave,
            timeout: optobus_transport::DEFAULT_TIMEOUT,
            retries: 0,
            silence_before: Duration::ZERO,
            silence_after: Duration::ZERO,
            power_up: Duration::ZERO,
            polls: Vec::new(),
            faults: None,
            writable: Writable::default(),
        }
    }

    /// The device with a poll of its measurements every `every`: the spec's `measurements`
    /// group, or else its first group (no poll for a model without groups).
    pub fn polling_measurements(mut self, every: Duration) -> Result<Self, String> {
        let groups = self.device.groups;
        let group = groups.iter().find(|g| g.name == "measurements");
        if let Some(group) = group.or(groups.first()) {
            let poll = PollConfig::new(self.device, group.name, Some(every))?;
            self.polls.push(poll);
        }
        Ok(self)
    }

    /// The simulated device a `simulated: true` line puts in this device's place: its model
    /// at its slave address, with its `faults` (a late reply lands after its `timeout`, unless
    /// the faults say how late with `late=` or `timeout=`).
    /// `optobus simulate --bus` serves a line of them on a pty or a port.
    pub fn simulator(&self) -> optobus_simulator::Simulator {
        let simulator = optobus_simulator::Simulator::new(self.device).slave(self.slave);
        match &self.faults {
            Some(faults) if faults.late_by() == optobus_simulator::Faults::default().late_by() => {
                simulator.faults(faults.clone().client_timeout(self.timeout))
            }
            Some(faults) => simulator.faults(faults.clone()),
            None => simulator,
        }
    }
}

/// Why a bus file could not be used.
#[derive(Debug)]
pub enum LoadError {
    /// The file could not be read.
    Read {
        /// The path given.
        path: PathBuf,
        /// Why.
        source: ReadError,
    },
    /// The file did not pass its checks.
    Rejected(Box<Rejected>),
}

impl std::fmt::Display for LoadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Read { path, source } => write!(f, "cannot read {}: {source}", path.display()),
            Self::Rejected(rejected) => rejected.fmt(f),
        }
    }
}

impl std::error::Error for LoadError {}

#[cfg(test)]
mod tests {
    use super::*;

    /// The YAML block of the crate's README under "The bus file".
    fn readme_schema() -> &'static str {
        let readme = include_str!("../../README.md");
        let start = readme.find("```yaml\n").expect("a YAML block") + "```yaml\n".len();
        let end = start + readme[start..].find("```").expect("its end");
        &readme[start..end]
    }

    /// Point 9 of issue 30: every key the reader takes is in the schema (`faults:` was not),
    /// and the README shows the schema the tool prints. (The outputs' keys are their crates';
    /// `optobus-service` checks that the schema shows them.)
    #[test]
    fn the_schema_names_every_key_the_reader_takes() {
        let keys = [
            read::TOP_KEYS,
            read::LINE_KEYS,
            read::PORT_KEYS,
            read::GATEWAY_KEYS,
            read::DEVICE_KEYS,
            read::POLL_KEYS,
        ]
        .into_iter()
        .flatten();
        let schema = readme_schema();
        let missing: Vec<&str> = keys
            .filter(|key| !schema.contains(&format!("{key}:")))
            .copied()
            .collect();
        assert!(missing.is_empty(), "the schema lacks {missing:?}");
        assert_eq!(schema, SCHEMA, "the README shows the schema as printed");
    }

    /// The README walk: `optobus bus schema`'s example failed its own `bus check` (`faults`
    /// on a serial line). It is a bus file that passes, with every key in use.
    #[test]
    fn the_schemas_example_passes_its_own_check() {
        let catalogue = crate::Catalogue::new([&optobus_p_series::DEVICE]);
        let file = BusFile::parse("schema.yaml", SCHEMA, Path::new("."), &catalogue)
            .unwrap_or_else(|e| panic!("{}", e.render()));
        let names = |devices: &[DeviceConfig]| -> Vec<(String, String)> {
            devices
                .iter()
                .map(|d| (d.name.clone(), file.lines[d.line].name.clone()))
                .collect()
        };
        assert_eq!(
            names(&file.devices),
            [
                ("left".to_owned(), "rs485".to_owned()),
                ("trial".to_owned(), "bench".to_owned())
            ]
        );
        assert!(file.devices[1].faults.is_some(), "the faults are read");
        assert_eq!(file.lines[1].port, Port::Simulated);
    }
}
