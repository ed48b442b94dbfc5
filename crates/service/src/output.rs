//! The outputs of a run, behind one shape: each starts from a [`Start`] (the bus file, the
//! running bus, a subscription taken before the bus started) with its own settings, and
//! stops through [`Output::stop`], saying what a clean stop has to say.

use std::future::Future;
use std::path::Path;
use std::pin::Pin;
use std::sync::Arc;
use std::time::Duration;

use optobus_bus::{BusFile, Event, Follower, Running};
use optobus_console::HttpConfig;
use optobus_metrics::MetricsConfig;
use optobus_mqtt::MqttConfig;
use tokio::sync::{broadcast, oneshot};
use tokio::task::JoinHandle;

use crate::outlet::Outlet;
use crate::recording::{Recorded, Recorder};
use crate::{counted, Say, ServiceError};

/// What every output starts from.
pub struct Start<'a> {
    /// The bus file the bus runs.
    pub file: &'a BusFile,
    /// The running bus (its handle for writes, its console state).
    pub running: &'a Running,
    /// A subscription taken before the bus started: every event from the first.
    pub events: broadcast::Receiver<Event>,
    /// Where the output says what happens to it while it runs.
    pub say: Say,
}

/// The end of [`Output::stop`]: the output's failure, if it had one.
pub type Stopping = Pin<Box<dyn Future<Output = Result<(), ServiceError>>>>;

/// A started output. Each is started by an `async fn start(settings, Start) -> Result<Self,
/// ServiceError>` of its own type.
pub trait Output {
    /// Its part of the run's first note (`metrics on http://127.0.0.1:9100/metrics`).
    fn summary(&self) -> Option<String> {
        None
    }

    /// A note of its own at the start, said after the run's first (`the console is on …`).
    fn note(&self) -> Option<String> {
        None
    }

    /// Stops it, the bus having stopped: it takes what it still holds within its own limit,
    /// says on `say` what it dropped, and gives its failure.
    fn stop(self: Box<Self>, say: Say) -> Stopping;
}

/// How long a stop waits for the MQTT broker to take what is queued.
const MQTT_DRAIN: Duration = Duration::from_secs(2);

/// Samples the CSVs of a recording may fall behind by before their oldest are dropped.
const RECORD_SAMPLES: usize = 4096;

/// How long the end of a run waits for the CSVs to take what is still queued: a disk that
/// stalled for good must not hold the exit forever.
pub const DRAIN_AT_END: Duration = Duration::from_secs(2);

/// Prometheus metrics on `/metrics` ([`optobus_metrics::Exporter`]).
pub struct Metrics(optobus_metrics::Exporter);

impl Metrics {
    /// Listens on the settings' address and follows the bus.
    pub async fn start(config: &MetricsConfig, start: Start<'_>) -> Result<Self, ServiceError> {
        optobus_metrics::Exporter::start(config, start.file, start.events)
            .await
            .map(Self)
            .map_err(|e| ServiceError::new(format!("metrics on {}: {e}", config.listen)))
    }

    /// The exporter's metrics (to add series to).
    pub fn metrics(&self) -> &optobus_metrics::Metrics {
        self.0.metrics()
    }
}

impl Output for Metrics {
    fn summary(&self) -> Option<String> {
        Some(format!("metrics on http://{}/metrics", self.0.address()))
    }

    fn stop(self: Box<Self>, _: Say) -> Stopping {
        drop(self);
        Box::pin(async { Ok(()) })
    }
}

/// Samples published to an MQTT broker ([`optobus_mqtt::Publisher`]).
pub struct Mqtt {
    publisher: optobus_mqtt::Publisher,
    summary: String,
}

impl Mqtt {
    /// Starts publishing (connecting in the background), with writes from the write topics.
    pub async fn start(config: &MqttConfig, start: Start<'_>) -> Result<Self, ServiceError> {
        let publisher = optobus_mqtt::Publisher::start(
            config,
            start.file,
            start.events,
            Some(start.running.handle()),
        )
        .map_err(|e| ServiceError::new(e.to_string()))?;
        let summary = format!(
            "MQTT to {}:{}, topics {}/…{}",
            config.host,
            config.port,
            config.prefix,
            if config.homeassistant.is_some() {
                ", Home Assistant discovery"
            } else {
                ""
            }
        );
        Ok(Self { publisher, summary })
    }

