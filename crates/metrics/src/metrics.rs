//! The registry and how each bus event changes it.

use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::AtomicU64;
use std::sync::{Arc, Mutex};
use std::time::UNIX_EPOCH;

use optobus_bus::{
    BusFile, DeviceId, ErrorCounts, Event, Health, LineStats, MeasurementEvent, Sample,
};
use optobus_inspect::{in_base_unit, Value};
use prometheus_client::encoding::text::encode;
use prometheus_client::encoding::EncodeLabelSet;
use prometheus_client::metrics::counter::Counter;
use prometheus_client::metrics::family::Family;
use prometheus_client::metrics::gauge::Gauge;
use prometheus_client::registry::Registry;

use crate::sources::{Source, SourceError, Sources, SourcesCollector};

type FloatGauge = Gauge<f64, AtomicU64>;

/// Readings by base unit (as [`in_base_unit`] names it), with their metric names.
const READINGS: [(&str, &str, &str); 7] = [
    ("m", "optobus_reading_meters", "A reading in metres."),
    ("s", "optobus_reading_seconds", "A reading in seconds."),
    (
        "degC",
        "optobus_reading_celsius",
        "A reading in degrees Celsius.",
    ),
    (
        "",
        "optobus_reading_ratio",
        "A reading given in percent, as a ratio (1 is 100 %).",
    ),
    ("V", "optobus_reading_volts", "A reading in volts."),
    ("A", "optobus_reading_amperes", "A reading in amperes."),
    ("Hz", "optobus_reading_hertz", "A reading in hertz."),
];

/// The bus file's measurements by base unit, in the order of [`READINGS`].
const MEASUREMENTS: [(&str, &str); 7] = [
    (
        "optobus_measurement_meters",
        "A measurement of the bus file in metres.",
    ),
    (
        "optobus_measurement_seconds",
        "A measurement of the bus file in seconds.",
    ),
    (
        "optobus_measurement_celsius",
        "A measurement of the bus file in degrees Celsius.",
    ),
    (
        "optobus_measurement_ratio",
        "A measurement of the bus file given in percent, as a ratio (1 is 100 %).",
    ),
    (
        "optobus_measurement_volts",
        "A measurement of the bus file in volts.",
    ),
    (
        "optobus_measurement_amperes",
        "A measurement of the bus file in amperes.",
    ),
    (
        "optobus_measurement_hertz",
        "A measurement of the bus file in hertz.",
    ),
];

#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
struct ReadingLabels {
    device: String,
    register: String,
    model: String,
}

/// An enumerated reading's labels: those of every reading and the code's name from the spec
/// (empty for a code the spec does not name).
#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
struct CodeLabels {
    device: String,
    register: String,
    model: String,
    name: String,
}

#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
struct MeasurementLabels {
    measurement: String,
}

#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
struct JudgementLabels {
    measurement: String,
    judgement: &'static str,
}

#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
struct DeviceLabels {
    device: String,
    model: String,
    line: String,
}

/// Which build serves the metrics: optobus's version, the Rust that compiled it and the target
/// it runs on.
#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
struct BuildLabels {
    version: &'static str,
    rust_version: &'static str,
    target: &'static str,
}

/// This build's labels (`rust_version` and `target` from the build script).
const BUILD: BuildLabels = BuildLabels {
    version: env!("CARGO_PKG_VERSION"),
    rust_version: env!("OPTOBUS_RUSTC_VERSION"),
    target: env!("OPTOBUS_TARGET"),
};

#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
struct LineLabels {
    line: String,
}

#[derive(Clone, Debug, Hash, PartialEq, Eq, EncodeLabelSet)]
struct LineErrorLabels {
    line: String,
    kind: &'static str,
}

