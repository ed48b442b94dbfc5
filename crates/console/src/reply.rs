//! The JSON the console sends, as types: the contract with `app.js` and every other client of
//! the API, one struct per shape, in the order its keys are sent.

use std::sync::Arc;
use std::time::{SystemTime, UNIX_EPOCH};

use optobus_bus::{ErrorCounts, Health, LineStats, MeasurementEvent, Sample};
use optobus_device::{FieldInfo, RegisterInfo, ValueKind};
use optobus_inspect::Value;
use optobus_measure::{Judgement, Limits, Summary};
use serde::ser::{Serialize, SerializeMap, Serializer};

/// A sample as the page takes it: its text as the tool shows it, its JSON value, a number for
/// charts, the fields of a packed or record register (a row each on the page), and the
/// reply's time.
#[derive(Clone, Debug, serde::Serialize)]
pub(crate) struct SampleJson {
    device: Arc<str>,
    register: &'static str,
    text: String,
    value: Value,
    number: Option<f64>,
    /// `null` for a register of one value.
    fields: Option<Vec<FieldJson>>,
    /// Milliseconds since 1970.
    time: f64,
}

/// One field of a packed or record register, for a row of its own on the page.
#[derive(Clone, Debug, serde::Serialize)]
pub(crate) struct FieldJson {
    name: &'static str,
    unit: Option<&'static str>,
    text: String,
    number: Option<f64>,
}

impl SampleJson {
    pub(crate) fn new(sample: &Sample) -> Self {
        Self {
            device: Arc::clone(&sample.source.device),
            register: sample.register.name,
            text: sample.value.to_string(),
            value: sample.value.clone(),
            number: number(&sample.value),
            fields: fields(sample.register, &sample.value),
            time: unix_ms(sample.replied),
        }
    }
}

/// Milliseconds since 1970, as the page's charts take times.
pub(crate) fn unix_ms(time: SystemTime) -> f64 {
    time.duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64() * 1000.0)
}

/// A value as a number for a chart, when it is one.
fn number(value: &Value) -> Option<f64> {
    match value {
        Value::Integer(n) => Some(*n as f64),
        Value::Quantity(fixed, _) => Some(fixed.to_f64()),
        Value::Bool(b) => Some(f64::from(u8::from(*b))),
        Value::Code(code, _) => Some(f64::from(*code)),
        _ => None,
    }
}

/// A packed or record register's fields, in its spec's order; `None` for a register of one
/// value.
fn fields(register: &RegisterInfo, value: &Value) -> Option<Vec<FieldJson>> {
    let fields = match register.kind {
        ValueKind::Packed(fields) | ValueKind::Record(fields) => fields,
        _ => return None,
    };
    let values = match value {
        Value::Fields(values) => values.as_slice(),
        // The whole register invalid: so is each field.
        _ => &[],
    };
    let field = |field: &FieldInfo| {
        let value = values
            .iter()
            .find(|(name, _)| *name == field.name)
            .map_or(&Value::Invalid, |(_, value)| value);
        FieldJson {
            name: field.name,
            unit: field.unit,
            text: value.to_string(),
            number: number(value),
        }
    };
    Some(fields.iter().map(field).collect())
}

/// A sample of `GET /api/values`: as the stream sent it, and whether it is still current (a
/// down device's last values are not).
#[derive(Debug, serde::Serialize)]
pub(crate) struct LatestSample<'a> {
    #[serde(flatten)]
    pub(crate) sample: &'a SampleJson,
    pub(crate) current: bool,
}

/// `GET /api/values`: each device's latest samples, by device name, in the bus file's order.
#[derive(Debug)]
pub(crate) struct Values<'a>(pub(crate) Vec<(&'a str, Vec<LatestSample<'a>>)>);

impl Serialize for Values<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(self.0.len()))?;
        for (device, samples) in &self.0 {
            map.serialize_entry(device, samples)?;
        }
        map.end()
    }
}

/// A device's health, as the stream sends its changes.
#[derive(Clone, Debug, serde::Serialize)]
pub(crate) struct HealthJson {
    device: Arc<str>,
    health: Health,
    errors: ErrorCounts,
    reason: Option<String>,
}

impl HealthJson {
    pub(crate) fn new(
        device: &Arc<str>,
        health: Health,
        errors: ErrorCounts,
        reason: Option<String>,
    ) -> Self {
        Self {
            device: Arc::clone(device),
            health,
            errors,
            reason,
        }
    }
}

/// A line's statistics, as the stream sends them once a second.
#[derive(Clone, Debug, serde::Serialize)]
pub(crate) struct LineJson {
    line: Arc<str>,
    transactions: u64,
    errors: ErrorCounts,
    utilisation: f64,
    open: bool,
}

impl LineJson {
    pub(crate) fn new(stats: &LineStats) -> Self {
        Self {
            line: Arc::clone(&stats.line),
            transactions: stats.transactions,
            errors: stats.errors,
            utilisation: stats.utilisation(),
            open: stats.open,
        }
    }
}

