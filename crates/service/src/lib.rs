//! A bus of optobus sensors run with its outputs, started and stopped as one: the MQTT
//! publisher, the Prometheus exporter, the console in the browser and a CSV recording, each
//! an [`Output`] started from the same [`Start`], and the run's start and stop sequence
//! written once ([`Service`]). A front end (the `optobus` tool) starts a service and renders
//! what it says; it follows the bus's events itself for what it shows. It reads the bus file
//! whole ([`ServiceFile`]): the bus, and each output's settings, which the output's crate
//! reads from its section of `outputs`.
//!
//! It also holds what such a run is made of and nothing below it owns: the
//! [recording format](mod@recording) (writer and reader side by side), the [demo bus](mod@demo),
//! the MQTT publisher's counts as Prometheus series ([`mqtt_metrics`]), the bounded,
//! counted queue towards a slow writer ([`outlet`]), the lines a run tells its operator
//! ([`journal`]), and the run as a terminal shows it ([`terminal`]).
#![forbid(unsafe_code)]

pub mod demo;
mod file;
pub mod journal;
pub mod mqtt_metrics;
pub mod outlet;
mod output;
pub mod recording;
pub mod terminal;

use std::path::PathBuf;
use std::sync::Arc;

use optobus_bus::{Bus, Event, Running};
use tokio::sync::broadcast;

pub use file::{HttpConfig, MetricsConfig, MqttConfig, OutputsConfig, ServiceFile, SECTIONS};
pub use output::{Console, Metrics, Mqtt, Output, Record, Start, Stopping, DRAIN_AT_END};

/// Where a service says what happens (a line for people: `optobus: …`); the front end
/// decides where it goes (stderr, a log).
pub type Say = Arc<dyn Fn(&str) + Send + Sync>;

/// Why a service could not start, or an output failed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ServiceError(String);

impl ServiceError {
    /// An error saying `message`.
    pub fn new(message: impl Into<String>) -> Self {
        Self(message.into())
    }
}

impl std::fmt::Display for ServiceError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ServiceError {}

/// `1 event`, `2 events`: a count and a noun whose plural takes an `s`, as the service's
/// lines and its front end's say it.
pub fn counted(count: impl Into<Count>, noun: &str) -> String {
    let Count(count) = count.into();
    let plural = if count == 1 { "" } else { "s" };
    format!("{count} {noun}{plural}")
}

/// A count of things for [`counted`], from any unsigned integer.
#[derive(Clone, Copy, Debug)]
pub struct Count(u128);

macro_rules! count_from {
    ($($int:ty),*) => {$(
        impl From<$int> for Count {
            fn from(count: $int) -> Self {
                Self(count as u128)
            }
        }
    )*};
}

count_from!(u8, u16, u32, u64, usize);

/// What a service runs besides the bus file's own outputs.
#[derive(Clone, Default)]
pub struct Options {
    /// A CSV per device, and per measurement of the bus file, into this folder (the
    /// [recording format](mod@recording)).
    pub record: Option<PathBuf>,
}

/// A bus running with its outputs.
pub struct Service {
    running: Running,
    /// In the order they started; they stop in the same order, after the bus.
    outputs: Vec<Box<dyn Output>>,
    /// The run's first note's parts: each gateway, then each output that has a summary.
    summary: Vec<String>,
    console: Option<String>,
    /// The caller's subscription, taken before the bus started.
    events: Option<broadcast::Receiver<Event>>,
    say: Say,
}