/// The metrics of one bus, changed by its events and encoded for scrapes.
#[derive(Debug)]
pub struct Metrics {
    registry: Registry,
    /// One family per base unit, in the order of [`READINGS`].
    readings: Vec<Family<ReadingLabels, FloatGauge>>,
    /// Numbers without a unit (and units with no base unit known), booleans as 0 and 1.
    plain: Family<ReadingLabels, FloatGauge>,
    codes: Family<CodeLabels, Gauge>,
    /// The name label each code series has now, to remove it when the code changes.
    code_names: Mutex<HashMap<ReadingLabels, String>>,
    up: Family<DeviceLabels, Gauge>,
    last_sample: Family<DeviceLabels, FloatGauge>,
    transactions: Family<LineLabels, Counter>,
    errors: Family<LineErrorLabels, Counter>,
    busy: Family<LineLabels, Counter<f64, AtomicU64>>,
    open: Family<LineLabels, Gauge>,
    missed: Counter,
    /// Always 1: the labels say which build serves the metrics.
    build_info: Family<BuildLabels, Gauge>,
    /// The bus file's measurements, one family per base unit as [`READINGS`], and those
    /// without a unit.
    measurements: Vec<Family<MeasurementLabels, FloatGauge>>,
    plain_measurements: Family<MeasurementLabels, FloatGauge>,
    judgements: Family<JudgementLabels, Counter>,
    invalid: Family<MeasurementLabels, Counter>,
    /// The names of the families above.
    names: Vec<&'static str>,
    /// Series of other outputs, read at every scrape.
    sources: Arc<Sources>,
    /// The `register` labels of each device's reading series, to remove them all when the
    /// device goes down.
    shown: Mutex<HashMap<String, BTreeSet<String>>>,
}

impl Metrics {
    /// The metrics of the bus `file` runs: every device `up` 0 until its first sample.
    pub fn new(file: &BusFile) -> Self {
        let mut registry = Registry::default();
        // Every family's name, for the sources added later to keep clear of.
        let mut names = Vec::new();
        let mut readings = Vec::new();
        for (_, name, help) in READINGS {
            readings.push(registered(&mut registry, &mut names, name, help));
        }
        let mut measurements = Vec::new();
        for (name, help) in MEASUREMENTS {
            measurements.push(registered(&mut registry, &mut names, name, help));
        }
        let sources = Arc::new(Sources::default());
        registry.register_collector(Box::new(SourcesCollector(Arc::clone(&sources))));
        let metrics = Self {
            sources,
            readings,
            plain: registered(
                &mut registry,
                &mut names,
                "optobus_reading",
                "A reading without a unit (or in a unit with no base unit), a boolean as 0 or 1.",
            ),
            codes: registered(
                &mut registry,
                &mut names,
                "optobus_code",
                "An enumerated reading's code, with its name from the device's spec in the label name.",
            ),
            code_names: Mutex::default(),
            up: registered(
                &mut registry,
                &mut names,
                "optobus_device_up",
                "1 while the device answers its polls, 0 before its first sample and while offline.",
            ),
            last_sample: registered(
                &mut registry,
                &mut names,
                "optobus_device_last_sample_timestamp_seconds",
                "When the device's last good reply arrived, in seconds since the Unix epoch.",
            ),
            transactions: registered(
                &mut registry,
                &mut names,
                "optobus_line_transactions",
                "Requests sent on the line.",
            ),
            errors: registered(
                &mut registry,
                &mut names,
                "optobus_line_errors",
                "Failed transactions on the line, by kind: timeout, frame, exception, line.",
            ),
            busy: registered(
                &mut registry,
                &mut names,
                "optobus_line_busy_seconds",
                "Time the line spent in transactions (request out to reply in, or the timeout); \
                 its rate() is the share of time the line is busy.",
            ),
            open: registered(
                &mut registry,
                &mut names,
                "optobus_line_open",
                "1 while the line's port is open.",
            ),
            missed: registered(
                &mut registry,
                &mut names,
                "optobus_metrics_events_missed",
                "Bus events the exporter fell too far behind to see.",
            ),
            build_info: registered(
                &mut registry,
                &mut names,
                "optobus_build_info",
                "Always 1; its labels say which build of optobus serves these metrics.",
            ),
            measurements,
            plain_measurements: registered(
                &mut registry,
                &mut names,
                "optobus_measurement",
                "A measurement of the bus file without a unit (or in a unit with no base unit).",
            ),
            judgements: registered(
                &mut registry,
                &mut names,
                "optobus_measurement_judgements",
                "Values of a measurement judged against its limits, by judgement: ll, lo, go, hi, hh.",
            ),
            invalid: registered(
                &mut registry,
                &mut names,
                "optobus_measurement_invalid",
                "Values of a measurement that had none (an input without a value, inputs too far apart).",
            ),
            names,
            registry,
            shown: Mutex::default(),
        };
        metrics.build_info.get_or_create(&BUILD).set(1);
        for device in &file.devices {
            let line = &file.lines[device.line].name;
            metrics
                .up
                .get_or_create(&DeviceLabels {
                    device: device.name.clone(),
                    model: device.device.model_name().to_string(),
                    line: line.clone(),
                })
                .set(0);
        }
        metrics
    }