/// A device in `GET /api/devices`: its health, and where it is.
#[derive(Debug, serde::Serialize)]
pub(crate) struct DeviceJson {
    #[serde(flatten)]
    pub(crate) health: HealthJson,
    pub(crate) model: Arc<str>,
    pub(crate) line: Arc<str>,
    pub(crate) slave: u8,
    pub(crate) title: &'static str,
}

/// `GET /api/devices`.
#[derive(Debug, serde::Serialize)]
pub(crate) struct Devices<'a> {
    pub(crate) devices: Vec<DeviceJson>,
    pub(crate) lines: Vec<&'a LineJson>,
    pub(crate) needs_token: bool,
}

/// `GET /api/status`.
#[derive(Debug, serde::Serialize)]
pub(crate) struct Status {
    pub(crate) stream_clients: usize,
    pub(crate) dropped_batches: u64,
    pub(crate) missed_events: u64,
    pub(crate) busy_refusals: u64,
    /// `null` until the listener serves.
    pub(crate) connections: Option<Connections>,
}

/// The listener's connections (see `optobus_http::Counts`).
#[derive(Debug, serde::Serialize)]
pub(crate) struct Connections {
    open: usize,
    accepted: u64,
    refused: u64,
    header_timeouts: u64,
    idle_closed: u64,
    request_timeouts: u64,
}

impl From<optobus_http::Counts> for Connections {
    fn from(counts: optobus_http::Counts) -> Self {
        Self {
            open: counts.open,
            accepted: counts.accepted,
            refused: counts.refused,
            header_timeouts: counts.header_timeouts,
            idle_closed: counts.idle_closed,
            request_timeouts: counts.request_timeouts,
        }
    }
}

/// A frame of `GET /api/devices/{device}/frames`.
#[derive(Debug, serde::Serialize)]
pub(crate) struct FrameJson {
    /// `sent` or `received`.
    pub(crate) direction: &'static str,
    pub(crate) hex: String,
    /// RFC 3339.
    pub(crate) time: String,
    pub(crate) unix_ms: f64,
    /// For a reply: microseconds after its request.
    pub(crate) after_us: Option<u64>,
}

/// A register read or written: `POST …/read` and `POST …/set`.
#[derive(Debug, serde::Serialize)]
pub(crate) struct RegisterValue {
    pub(crate) register: String,
    /// As the tool shows it; `written` for a register that cannot be read back.
    pub(crate) text: String,
    pub(crate) value: Option<Value>,
}

/// `POST …/do`.
#[derive(Debug, serde::Serialize)]
pub(crate) struct Done {
    pub(crate) command: String,
    pub(crate) done: bool,
}

/// Every refusal: `{"error": "…"}`.
#[derive(Debug, serde::Serialize)]
pub(crate) struct Refusal<'a> {
    pub(crate) error: &'a str,
}

/// One batch of the live stream: what happened since the last.
#[derive(Debug, Default, serde::Serialize)]
pub(crate) struct BatchJson {
    pub(crate) samples: Vec<SampleJson>,
    pub(crate) health: Vec<HealthJson>,
    pub(crate) lines: Vec<LineJson>,
    pub(crate) measurements: Vec<MeasurementJson>,
    /// Samples dropped because the batch was full.
    pub(crate) overflow: u64,
}

/// `GET /api/devices/{device}`: its register map, commands and groups, from its spec.
#[derive(Debug, serde::Serialize)]
pub(crate) struct DeviceMap {
    pub(crate) device: String,
    pub(crate) model: String,
    pub(crate) title: &'static str,
    pub(crate) buffer: bool,
    pub(crate) registers: Vec<RegisterJson>,
    pub(crate) commands: Vec<CommandJson>,
    pub(crate) groups: Vec<GroupJson>,
}

/// One register of the map: where it is, its type, unit, range or codes, and the manual's
/// words.
#[derive(Debug, serde::Serialize)]
pub(crate) struct RegisterJson {
    pub(crate) name: &'static str,
    pub(crate) table: &'static str,
    pub(crate) address: u16,
    pub(crate) address_hex: String,
    pub(crate) words: u16,
    pub(crate) access: &'static str,
    pub(crate) writable: bool,
    #[serde(rename = "type")]
    pub(crate) kind: &'static str,
    pub(crate) unit: Option<&'static str>,
    pub(crate) range: String,
    pub(crate) codes: Vec<CodeJson>,
    pub(crate) section: &'static str,
    pub(crate) manual_name: &'static str,
    pub(crate) doc: &'static str,
}

/// One code of an enumerated register.
#[derive(Debug, serde::Serialize)]
pub(crate) struct CodeJson {
    pub(crate) code: u32,
    pub(crate) name: &'static str,
}