impl Service {
    /// Starts the bus of `file`, then its outputs (the file's `outputs`, and `options`), each
    /// with a subscription taken before the bus started: the recording, the metrics, MQTT
    /// (the publisher's counts on the metrics when both run), then says the gateways and
    /// outputs on one line, starts the console and says where it is.
    pub async fn start(
        file: ServiceFile,
        options: Options,
        say: Say,
    ) -> Result<Self, ServiceError> {
        let ServiceFile {
            bus: file,
            outputs: settings,
        } = file;
        let bus = Bus::new(file.clone());
        let events = bus.subscribe();
        let record_events = options.record.as_ref().map(|_| bus.subscribe());
        let metrics_events = settings.metrics.as_ref().map(|_| bus.subscribe());
        let mqtt_events = settings.mqtt.as_ref().map(|_| bus.subscribe());
        let console_events = settings.http.as_ref().map(|_| bus.subscribe());
        let running = bus.start().map_err(|e| ServiceError::new(e.to_string()))?;
        let start = |events| Start {
            file: &file,
            running: &running,
            events,
            say: Arc::clone(&say),
        };
        let mut outputs: Vec<Box<dyn Output>> = Vec::new();
        if let (Some(dir), Some(events)) = (&options.record, record_events) {
            outputs.push(Box::new(Record::start(dir, start(events)).await?));
        }
        let metrics = match (&settings.metrics, metrics_events) {
            (Some(config), Some(events)) => Some(Metrics::start(config, start(events)).await?),
            _ => None,
        };
        let mqtt = match (&settings.mqtt, mqtt_events) {
            (Some(config), Some(events)) => Some(Mqtt::start(config, start(events)).await?),
            _ => None,
        };
        if let (Some(metrics), Some(mqtt)) = (&metrics, &mqtt) {
            mqtt_metrics::add(metrics.metrics(), mqtt.counts_reader())
                .map_err(|e| ServiceError::new(format!("metrics of MQTT: {e}")))?;
        }
        outputs.extend(metrics.map(|m| Box::new(m) as Box<dyn Output>));
        outputs.extend(mqtt.map(|m| Box::new(m) as Box<dyn Output>));
        let summary: Vec<String> = running
            .gateways()
            .map(|(line, address)| format!("gateway of {line} on {address}"))
            .chain(outputs.iter().filter_map(|output| output.summary()))
            .collect();
        if !summary.is_empty() {
            say(&format!("optobus: {}", summary.join(", ")));
        }
        let mut console = None;
        if let (Some(config), Some(events)) = (&settings.http, console_events) {
            let started = Console::start(config, start(events)).await?;
            console = Some(started.url());
            outputs.push(Box::new(started));
        }
        for output in &outputs {
            if let Some(note) = output.note() {
                say(&note);
            }
        }
        Ok(Self {
            running,
            outputs,
            summary,
            console,
            events: Some(events),
            say,
        })
    }

    /// The caller's subscription to the bus's events, taken before the bus started (every
    /// event from the first); `None` after the first call.
    pub fn events(&mut self) -> Option<broadcast::Receiver<Event>> {
        self.events.take()
    }

    /// The run's first note's parts: each gateway and where it listens, then each output's
    /// summary (`metrics on http://…/metrics`, `MQTT to …`).
    pub fn summary(&self) -> &[String] {
        &self.summary
    }

    /// The console's page, when it runs.
    pub fn console_url(&self) -> Option<&str> {
        self.console.as_deref()
    }

    /// The running bus.
    pub fn running(&self) -> &Running {
        &self.running
    }

    /// Stops the bus, then each output in the order they started, each taking what it still
    /// holds within its limit and saying what it dropped; gives the first output's failure.
    pub async fn stop(self) -> Result<(), ServiceError> {
        let Self {
            running,
            outputs,
            say,
            ..
        } = self;
        drop(running);
        let mut failed = Ok(());
        for output in outputs {
            let stopped = output.stop(Arc::clone(&say)).await;
            if failed.is_ok() {
                failed = stopped;
            }
        }
        failed
    }
}

#[cfg(test)]
mod tests {
    use super::counted;

    #[test]
    fn a_count_takes_the_plural_s_except_for_one_of_any_integer_width() {
        assert_eq!(counted(1u8, "line"), "1 line");
        assert_eq!(counted(0usize, "device"), "0 devices");
        assert_eq!(counted(u64::MAX, "event"), "18446744073709551615 events");
    }
}