    /// Reads the publisher's counts from elsewhere (the metrics' scrape).
    pub fn counts_reader(&self) -> optobus_mqtt::CountsReader {
        self.publisher.counts_reader()
    }
}

impl Output for Mqtt {
    fn summary(&self) -> Option<String> {
        Some(self.summary.clone())
    }

    fn stop(self: Box<Self>, say: Say) -> Stopping {
        Box::pin(async move {
            let counts = self.publisher.counts();
            if counts.dropped > 0 || !counts.connected {
                say(&format!(
                    "optobus: MQTT: {} published, {} dropped while the broker was away, {} still queued",
                    counted(counts.published, "sample"),
                    counts.dropped,
                    counts.queued
                ));
            }
            self.publisher.stop(MQTT_DRAIN).await;
            Ok(())
        })
    }
}

/// The console in the browser ([`optobus_console::Server`]).
pub struct Console(optobus_console::Server);

impl Console {
    /// Serves the console of the running bus.
    pub async fn start(config: &HttpConfig, start: Start<'_>) -> Result<Self, ServiceError> {
        optobus_console::serve(start.running, config)
            .await
            .map(Self)
            .map_err(|e| ServiceError::new(e.to_string()))
    }

    /// The page's address, for people.
    pub fn url(&self) -> String {
        self.0.url()
    }
}

impl Output for Console {
    fn note(&self) -> Option<String> {
        Some(format!("optobus: the console is on {}", self.url()))
    }

    fn stop(self: Box<Self>, _: Say) -> Stopping {
        drop(self);
        Box::pin(async { Ok(()) })
    }
}

/// A CSV per device and per measurement ([`Recorder`]), written on a thread of its own.
pub struct Record {
    stop: oneshot::Sender<()>,
    /// The follow's task: it gives the outlet back, and the events it missed.
    follow: JoinHandle<(RecorderOutlet, u64)>,
}

type RecorderOutlet = Outlet<Recorded, Recorder>;

impl Record {
    /// Creates the folder `dir` and a CSV per device in it, and follows the bus.
    pub async fn start(dir: &Path, start: Start<'_>) -> Result<Self, ServiceError> {
        let recorder = Recorder::create(dir, start.file, Arc::clone(&start.say))?;
        let outlet = Outlet::start("optobus-record", RECORD_SAMPLES, recorder);
        let (stop, stopped) = oneshot::channel::<()>();
        let say = start.say;
        let events = start.events;
        let follow = tokio::spawn(async move {
            let stopped = async {
                let _ = stopped.await;
            };
            let mut missed = 0;
            Follower::new(events, |count| missed += count)
                .until(stopped, |event| {
                    let item = match event {
                        Event::Sample(sample) => Recorded::Sample(sample),
                        Event::Measurement(value) => Recorded::Measurement(value),
                        _ => return,
                    };
                    if outlet.push(item).first_drop() {
                        say("optobus: --record is not keeping up: dropping its oldest samples");
                    }
                })
                .await;
            (outlet, missed)
        });
        Ok(Self { stop, follow })
    }
}

impl Output for Record {
    fn stop(self: Box<Self>, say: Say) -> Stopping {
        Box::pin(async move {
            let _ = self.stop.send(());
            let (outlet, missed) = self
                .follow
                .await
                .map_err(|e| ServiceError::new(format!("--record: {e}")))?;
            // The CSVs are waited for on a thread of the blocking pool: meanwhile the runtime
            // goes on closing the other listeners.
            let (dropped, recorder) = tokio::task::spawn_blocking(move || {
                (outlet.dropped(), outlet.finish(DRAIN_AT_END))
            })
            .await
            .map_err(|e| ServiceError::new(format!("the end of the run: {e}")))?;
            if missed > 0 {
                say(&format!(
                    "optobus: --record fell behind the bus and skipped {}",
                    counted(missed, "event")
                ));
            }
            if dropped > 0 {
                say(&format!(
                    "optobus: --record fell behind: its {dropped} oldest samples were dropped"
                ));
            }
            match recorder {
                Some(recorder) => recorder.finish(),
                None => Err(ServiceError::new(
                    "--record: the CSVs did not take their last rows in time",
                )),
            }
        })
    }
}