    /// Takes in one event of the bus.
    pub fn observe(&self, event: &Event) {
        match event {
            Event::Sample(sample) => self.sample(sample),
            Event::Health(health) => {
                let up = health.health == Health::Online;
                self.up
                    .get_or_create(&device_labels(&health.source))
                    .set(i64::from(up));
                if !up {
                    self.take_down(&health.source);
                }
            }
            Event::Line(stats) => self.line(stats),
            Event::Measurement(measurement) => self.measurement(measurement),
            // Writes are in the audit trail; the register's next sample shows its value.
            Event::Written(_) => {}
        }
    }

    /// Adds the series of `source` (another output's own counts), read at every scrape from
    /// then on. Its names are checked once, here: each a Prometheus metric name, none ending
    /// in `_total` (a counter gets it when exposed), none that the bus's metrics or another
    /// source already have. Later reads give the same names of the same types; a series
    /// that was not there when the source was added is left out of scrapes.
    pub fn add_source(&self, source: impl Source) -> Result<(), SourceError> {
        self.sources.add(Box::new(source), &self.names)
    }

    /// Counts events the exporter missed.
    pub fn missed(&self, events: u64) {
        self.missed.inc_by(events);
    }

    fn sample(&self, sample: &Sample) {
        let source = &sample.source;
        self.set(source, sample.register.name, &sample.value);
        self.up.get_or_create(&device_labels(source)).set(1);
        if let Ok(since) = sample.replied.duration_since(UNIX_EPOCH) {
            self.last_sample
                .get_or_create(&device_labels(source))
                .set(since.as_secs_f64());
        }
    }

    /// A measurement's value in its base unit, its judgement counted; an invalid one removes
    /// its series, so that no stale number stands for it, and is counted.
    fn measurement(&self, measurement: &MeasurementEvent) {
        let labels = MeasurementLabels {
            measurement: measurement.measurement.to_string(),
        };
        let families = self.measurements.iter().chain([&self.plain_measurements]);
        let value = match measurement.value {
            Ok(value) => value,
            Err(_) => {
                for family in families {
                    family.remove(&labels);
                }
                self.invalid.get_or_create(&labels).inc();
                return;
            }
        };
        match in_base_unit(value, &measurement.unit).and_then(|(number, base)| {
            Some((number, READINGS.iter().position(|(b, _, _)| *b == base)?))
        }) {
            Some((number, index)) => self.measurements[index].get_or_create(&labels).set(number),
            None => self
                .plain_measurements
                .get_or_create(&labels)
                .set(value.to_f64()),
        };
        if let Some(judgement) = measurement.judgement {
            self.judgements
                .get_or_create(&JudgementLabels {
                    measurement: labels.measurement.clone(),
                    judgement: judgement.name(),
                })
                .inc();
        }
    }

    /// Removes every reading series of a device that went down: a last value is not shown as
    /// a current one while `optobus_device_up` is 0. Its next sample brings them back.
    fn take_down(&self, source: &DeviceId) {
        let shown = self
            .shown
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(&*source.device)
            .unwrap_or_default();
        for register in shown {
            self.remove(&ReadingLabels {
                device: source.device.to_string(),
                register,
                model: source.model.to_string(),
            });
        }
    }

    /// Removes the series `labels` from every reading family.
    fn remove(&self, labels: &ReadingLabels) {
        for family in self.readings.iter().chain([&self.plain]) {
            family.remove(labels);
        }
        if let Some(name) = self
            .code_names
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(labels)
        {
            self.codes.remove(&code_labels(labels, name));
        }
    }

