//! The cheap, clonable handle tests and servers share.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use optobus_codec::{Request, WriteValue};
use optobus_device::{DeviceInfo, RegisterInfo, Table};
use tokio::time::Instant;

use crate::faults::{FaultStats, Faults, Injector};
use crate::model::{Device, Incoming, Reply};
use crate::quirks::Quirks;

/// A virtual device of one family, driven by its `DeviceInfo`.
///
/// Clones share one device: a test keeps one clone to inspect and poke registers while
/// another serves the wire. Options are builder-style:
///
/// ```
/// # use optobus_device::DeviceInfo;
/// # fn demo(device: &'static DeviceInfo) {
/// use optobus_simulator::Simulator;
/// let sim = Simulator::new(device).slave(5).seed(42);
/// assert_eq!(sim.address(), 5);
/// # }
/// ```
#[derive(Clone, Debug)]
pub struct Simulator {
    shared: Arc<Mutex<Device>>,
    observer: Option<Observer>,
}

/// One request the device saw and its answer, as passed to [`Simulator::observe`].
#[derive(Clone, Copy, Debug)]
pub struct Exchange<'a> {
    /// The slave address of an RTU frame (`None` over TCP, where the unit id is ignored).
    pub slave: Option<u8>,
    /// The request's function code.
    pub function: u8,
    /// The decoded request (`None` for function codes the codec does not decode).
    pub request: Option<&'a Request>,
    /// What the device answers (`Reply::Silent` when it does not).
    pub reply: &'a Reply,
}

/// One log line: `slave 1 read holding 0 x2 -> 2 words` (no slave over TCP).
impl std::fmt::Display for Exchange<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(slave) = self.slave {
            write!(f, "slave {slave} ")?;
        }
        match self.request {
            Some(Request::Read {
                function,
                address,
                count,
            }) => {
                let table = Table::read_by(*function).as_str();
                write!(f, "read {table} {address} x{count}")?;
            }
            Some(Request::Write { address, value }) => match value {
                WriteValue::Word(word) => write!(f, "write {address} = {word}")?,
                WriteValue::DoubleWord(value) => write!(f, "write {address} = {value} (4 bytes)")?,
            },
            None => write!(f, "function {:02X}", self.function)?,
        }
        match self.reply {
            Reply::Read { words, .. } => write!(f, " -> {} words", words.len()),
            Reply::Write { .. } => f.write_str(" -> echo"),
            Reply::Exception { code, .. } => write!(f, " -> exception {:02X}", code.0),
            Reply::Silent => f.write_str(" -> no reply"),
        }
    }
}

/// A callback that sees every exchange (for logs).
#[derive(Clone)]
struct Observer(Arc<dyn Fn(&Exchange<'_>) + Send + Sync>);

impl std::fmt::Debug for Observer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Observer")
    }
}

/// A register's current state, for inspection.
#[derive(Clone, Debug, PartialEq)]
pub struct RegisterState {
    /// The register's description.
    pub info: &'static RegisterInfo,
    /// The words a read of the whole register shows now.
    pub words: Vec<u16>,
    /// Whether a test fixed the value with [`Simulator::poke`] (measurements only).
    pub pinned: bool,
}

/// Why [`Simulator::poke`] refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PokeError {
    /// No register at this address of the table.
    NoRegister {
        /// The table.
        table: Table,
        /// The first address without a register.
        address: u16,
    },
    /// No register of that name.
    UnknownName,
}

impl std::fmt::Display for PokeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NoRegister { table, address } => {
                write!(f, "no register at {} address {address}", table.as_str())
            }
            Self::UnknownName => f.write_str("no register of that name"),
        }
    }
}

impl std::error::Error for PokeError {}

impl Simulator {
    /// A device of `device`'s family at its factory settings, answering to
    /// `device.default_slave`.
    pub fn new(device: &'static DeviceInfo) -> Self {
        Self {
            shared: Arc::new(Mutex::new(Device::new(device))),
            observer: None,
        }
    }

