//! A measurement's value as the bus tells it: the event, and its JSON, the contract of every
//! output.

use std::sync::Arc;
use std::time::{Duration, SystemTime};

use optobus_codec::value::{Fixed, Scale};
use optobus_measure::{Judgement, Summary};
use serde::ser::{SerializeMap, SerializeStruct, Serializer};
use serde::Serialize;

use crate::time::rfc3339;

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
    /// Its judgement counts after this value (lowest first: ll, lo, go, hi, hh) since start
    /// or the last reset, where it has limits.
    pub counts: Option<[u64; 5]>,
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
/// (`count`, `mean`, `sd`, `min`, `max`, `range` as quantities, `cp`, `cpk`), `counts` (the
/// judgement counts by name, `{"ll": 0, "lo": 0, "go": 12, "hi": 1, "hh": 0}`, or `null`
/// without limits), `time` (RFC 3339).
impl Serialize for MeasurementEvent {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let unit = &*self.unit;
        let mut fields = serializer.serialize_struct("Measurement", 9)?;
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
        fields.serialize_field("counts", &self.counts.map(Counts))?;
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

/// Judgement counts by the judgements' names.
struct Counts([u64; 5]);

impl Serialize for Counts {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(5))?;
        for (judgement, count) in Judgement::ALL.iter().zip(self.0) {
            map.serialize_entry(judgement.name(), &count)?;
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
