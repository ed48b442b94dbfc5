//! The bus file's measurements computed on the running bus: one task follows the bus's samples
//! and health, feeds each input's reading to `optobus_measure::Live`, and sends every value it
//! completes as an [`Event::Measurement`](crate::Event::Measurement).

use std::sync::Arc;
use std::time::SystemTime;

use optobus_codec::value::{Fixed, Scale};
use optobus_inspect::Value;
use optobus_measure::{Live, Outcome, Reading};
use tokio::sync::broadcast::{self, error::RecvError};

use crate::event::Event;
use crate::file::Measurements;
use crate::measurement::{InputValue, MeasurementEvent};
use crate::schedule::Health;

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
            // Each value's counts taken under the same lock: the counts after that value.
            let mut live = measuring.live();
            let outcomes = live.take(index, reading);
            let counts: Vec<_> = outcomes.iter().map(|o| live.counts(o.formula)).collect();
            drop(live);
            for (outcome, counts) in outcomes.into_iter().zip(counts) {
                let mut event =
                    measurement_event(outcome, &measuring.names, &units, &measuring.formulas);
                event.counts = counts;
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
        counts: None,
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
