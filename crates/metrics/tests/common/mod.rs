//! What the metrics tests share: a running bus's file, requests to the listener, the series
//! in a body, a sample made by hand.

#![allow(dead_code, unused_imports, unreachable_pub)]

pub use std::collections::HashMap;
pub use std::path::Path;
pub use std::time::Duration;

pub use optobus_bus::{Bus, BusFile, Catalogue, Event};
pub use optobus_inspect::Value;
pub use optobus_metrics::{Exporter, Metrics, MetricsConfig, Reading, SourceError};
pub use tokio::io::{AsyncReadExt, AsyncWriteExt};
pub use tokio::sync::broadcast::error::RecvError;

pub const BUS: &str = "
lines:
  - { name: rs485, simulated: true, baud: 115200, any_format: true }
devices:
  - { name: top, model: p-series, slave: 1, timeout: 200ms, poll: [{ read: [light_power, laser_enabled, measurements, temperature], every: 20ms }] }
  - { name: confocal, model: ccs, slave: 3, timeout: 200ms, poll: [{ read: [measurements, exposure_time], every: 20ms }] }
outputs:
  metrics: 0
";

pub fn file() -> BusFile {
    with_metrics().0
}

/// The bus file [`BUS`] and its `metrics` output's settings.
pub fn with_metrics() -> (BusFile, MetricsConfig) {
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE, &optobus_ccs::DEVICE]);
    let mut metrics = None;
    let file = BusFile::parse_with("bus.yaml", BUS, Path::new("."), &catalogue, &mut metrics)
        .unwrap_or_else(|e| panic!("{}", e.render()));
    (file, metrics.expect("metrics are on"))
}

/// An exporter of `bus`'s events (a bus of [`file`]) on the `metrics` output's address.
pub async fn exporter(bus: &Bus) -> Exporter {
    let (file, config) = with_metrics();
    Exporter::start(&config, &file, bus.subscribe())
        .await
        .expect("listens")
}

/// An exporter of `bus`'s events (a bus of [`file`]) whose listener has the limits `limits`.
pub async fn exporter_with_limits(bus: &Bus, limits: optobus_http::Limits) -> Exporter {
    let (file, config) = with_metrics();
    Exporter::start_with_limits(&config, &file, bus.subscribe(), limits)
        .await
        .expect("listens")
}

/// `GET /metrics` with `accept`, as (head, body).
pub async fn scrape(address: std::net::SocketAddr, accept: &str) -> (String, String) {
    get_with(address, "/metrics", &format!("Accept: {accept}\r\n")).await
}

/// `GET path` on `address`: the status line and headers, and the body.
pub async fn get(address: std::net::SocketAddr, path: &str) -> (String, String) {
    get_with(address, path, "").await
}

/// `GET path` on `address` with the further header lines `headers` (each ending in CRLF):
/// the status line and headers, and the body.
pub async fn get_with(
    address: std::net::SocketAddr,
    path: &str,
    headers: &str,
) -> (String, String) {
    let mut stream = tokio::net::TcpStream::connect(address)
        .await
        .expect("connects");
    let request =
        format!("GET {path} HTTP/1.1\r\nHost: {address}\r\n{headers}Connection: close\r\n\r\n");
    stream.write_all(request.as_bytes()).await.unwrap();
    let mut reply = String::new();
    stream.read_to_string(&mut reply).await.unwrap();
    let (head, body) = reply.split_once("\r\n\r\n").expect("an HTTP reply");
    (head.to_owned(), body.to_owned())
}

/// The value of the series `name{labels}` in Prometheus text.
pub fn series(text: &str, name: &str, labels: &str) -> Option<f64> {
    let prefix = if labels.is_empty() {
        format!("{name} ")
    } else {
        format!("{name}{{{labels}}} ")
    };
    text.lines()
        .find_map(|line| line.strip_prefix(&prefix))
        .map(|value| value.parse().expect("a number"))
}

/// `promtool check metrics` accepts `text` (the tests calling it are ignored without promtool).
pub fn assert_promtool_accepts(text: &str) {
    optobus_testkit::assert_promtool_accepts(text);
}

// Short limits, so that the tests wait little; a read until the server closes.
pub use optobus_testkit::http::{short_limits as short, until_closed};

/// A sample of `register` of the P series `top`, decoded from `words` as the bus does.
pub fn p_series_sample(register: &str, words: &[u16]) -> Event {
    use std::sync::Arc;
    let register = optobus_p_series::DEVICE.register(register).unwrap();
    Event::Sample(Arc::new(optobus_bus::Sample {
        source: Arc::new(optobus_bus::DeviceId {
            device: "top".into(),
            model: optobus_p_series::DEVICE.model_name().to_string().into(),
            line: "rs485".into(),
            slave: 1,
        }),
        register,
        value: optobus_inspect::decode_value(register, words),
        requested: std::time::SystemTime::now(),
        replied: std::time::SystemTime::now(),
    }))
}
