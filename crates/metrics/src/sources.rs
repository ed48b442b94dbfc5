//! Series from outside the bus's events, read at every scrape: another output's own counts
//! (the MQTT publisher's queue and drops), added by whoever runs both outputs, so that the
//! outputs need not know one another.

use std::sync::RwLock;

use prometheus_client::collector::Collector;
use prometheus_client::encoding::{DescriptorEncoder, EncodeMetric};
use prometheus_client::metrics::counter::ConstCounter;
use prometheus_client::metrics::gauge::ConstGauge;

/// The value of a [`Reading`], which also says its type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReadingValue {
    /// A total that only goes up; exposed as `<name>_total`.
    Counter(u64),
    /// A value that goes up and down (a queue's length, 0 or 1 for a state).
    Gauge(i64),
}

/// One series of a [`Source`] (no labels).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reading {
    /// The metric's name, in Prometheus's form (`optobus_mqtt_samples_dropped`); a counter's
    /// without `_total`, which the exposition adds.
    pub name: &'static str,
    /// What it counts, one line.
    pub help: &'static str,
    /// Its value now.
    pub value: ReadingValue,
}

impl Reading {
    /// A counter.
    pub fn counter(name: &'static str, help: &'static str, value: u64) -> Self {
        Self {
            name,
            help,
            value: ReadingValue::Counter(value),
        }
    }

    /// A gauge.
    pub fn gauge(name: &'static str, help: &'static str, value: i64) -> Self {
        Self {
            name,
            help,
            value: ReadingValue::Gauge(value),
        }
    }
}

/// Series read at every scrape, from one look at their source so that they agree with one
/// another. A source gives the same names of the same types every time; see
/// [`Metrics::add_source`](crate::Metrics::add_source).
pub trait Source: Send + Sync + 'static {
    /// The series now.
    fn read(&self) -> Vec<Reading>;
}

impl<F> Source for F
where
    F: Fn() -> Vec<Reading> + Send + Sync + 'static,
{
    fn read(&self) -> Vec<Reading> {
        self()
    }
}

/// Why a source was refused.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum SourceError {
    /// Not a Prometheus metric name (`[a-zA-Z_:][a-zA-Z0-9_:]*`, not starting with `__`).
    BadName(String),
    /// Ends in `_total`: counters get it in the exposition, gauges must not have it.
    Total(String),
    /// A help text of more than one line.
    BadHelp(String),
    /// A name the metrics or another source already have.
    Taken(String),
}

impl std::fmt::Display for SourceError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::BadName(name) => write!(f, "`{name}` is no Prometheus metric name"),
            Self::Total(name) => write!(
                f,
                "`{name}` ends in `_total`: a counter gets it when exposed, a gauge must not have it"
            ),
            Self::BadHelp(name) => write!(f, "the help of `{name}` is more than one line"),
            Self::Taken(name) => write!(f, "`{name}` is there already"),
        }
    }
}

impl std::error::Error for SourceError {}

/// A source and the series it declared when added: (name, whether a counter).
type Declared = (Box<dyn Source>, Vec<(&'static str, bool)>);

/// The sources added so far; encoded after the registry's own metrics at every scrape.
#[derive(Default)]
pub(crate) struct Sources {
    sources: RwLock<Vec<Declared>>,
}

impl std::fmt::Debug for Sources {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let sources = self.sources.read().unwrap_or_else(|p| p.into_inner());
        f.debug_list()
            .entries(sources.iter().map(|(_, names)| names))
            .finish()
    }
}

impl Sources {
    /// Adds `source` after checking its series' names against each other, against those of
    /// the other sources and against `taken`.
    pub(crate) fn add(&self, source: Box<dyn Source>, taken: &[&str]) -> Result<(), SourceError> {
        let mut sources = self.sources.write().unwrap_or_else(|p| p.into_inner());
        let mut declared: Vec<(&'static str, bool)> = Vec::new();
        for reading in source.read() {
            let name = reading.name;
            if !is_metric_name(name) {
                return Err(SourceError::BadName(name.to_owned()));
            }
            if name.ends_with("_total") {
                return Err(SourceError::Total(name.to_owned()));
            }
            if reading.help.contains(['\n', '\r']) {
                return Err(SourceError::BadHelp(name.to_owned()));
            }
            let clash = |other: &str| {
                other == name
                    || other.strip_suffix("_total") == Some(name)
                    || name.strip_suffix("_total") == Some(other)
            };
            let elsewhere = sources.iter().flat_map(|(_, names)| names.iter());
            if taken.iter().any(|t| clash(t))
                || declared.iter().chain(elsewhere).any(|(n, _)| clash(n))
            {
                return Err(SourceError::Taken(name.to_owned()));
            }
            declared.push((name, matches!(reading.value, ReadingValue::Counter(_))));
        }
        sources.push((source, declared));
        Ok(())
    }
}

/// Encodes the sources' series for the registry.
#[derive(Debug)]
pub(crate) struct SourcesCollector(pub(crate) std::sync::Arc<Sources>);

impl Collector for SourcesCollector {
    fn encode(&self, mut encoder: DescriptorEncoder) -> Result<(), std::fmt::Error> {
        let sources = self.0.sources.read().unwrap_or_else(|p| p.into_inner());
        for (source, declared) in sources.iter() {
            for reading in source.read() {
                // Only what was checked when the source was added, of the type it had then.
                let counter = matches!(reading.value, ReadingValue::Counter(_));
                if !declared.contains(&(reading.name, counter)) {
                    continue;
                }
                match reading.value {
                    ReadingValue::Counter(value) => {
                        describe(&mut encoder, &reading, &ConstCounter::new(value))?;
                    }
                    ReadingValue::Gauge(value) => {
                        describe(&mut encoder, &reading, &ConstGauge::new(value))?;
                    }
                }
            }
        }
        Ok(())
    }
}

fn is_metric_name(name: &str) -> bool {
    let mut chars = name.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_' || c == ':')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_' || c == ':')
        && !name.starts_with("__")
}

/// Encodes `metric`, the value of `reading`, under the reading's name and help.
fn describe(
    encoder: &mut DescriptorEncoder,
    reading: &Reading,
    metric: &impl EncodeMetric,
) -> Result<(), std::fmt::Error> {
    metric.encode(encoder.encode_descriptor(
        reading.name,
        reading.help,
        None,
        metric.metric_type(),
    )?)
}
