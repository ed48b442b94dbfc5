//! The `outputs` of a bus file: where a running bus sends what it reads, besides its events.
//! Plain settings, checked with the rest of the file; the crates that publish or serve read
//! them.

mod http;
mod metrics;
mod mqtt;

pub use http::{HttpConfig, DEFAULT_HTTP_PORT};
pub use metrics::MetricsConfig;
pub use mqtt::{
    MqttConfig, SecretSource, StateEvery, DEFAULT_MQTT_QUEUE, DEFAULT_REFRESH_EVERY,
    DEFAULT_STATE_EVERY,
};

use optobus_spec::source::{Node, Span};

use super::reader::Reader;

/// Where a running bus sends what it reads; nothing unless the file says so.
#[derive(Clone, Debug, Default, PartialEq)]
#[non_exhaustive]
pub struct Outputs {
    /// An MQTT broker to publish to (and take writes from).
    pub mqtt: Option<MqttConfig>,
    /// A Prometheus `/metrics` endpoint.
    pub metrics: Option<MetricsConfig>,
    /// The console in the browser (`http:`).
    pub http: Option<HttpConfig>,
}

pub(in crate::file) const OUTPUT_KEYS: &[&str] = &["mqtt", "metrics", "http"];

/// Every key `outputs` and its parts take, for the test that the schema shows each.
#[cfg(test)]
pub(in crate::file) const KEYS: [&[&str]; 3] = [OUTPUT_KEYS, mqtt::MQTT_KEYS, http::HTTP_KEYS];

impl Reader<'_> {
    /// `outputs:`; a problem is reported and leaves its output out.
    pub(in crate::file) fn outputs(&mut self, node: &Node, devices: &[(&str, Span)]) -> Outputs {
        let Some(pairs) = self.mapping(node, "`outputs`", OUTPUT_KEYS) else {
            return Outputs::default();
        };
        let get = |key: &str| pairs.iter().find(|(k, _)| k.scalar() == Some(key));
        Outputs {
            mqtt: get("mqtt").and_then(|(k, v)| self.mqtt(v, k.span, devices)),
            metrics: get("metrics").and_then(|(_, v)| self.metrics(v)),
            http: get("http").and_then(|(_, v)| self.http(v)),
        }
    }
}
