//! The bus file's measurements computed on the running bus: one task follows the bus's samples
//! and health, feeds each input's reading to `optobus_measure::Live`, and sends every value it
//! completes as an [`Event::Measurement`](crate::Event::Measurement).

use std::sync::Arc;
use std::time::{Duration, SystemTime};

use optobus_codec::value::{Fixed, Scale};
use optobus_inspect::Value;
use optobus_measure::{Judgement, Live, Outcome, Reading, Summary};
use serde::ser::{SerializeMap, SerializeStruct, Serializer};
use serde::Serialize;
use tokio::sync::broadcast::{self, error::RecvError};

use crate::event::{rfc3339, Event};
use crate::file::Measurements;
use crate::schedule::Health;

/// A measurement's value, or why it has none, with the inputs it was computed from.
#[derive(Clone, Debug)]
pub struct MeasurementEvent {
    /// Its name in the bus file.
    pub measurement: Arc<str>,
    /// Its unit (`mm`; empty for a plain number).
    pub unit: Arc<str>,
    /// Its value in its unit, or why it has none.
    pub value: Result<Fixed, String>,
    /// Each input as it was read.
    pub inputs: Vec<InputValue>,
    /// Between its first and its last input's request.
    pub skew: Duration,
    /// Against its limits, where it has limits and a value.
    pub judgement: Option<Judgement>,
    /// Its statistics after this value, where it keeps them.
    pub stats: Option<Summary>,
    /// When the value was computed.
    pub time: SystemTime,
}

/// One input of a measurement's value, as it was read.
#[derive(Clone, Debug)]
pub struct InputValue {
    /// `device.register`.
    pub name: Arc<str>,
    /// Its value; `None` when it has none.
    pub value: Option<Fixed>,
    /// Its unit (empty for a plain number).
    pub unit: Arc<str>,
    /// When its request left.
    pub requested: SystemTime,
    /// Why it has no value.
    pub reason: Option<String>,
}

/// A quantity as the drivers' JSON writes one: `{"value": "10.061630", "unit": "mm"}`.
struct Quantity<'a>(Fixed, &'a str);

impl Serialize for Quantity<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(2))?;
        map.serialize_entry("value", &self.0.to_string())?;
        map.serialize_entry("unit", self.1)?;
        map.end()
    }
}

/// A statistic (an `f64` estimate) as a quantity, to the measurement's resolution and three
/// digits more.
struct Estimate<'a>(f64, i8, &'a str);

impl Serialize for Estimate<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let Estimate(value, exponent, unit) = *self;
        let decimals = usize::try_from(-i32::from(exponent)).unwrap_or(0) + 3;
        let mut map = serializer.serialize_map(Some(2))?;
        map.serialize_entry("value", &format!("{value:.decimals$}"))?;
        map.serialize_entry("unit", unit)?;
        map.end()
    }
}

/// The JSON of a measurement's value, the contract of every output: `measurement`, `value`
/// (a quantity, or `null` with `reason`), `inputs` (by `device.register`: each a quantity or
/// `null`), `skew_us`, `judgement` (`ll`, `lo`, `go`, `hi`, `hh`, or `null`), `stats`
/// (`count`, `mean`, `sd`, `min`, `max`, `range` as quantities, `cp`, `cpk`), `time` (RFC
/// 3339).
impl Serialize for MeasurementEvent {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let unit = &*self.unit;
        let mut fields = serializer.serialize_struct("Measurement", 8)?;
        fields.serialize_field("measurement", &*self.measurement)?;
        match &self.value {
            Ok(value) => {
                fields.serialize_field("value", &Quantity(*value, unit))?;
                fields.skip_field("reason")?;
            }
            Err(reason) => {
                fields.serialize_field("value", &None::<()>)?;
                fields.serialize_field("reason", reason)?;
            }
        }
        fields.serialize_field("inputs", &Inputs(&self.inputs))?;
        let skew_us = u64::try_from(self.skew.as_micros()).unwrap_or(u64::MAX);
        fields.serialize_field("skew_us", &skew_us)?;
        fields.serialize_field("judgement", &self.judgement.map(Judgement::name))?;
        let exponent = match &self.value {
            Ok(value) => match value.scale() {
                Scale::Decimal { exponent } => exponent,
                Scale::Ratio { .. } => -6,
            },
            Err(_) => -6,
        };
        fields.serialize_field("stats", &self.stats.map(|s| Stats(s, exponent, unit)))?;
        fields.serialize_field("time", &rfc3339(self.time))?;
        fields.end()
    }
}

struct Inputs<'a>(&'a [InputValue]);

impl Serialize for Inputs<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(self.0.len()))?;
        for input in self.0 {
            let name = &*input.name;
            match input.value {
                Some(value) => map.serialize_entry(name, &Quantity(value, &input.unit))?,
                None => map.serialize_entry(name, &None::<()>)?,
            }
        }
        map.end()
    }
}

struct Stats<'a>(Summary, i8, &'a str);

impl Serialize for Stats<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let Stats(summary, exponent, unit) = *self;
        let quantity = |value: f64| Estimate(value, exponent, unit);
        let mut fields = serializer.serialize_struct("Stats", 8)?;
        fields.serialize_field("count", &summary.count)?;
        fields.serialize_field("mean", &quantity(summary.mean))?;
        fields.serialize_field("sd", &summary.sd.map(quantity))?;
        fields.serialize_field("min", &quantity(summary.min))?;
        fields.serialize_field("max", &quantity(summary.max))?;
        fields.serialize_field("range", &quantity(summary.range))?;
        fields.serialize_field("cp", &summary.cp)?;
        fields.serialize_field("cpk", &summary.cpk)?;
        fields.end()
    }
}

