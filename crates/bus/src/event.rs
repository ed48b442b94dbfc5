//! What a running bus tells: samples, device health, line statistics.

use std::sync::Arc;
use std::time::{Duration, SystemTime};

use optobus_device::RegisterInfo;
use optobus_inspect::Value;
use serde::ser::{SerializeStruct, Serializer};
use serde::Serialize;

use crate::measurement::MeasurementEvent;
use crate::schedule::Health;
use crate::source::Source;
pub use crate::time::rfc3339;

/// One event of a running bus.
#[derive(Clone, Debug)]
pub enum Event {
    /// A register's value, read by a poll.
    Sample(Arc<Sample>),
    /// A device went online or offline.
    Health(Arc<HealthEvent>),
    /// A line's statistics, sent once a second while it runs.
    Line(Arc<LineStats>),
    /// A measurement of the bus file: its value, or why it has none.
    Measurement(Arc<MeasurementEvent>),
    /// A write reached a device and it took it: whoever shows the register's value (MQTT's
    /// Home Assistant states) may read it again now rather than at its next refresh.
    Written(Arc<Written>),
}

/// Who had a register written.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Writer {
    /// A client of the line's Modbus TCP gateway.
    Gateway,
    /// A job of a [`Handle`](crate::Handle), of its [`Source`].
    Job(Source),
}

impl Writer {
    /// Its name in messages: `gateway`, or the source's (`api`, `console`, `mqtt`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Gateway => "gateway",
            Self::Job(source) => source.name(),
        }
    }
}

/// A write a device took (its reply said so; a broadcast: once it was sent, for every device
/// of the line).
#[derive(Clone, Debug)]
pub struct Written {
    /// The device written.
    pub source: Arc<DeviceId>,
    /// The registers the write covered, in address order (a command's: its register).
    pub registers: Vec<&'static RegisterInfo>,
    /// Who asked for it.
    pub by: Writer,
}

/// For scripts: `device`, `model`, `line`, `slave`, `registers` (their names) and `by`.
impl Serialize for Written {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut fields = serializer.serialize_struct("Written", 6)?;
        fields.serialize_field("device", &*self.source.device)?;
        fields.serialize_field("model", &*self.source.model)?;
        fields.serialize_field("line", &*self.source.line)?;
        fields.serialize_field("slave", &self.source.slave)?;
        let names: Vec<&str> = self.registers.iter().map(|r| r.name).collect();
        fields.serialize_field("registers", &names)?;
        fields.serialize_field("by", self.by.name())?;
        fields.end()
    }
}

/// Which device a sample or health event is about.
#[derive(Clone, Debug, Serialize)]
pub struct DeviceId {
    /// Its name in the bus file.
    pub device: Arc<str>,
    /// Its model as users type it (`p-series`).
    pub model: Arc<str>,
    /// Its line's name.
    pub line: Arc<str>,
    /// Its slave address.
    pub slave: u8,
}

/// A register's value as one reply carried it.
#[derive(Clone, Debug)]
pub struct Sample {
    /// Whose value it is.
    pub source: Arc<DeviceId>,
    /// The register.
    pub register: &'static RegisterInfo,
    /// The value, decoded from the spec (quantities exact, with their unit).
    pub value: Value,
    /// When the poll's first request left.
    pub requested: SystemTime,
    /// When its last reply arrived.
    pub replied: SystemTime,
}

/// For scripts: `device`, `model`, `line`, `slave`, `register`, the value in the tool's JSON
/// shape, and `time` (the reply's) in RFC 3339 with microseconds.
impl Serialize for Sample {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut fields = serializer.serialize_struct("Sample", 7)?;
        fields.serialize_field("device", &*self.source.device)?;
        fields.serialize_field("model", &*self.source.model)?;
        fields.serialize_field("line", &*self.source.line)?;
        fields.serialize_field("slave", &self.source.slave)?;
        fields.serialize_field("register", self.register.name)?;
        fields.serialize_field("value", &self.value)?;
        fields.serialize_field("time", &rfc3339(self.replied))?;
        fields.end()
    }
}

/// Failed transactions of a device or line, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ErrorCounts {
    /// No reply in time.
    pub timeouts: u64,
    /// Garbled, foreign or malformed replies.
    pub frames: u64,
    /// Exception replies.
    pub exceptions: u64,
    /// The port closed, could not be opened, or failed otherwise.
    pub line: u64,
}

impl ErrorCounts {
    /// All of them.
    pub fn total(&self) -> u64 {
        self.timeouts + self.frames + self.exceptions + self.line
    }
}

/// A device's health changed.
#[derive(Clone, Debug, Serialize)]
pub struct HealthEvent {
    /// Which device.
    pub source: Arc<DeviceId>,
    /// Its new health.
    pub health: Health,
    /// Its errors since the bus started.
    pub errors: ErrorCounts,
    /// The last failure, when it went offline.
    pub reason: Option<String>,
}

/// How busy a line has been since the bus started.
#[derive(Clone, Debug, Serialize)]
pub struct LineStats {
    /// The line's name.
    pub line: Arc<str>,
    /// Requests sent.
    pub transactions: u64,
    /// Failed ones, by kind.
    pub errors: ErrorCounts,
    /// Time spent in transactions (request out to reply in, or the timeout).
    pub busy: Duration,
    /// Time since the line started.
    pub elapsed: Duration,
    /// Whether the port is open.
    pub open: bool,
}

impl LineStats {
    /// The share of time the line spent in transactions, 0 to 1.
    pub fn utilisation(&self) -> f64 {
        if self.elapsed.is_zero() {
            return 0.0;
        }
        (self.busy.as_secs_f64() / self.elapsed.as_secs_f64()).min(1.0)
    }
}
