//! A bus file as a service runs it: the bus, and the settings of each output it names, each
//! read by the output's own crate from its section of `outputs` as the file is read, so that
//! every problem of the file, the bus's and the outputs', is in one located report.

use std::path::Path;

use optobus_bus::file::reading::Reader;
use optobus_bus::{BusFile, Catalogue, LoadError, OutputSettings, Outputs, ReadOutputs, Rejected};
pub use optobus_console::HttpConfig;
pub use optobus_metrics::MetricsConfig;
pub use optobus_mqtt::MqttConfig;

/// The sections `outputs` takes, in the order a message lists them.
pub const SECTIONS: [&str; 3] = [
    MqttConfig::SECTION,
    MetricsConfig::SECTION,
    HttpConfig::SECTION,
];

/// The settings of the outputs a bus file names; nothing unless the file says so.
#[derive(Clone, Debug, Default, PartialEq)]
#[non_exhaustive]
pub struct OutputsConfig {
    /// An MQTT broker to publish to (and take writes from).
    pub mqtt: Option<MqttConfig>,
    /// A Prometheus `/metrics` endpoint.
    pub metrics: Option<MetricsConfig>,
    /// The console in the browser (`http:`).
    pub http: Option<HttpConfig>,
}

/// Each output's section read by its crate, in the order of [`SECTIONS`].
impl ReadOutputs for OutputsConfig {
    fn sections(&self) -> &[&str] {
        &SECTIONS
    }

    fn read(&mut self, outputs: &Outputs<'_>, reader: &mut Reader<'_>) {
        self.mqtt = MqttConfig::read(outputs, reader);
        self.metrics = MetricsConfig::read(outputs, reader);
        self.http = HttpConfig::read(outputs, reader);
    }
}

/// A checked bus file with its outputs' settings.
#[derive(Clone, Debug)]
pub struct ServiceFile {
    /// The lines, devices and measurements: what the bus runs.
    pub bus: BusFile,
    /// Where the service sends what the bus reads.
    pub outputs: OutputsConfig,
}

impl ServiceFile {
    /// Reads and checks a bus file's text with its outputs, as [`BusFile::parse`] reads
    /// the rest.
    pub fn parse(
        name: &str,
        text: &str,
        base: &Path,
        catalogue: &Catalogue,
    ) -> Result<Self, Box<Rejected>> {
        let mut outputs = OutputsConfig::default();
        let bus = BusFile::parse_with(name, text, base, catalogue, &mut outputs)?;
        Ok(Self { bus, outputs })
    }

    /// Reads and checks the bus file at `path` with its outputs, as [`BusFile::load`] reads
    /// the rest.
    pub fn load(path: &Path, catalogue: &Catalogue) -> Result<Self, LoadError> {
        let mut outputs = OutputsConfig::default();
        let bus = BusFile::load_with(path, catalogue, &mut outputs)?;
        Ok(Self { bus, outputs })
    }
}

impl From<BusFile> for ServiceFile {
    /// A bus without outputs.
    fn from(bus: BusFile) -> Self {
        Self {
            bus,
            outputs: OutputsConfig::default(),
        }
    }
}