/// The live measurements of a running bus, shared by the task that computes them and the
/// [`Handle`](crate::Handle) that reads their counts and resets them.
#[derive(Debug)]
pub(crate) struct Measuring {
    live: std::sync::Mutex<Live>,
    /// Each formula's name and unit, in the plan's order.
    formulas: Vec<(Arc<str>, Arc<str>)>,
    /// Each input's name (`device.register`), in the plan's order.
    names: Vec<Arc<str>>,
}

impl Measuring {
    pub(crate) fn new(measurements: Measurements) -> Self {
        let names = measurements
            .plan
            .inputs
            .iter()
            .map(|input| Arc::from(input.to_string()))
            .collect();
        let formulas = measurements
            .plan
            .formulas
            .iter()
            .map(|f| (Arc::from(f.name.as_str()), Arc::from(f.unit.name.as_str())))
            .collect();
        Self {
            live: std::sync::Mutex::new(Live::new(measurements.plan, measurements.settings)),
            formulas,
            names,
        }
    }

    fn live(&self) -> std::sync::MutexGuard<'_, Live> {
        self.live.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The judgement counts of measurement `name` since start or the last reset (lowest
    /// first: ll, lo, go, hi, hh); `None` for a measurement without limits or not there.
    pub(crate) fn counts(&self, name: &str) -> Option<[u64; 5]> {
        let formula = self.formulas.iter().position(|(n, _)| &**n == name)?;
        self.live().counts(formula)
    }

    /// Every count back to zero and every statistics window emptied.
    pub(crate) fn reset(&self) {
        self.live().reset();
    }

    /// The measurements' names and units, in the order they are computed.
    pub(crate) fn names(&self) -> impl Iterator<Item = (&str, &str)> {
        self.formulas.iter().map(|(name, unit)| (&**name, &**unit))
    }
}

/// Follows `events` until the bus stops, computing the measurements and sending their values
/// on `sender`. A sample of an input is its reading; a device going offline makes a reading
/// without a value of each of its inputs ("top is offline").
pub(crate) async fn follow(
    measuring: Arc<Measuring>,
    mut events: broadcast::Receiver<Event>,
    sender: broadcast::Sender<Event>,
) {
    let inputs = measuring.live().plan().inputs.clone();
    let mut units: Vec<Arc<str>> = vec![Arc::from(""); inputs.len()];
    loop {
        let event = match events.recv().await {
            Ok(event) => event,
            // Missed samples are missed readings: the next ones complete the values.
            Err(RecvError::Lagged(_)) => continue,
            Err(RecvError::Closed) => return,
        };
        let readings: Vec<(usize, Reading)> = match &event {
            Event::Sample(sample) => inputs
                .iter()
                .enumerate()
                .filter(|(_, input)| {
                    *input.device == *sample.source.device && input.register == sample.register.name
                })
                .map(|(index, _)| {
                    units[index] = Arc::from(sample.register.unit.unwrap_or(""));
                    (index, reading(&sample.value, sample.requested))
                })
                .collect(),
            Event::Health(health) if health.health == Health::Offline => inputs
                .iter()
                .enumerate()
                .filter(|(_, input)| *input.device == *health.source.device)
                .map(|(index, _)| {
                    let reason = format!("{} is offline", health.source.device);
                    (index, without_value(SystemTime::now(), reason))
                })
                .collect(),
            _ => continue,
        };
        for (index, reading) in readings {
            let outcomes = measuring.live().take(index, reading);
            for outcome in outcomes {
                let event =
                    measurement_event(outcome, &measuring.names, &units, &measuring.formulas);
                // No receiver: nobody listens now, which is no error.
                let _ = sender.send(Event::Measurement(Arc::new(event)));
            }
        }
    }
}

fn measurement_event(
    outcome: Outcome,
    names: &[Arc<str>],
    units: &[Arc<str>],
    formulas: &[(Arc<str>, Arc<str>)],
) -> MeasurementEvent {
    let (measurement, unit) = formulas[outcome.formula].clone();
    MeasurementEvent {
        measurement,
        unit,
        value: outcome.value,
        inputs: outcome
            .inputs
            .into_iter()
            .map(|(index, reading)| InputValue {
                name: Arc::clone(&names[index]),
                value: reading.value,
                unit: Arc::clone(&units[index]),
                requested: reading.requested,
                reason: reading.reason,
            })
            .collect(),
        skew: outcome.skew,
        judgement: outcome.judgement,
        stats: outcome.stats,
        time: SystemTime::now(),
    }
}

/// A sample's value as a measurement's input reading.
fn reading(value: &Value, requested: SystemTime) -> Reading {
    let fixed = match value {
        Value::Quantity(fixed, _) => Some(*fixed),
        Value::Integer(n) => Some(Fixed::new(*n, Scale::ONE)),
        Value::Bool(b) => Some(Fixed::new(i64::from(*b), Scale::ONE)),
        Value::Code(code, _) => Some(Fixed::new(i64::from(*code), Scale::ONE)),
        _ => None,
    };
    match fixed {
        Some(fixed) => Reading {
            value: Some(fixed),
            requested,
            reason: None,
        },
        None => without_value(requested, "the device reads it as invalid".into()),
    }
}

fn without_value(requested: SystemTime, reason: String) -> Reading {
    Reading {
        value: None,
        requested,
        reason: Some(reason),
    }
}
