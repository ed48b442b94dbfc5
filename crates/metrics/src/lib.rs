//! Prometheus metrics of a running optobus bus, served on `/metrics`.
//!
//! [`Metrics`] follows a bus's [`Event`]s: each reading in its base unit (metres, seconds,
//! degrees Celsius, ratios; the unit comes from the spec, converted by prefix) with `device`,
//! `register` and `model` labels, each device's `up` and the time of its last good sample,
//! and each line's transactions, errors by kind and busy time (a counter whose `rate()` is
//! the utilisation), and which build serves them. [`serve`] answers scrapes with them
//! (127.0.0.1 unless the bus file names another address).
//! [`Metrics::add_source`] adds series of other outputs, read at every scrape (`optobus run`
//! adds the MQTT publisher's queue and drops that way; this crate does not know MQTT).
//!
//! ```
//! use optobus_bus::{Bus, BusFile, Catalogue};
//!
//! # #[tokio::main(flavor = "current_thread")]
//! # async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
//! let text = "
//! lines: [{ name: rs485, simulated: true }]
//! devices: [{ name: top, model: p-series, slave: 1, poll: [{ read: measurements }] }]
//! outputs: { metrics: 0 }
//! ";
//! let mut metrics = None;
//! let file = BusFile::parse_with("demo.yaml", text, ".".as_ref(), &catalogue, &mut metrics)?;
//! let config: optobus_metrics::MetricsConfig = metrics.expect("metrics are on");
//! let bus = Bus::new(file.clone());
//! let exporter = optobus_metrics::Exporter::start(&config, &file, bus.subscribe()).await?;
//! let running = bus.start()?;
//! println!("scrape http://{}/metrics", exporter.address());
//! # running.stop();
//! # Ok(())
//! # }
//! ```
#![forbid(unsafe_code)]

mod exposition;
mod metrics;
mod serve;
pub mod settings;
mod sources;

pub use exposition::{prometheus_text, OPENMETRICS_TYPE, PROMETHEUS_TEXT_TYPE};
pub use metrics::Metrics;
pub use serve::{serve, Exporter, LIMITS};
pub use settings::MetricsConfig;
pub use sources::{Reading, ReadingValue, Source, SourceError};

pub use optobus_bus::Event;