/// One command of the map.
#[derive(Debug, serde::Serialize)]
pub(crate) struct CommandJson {
    pub(crate) name: &'static str,
    pub(crate) doc: &'static str,
    pub(crate) drastic: bool,
    pub(crate) allowed: bool,
    pub(crate) busy_ms: u32,
}

/// One group of the map.
#[derive(Debug, serde::Serialize)]
pub(crate) struct GroupJson {
    pub(crate) name: &'static str,
    pub(crate) registers: &'static [&'static str],
}

/// A measurement's value as the page takes it (one of the bus's `measurements:`): its exact
/// text and a number for the chart, or why it has none; its judgement, skew and statistics as
/// the bus computed them.
#[derive(Clone, Debug, serde::Serialize)]
pub(crate) struct MeasurementJson {
    measurement: Arc<str>,
    /// Empty for a plain number.
    unit: Arc<str>,
    /// The exact value (`10.061630`); `null` when it has none.
    value: Option<String>,
    number: Option<f64>,
    /// Why it has no value.
    reason: Option<String>,
    /// `ll`, `lo`, `go`, `hi`, `hh`; `null` without limits or value.
    judgement: Option<&'static str>,
    skew_us: u64,
    stats: Option<StatsJson>,
    /// Milliseconds since 1970.
    time: f64,
}

impl MeasurementJson {
    pub(crate) fn new(event: &MeasurementEvent) -> Self {
        let (value, number, reason) = match &event.value {
            Ok(value) => (Some(value.to_string()), Some(value.to_f64()), None),
            Err(reason) => (None, None, Some(reason.clone())),
        };
        Self {
            measurement: Arc::clone(&event.measurement),
            unit: Arc::clone(&event.unit),
            value,
            number,
            reason,
            judgement: event.judgement.map(Judgement::name),
            skew_us: u64::try_from(event.skew.as_micros()).unwrap_or(u64::MAX),
            stats: event.stats.map(StatsJson::from),
            time: unix_ms(event.time),
        }
    }

    /// Its time and number, for a chart.
    pub(crate) fn point(&self) -> (f64, Option<f64>) {
        (self.time, self.number)
    }
}

/// A measurement's rolling statistics, in its unit, as the bus computed them.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub(crate) struct StatsJson {
    count: usize,
    mean: f64,
    /// `null` below two values.
    sd: Option<f64>,
    min: f64,
    max: f64,
    range: f64,
    /// `null` without both `lo` and `hi`, or without spread.
    cp: Option<f64>,
    cpk: Option<f64>,
}

impl From<Summary> for StatsJson {
    fn from(summary: Summary) -> Self {
        Self {
            count: summary.count,
            mean: summary.mean,
            sd: summary.sd,
            min: summary.min,
            max: summary.max,
            range: summary.range,
            cp: summary.cp,
            cpk: summary.cpk,
        }
    }
}

/// A measurement's limits, in its unit, each `null` where not given: what its chart draws.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub(crate) struct LimitsJson {
    ll: Option<f64>,
    lo: Option<f64>,
    hi: Option<f64>,
    hh: Option<f64>,
}

impl From<&Limits> for LimitsJson {
    fn from(limits: &Limits) -> Self {
        let number = |limit: Option<optobus_measure::Decimal>| limit.map(|l| l.to_f64());
        Self {
            ll: number(limits.ll),
            lo: number(limits.lo),
            hi: number(limits.hi),
            hh: number(limits.hh),
        }
    }
}

/// A measurement in `GET /api/measurements`: its limits, latest value, recent values (oldest
/// first, `[time, number or null]`) and judgement counts since start or reset.
#[derive(Debug, serde::Serialize)]
pub(crate) struct MeasurementState<'a> {
    pub(crate) measurement: &'a str,
    pub(crate) unit: &'a str,
    /// `null` for a measurement without limits.
    pub(crate) limits: Option<LimitsJson>,
    /// `null` before its first value.
    pub(crate) latest: Option<&'a MeasurementJson>,
    pub(crate) history: Vec<(f64, Option<f64>)>,
    /// `ll`, `lo`, `go`, `hi`, `hh`; `null` without limits.
    pub(crate) counts: Option<JudgementCounts>,
}

/// How often each judgement was given (OK is `go`, the rest NG).
#[derive(Debug, serde::Serialize)]
pub(crate) struct JudgementCounts {
    ll: u64,
    lo: u64,
    go: u64,
    hi: u64,
    hh: u64,
}

impl From<[u64; 5]> for JudgementCounts {
    fn from([ll, lo, go, hi, hh]: [u64; 5]) -> Self {
        Self { ll, lo, go, hi, hh }
    }
}

/// `GET /api/measurements`, in the order the bus computes them.
#[derive(Debug, serde::Serialize)]
pub(crate) struct Measurements<'a> {
    pub(crate) measurements: Vec<MeasurementState<'a>>,
}