    /// Calls `observer` with every request this handle (and clones made from it afterwards)
    /// answers, e.g. to log them.
    pub fn observe(mut self, observer: impl Fn(&Exchange<'_>) + Send + Sync + 'static) -> Self {
        self.observer = Some(Observer(Arc::new(observer)));
        self
    }

    pub(crate) fn lock(&self) -> MutexGuard<'_, Device> {
        // A panic elsewhere must not take the simulator down with it.
        self.shared.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Answers to slave address `slave` (also stored in the slave-address register, if the
    /// device has one, as if configured and saved).
    pub fn slave(self, slave: u8) -> Self {
        self.lock().set_slave(slave);
        self
    }

    /// Varies the measurement signals (phases, noise, sentinel samples); default 0.
    pub fn seed(self, seed: u64) -> Self {
        self.lock().signals.seed = seed;
        self
    }

    /// One sample in `every` of a reading with a sentinel reads as the sentinel (default 50;
    /// 0 never).
    pub fn sentinel_every(self, every: u32) -> Self {
        self.lock().signals.sentinel_every = every;
        self
    }

    /// Replaces the error codes and address rules derived by [`Quirks::of`].
    pub fn quirks(self, quirks: Quirks) -> Self {
        self.lock().quirks = quirks;
        self
    }

    /// Replaces the quirks in force from now on (all clones share them), e.g. to make a
    /// device contradict itself halfway through a procedure.
    pub fn set_quirks(&self, quirks: Quirks) {
        self.lock().quirks = quirks;
    }

    /// Injects `faults` into the replies of every server of this device (RTU and TCP; all
    /// clones share them). See [`crate::faults`].
    pub fn faults(self, faults: Faults) -> Self {
        self.set_faults(Some(faults));
        self
    }

    /// Starts injecting `faults` with fresh [`FaultStats`], or stops with `None`.
    pub fn set_faults(&self, faults: Option<Faults>) {
        self.lock().faults = faults.map(Injector::new);
    }

    /// Counts and log of the faults in force, if any.
    pub fn fault_stats(&self) -> Option<FaultStats> {
        self.lock().faults.as_ref().map(Injector::stats)
    }

    pub(crate) fn injector(&self) -> Option<Injector> {
        self.lock().faults.clone()
    }

    /// The device description.
    pub fn device(&self) -> &'static DeviceInfo {
        self.lock().info
    }

    /// The slave address the device answers to now.
    pub fn address(&self) -> u8 {
        self.lock().address
    }

    /// The error codes and address rules in force.
    pub fn current_quirks(&self) -> Quirks {
        self.lock().quirks
    }

    /// Stops (`true`) or resumes answering; a silent device neither answers nor acts.
    pub fn set_silent(&self, silent: bool) {
        self.lock().silent = silent;
    }

    /// Whether the device was made silent.
    pub fn is_silent(&self) -> bool {
        self.lock().silent
    }

    /// How long a command whose spec says how the device shows it finished (`done_when`)
    /// keeps the value written in its register before it shows that, instead of the
    /// command's busy time (all clones share it); `Duration::MAX` never finishes.
    pub fn finish_time(self, time: Duration) -> Self {
        self.lock().finish_time = Some(time);
        self
    }

    /// Whether the device ignores requests now (silent, or busy after a command).
    pub fn is_busy(&self) -> bool {
        let device = self.lock();
        device.silent
            || device
                .busy_until
                .is_some_and(|until| Instant::now() < until)
    }

    /// Switches the device off and on: unsaved settings, zero offsets and the data buffer
    /// are lost, the saved slave address applies (LC-RS: every setting takes effect only
    /// after save and power cycle, 2.2 3)), and the device is silent for
    /// `DeviceInfo::power_up_ms`.
    pub fn power_cycle(&self) {
        let now = Instant::now();
        let mut device = self.lock();
        let t = device.seconds(now);
        device.restart(t);
        let power_up = u64::from(device.info.power_up_ms);
        device.busy_until = (power_up > 0).then(|| now + Duration::from_millis(power_up));
    }

    /// Answers one request sent to `slave` (0: broadcast), as the RTU server would.
    pub fn request(&self, slave: u8, request: &Request) -> Reply {
        self.lock()
            .respond(Some(slave), Incoming::Request(request), Instant::now())
    }

    /// Answers a request sent over Modbus TCP (any unit id).
    pub fn request_tcp(&self, request: &Request) -> Reply {
        self.lock()
            .respond(None, Incoming::Request(request), Instant::now())
    }

    pub(crate) fn respond(&self, slave: Option<u8>, incoming: Incoming<'_>) -> Reply {
        let reply = self.lock().respond(slave, incoming, Instant::now());
        if let Some(Observer(observer)) = &self.observer {
            let (request, function) = match incoming {
                Incoming::Request(request) => (Some(request), request.function_code()),
                Incoming::Unsupported(function) => (None, function),
            };
            observer(&Exchange {
                slave,
                function,
                request,
                reply: &reply,
            });
        }
        reply
    }

    /// Every register with the words it shows now.
    pub fn registers(&self) -> Vec<RegisterState> {
        let device = self.lock();
        let t = device.seconds(Instant::now());
        device
            .info
            .registers
            .iter()
            .enumerate()
            .map(|(index, info)| RegisterState {
                info,
                words: device.live_words(index, t),
                pinned: device.pinned.get(index).copied().unwrap_or(false),
            })
            .collect()
    }

    /// The register called `name` with the words it shows now.
    pub fn register(&self, name: &str) -> Option<RegisterState> {
        let device = self.lock();
        let index = device.layout.find(name)?;
        let t = device.seconds(Instant::now());
        Some(RegisterState {
            info: device.register(index)?,
            words: device.live_words(index, t),
            pinned: device.pinned.get(index).copied().unwrap_or(false),
        })
    }

    /// The words a read of `address` alone would show now: one word, or the whole field on
    /// one-address-per-field devices. Reserved addresses show zeros; `None` for undefined
    /// addresses. Reading does not turn the data buffer's page.
    pub fn peek(&self, table: Table, address: u16) -> Option<Vec<u16>> {
        self.lock().peek(table, address, Instant::now())
    }

    /// Stores `words` from `address` on (the whole field on one-address-per-field devices),
    /// without validation or commands. A measurement poked this way keeps the value until
    /// [`Simulator::release`] or a zero command.
    pub fn poke(&self, table: Table, address: u16, words: &[u16]) -> Result<(), PokeError> {
        self.lock()
            .poke(table, address, words, Instant::now())
            .map_err(|address| PokeError::NoRegister { table, address })
    }

    /// [`Simulator::poke`] by register name: `words` are the whole register's.
    pub fn set(&self, name: &str, words: &[u16]) -> Result<(), PokeError> {
        let register = self.device().register(name).ok_or(PokeError::UnknownName)?;
        self.poke(register.table, register.address, words)
    }

    /// Lets a poked measurement move again; `false` if `name` is not a register.
    pub fn release(&self, name: &str) -> bool {
        let mut device = self.lock();
        let Some(index) = device.layout.find(name) else {
            return false;
        };
        if let Some(pinned) = device.pinned.get_mut(index) {
            *pinned = false;
        }
        true
    }
}