    /// Sets the series of `register` of `source` to `value` (fields as `register.field`); an
    /// invalid reading removes its series, so that no stale number stands for it.
    fn set(&self, source: &DeviceId, register: &str, value: &Value) {
        let labels = || ReadingLabels {
            device: source.device.to_string(),
            register: register.to_owned(),
            model: source.model.to_string(),
        };
        if !matches!(value, Value::Fields(_) | Value::Ipv4(_) | Value::Version(_)) {
            let mut shown = self.shown.lock().unwrap_or_else(|e| e.into_inner());
            let registers = shown.entry(source.device.to_string()).or_default();
            if !registers.contains(register) {
                registers.insert(register.to_owned());
            }
        }
        match value {
            Value::Quantity(number, unit) => {
                let converted = unit.and_then(|unit| in_base_unit(*number, unit));
                match converted.and_then(|(number, base)| {
                    let index = READINGS.iter().position(|(b, _, _)| *b == base)?;
                    Some((number, index))
                }) {
                    Some((number, index)) => {
                        self.readings[index].get_or_create(&labels()).set(number);
                    }
                    None => {
                        self.plain.get_or_create(&labels()).set(number.to_f64());
                    }
                }
            }
            Value::Integer(number) => {
                self.plain.get_or_create(&labels()).set(*number as f64);
            }
            Value::Bool(on) => {
                self.plain
                    .get_or_create(&labels())
                    .set(if *on { 1.0 } else { 0.0 });
            }
            Value::Code(code, name) => {
                let labels = labels();
                let name = name.unwrap_or_default().to_owned();
                let before = self
                    .code_names
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .insert(labels.clone(), name.clone());
                // One series per register: the one under the previous code's name goes.
                if let Some(before) = before.filter(|before| *before != name) {
                    self.codes.remove(&code_labels(&labels, before));
                }
                self.codes
                    .get_or_create(&code_labels(&labels, name))
                    .set(i64::from(*code));
            }
            Value::Fields(fields) => {
                for (name, value) in fields {
                    self.set(source, &format!("{register}.{name}"), value);
                }
            }
            Value::Invalid => self.remove(&labels()),
            // Addresses and versions are settings, not readings.
            Value::Ipv4(_) | Value::Version(_) => {}
        }
    }

    fn line(&self, stats: &LineStats) {
        let labels = LineLabels {
            line: stats.line.to_string(),
        };
        raise(
            &self.transactions.get_or_create(&labels),
            stats.transactions,
        );
        let ErrorCounts {
            timeouts,
            frames,
            exceptions,
            line,
        } = stats.errors;
        for (kind, count) in [
            ("timeout", timeouts),
            ("frame", frames),
            ("exception", exceptions),
            ("line", line),
        ] {
            let labels = LineErrorLabels {
                line: stats.line.to_string(),
                kind,
            };
            raise(&self.errors.get_or_create(&labels), count);
        }
        let busy = self.busy.get_or_create(&labels);
        let seconds = stats.busy.as_secs_f64();
        if seconds > busy.get() {
            busy.inc_by(seconds - busy.get());
        }
        self.open.get_or_create(&labels).set(i64::from(stats.open));
    }

    /// The metrics in OpenMetrics text.
    pub fn openmetrics(&self) -> String {
        let mut text = String::new();
        // Writing into a String cannot fail.
        let _ = encode(&mut text, &self.registry);
        text
    }

    /// The metrics in the Prometheus text format (0.0.4).
    pub fn prometheus(&self) -> String {
        crate::prometheus_text(&self.openmetrics())
    }
}

/// A metric registered under `name`, which joins `names`.
fn registered<M>(
    registry: &mut Registry,
    names: &mut Vec<&'static str>,
    name: &'static str,
    help: &str,
) -> M
where
    M: prometheus_client::registry::Metric + Clone + Default,
{
    let metric = M::default();
    // prometheus-client ends every help text with a period of its own: ours are sentences,
    // so theirs goes (else `# HELP x A reading..`).
    let help = help.strip_suffix('.').unwrap_or(help);
    registry.register(name, help, metric.clone());
    names.push(name);
    metric
}

/// Raises a counter to `total` (the bus counts; the counter follows).
fn raise(counter: &Counter, total: u64) {
    counter.inc_by(total.saturating_sub(counter.get()));
}

fn code_labels(labels: &ReadingLabels, name: String) -> CodeLabels {
    CodeLabels {
        device: labels.device.clone(),
        register: labels.register.clone(),
        model: labels.model.clone(),
        name,
    }
}

fn device_labels(source: &DeviceId) -> DeviceLabels {
    DeviceLabels {
        device: source.device.to_string(),
        model: source.model.to_string(),
        line: source.line.to_string(),
    }
}
