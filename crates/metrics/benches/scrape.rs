//! A `/metrics` scrape of a 20-device bus (every register of each device's `measurements`
//! group and its temperature, line statistics), over HTTP on 127.0.0.1, a new connection per
//! scrape as Prometheus's first scrape makes it; anchor: an axum endpoint of the same shape
//! serving a fixed body of the same size, scrapes interleaved. `cargo bench -p optobus-metrics`.

use std::net::SocketAddr;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime};

use axum::routing::get;
use axum::Router;
use optobus_bus::{BusFile, Catalogue, DeviceId, ErrorCounts, Event, LineStats, Sample};
use optobus_codec::value::{Fixed, Scale};
use optobus_inspect::Value;
use optobus_metrics::{serve, Metrics};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

const P: &optobus_device::DeviceInfo = &optobus_p_series::DEVICE;
const DEVICES: usize = 20;
const SCRAPES: usize = 2_000;

fn file() -> BusFile {
    let mut text = String::from(
        "lines: [{ name: a, simulated: true }, { name: b, simulated: true }]\ndevices:\n",
    );
    for n in 0..DEVICES {
        text += &format!(
            "  - {{ name: d{n}, model: p-series, line: {}, slave: {}, poll: [{{ read: [measurements, temperature] }}] }}\n",
            if n % 2 == 0 { "a" } else { "b" },
            n / 2 + 1
        );
    }
    BusFile::parse("bench.yaml", &text, Path::new("."), &Catalogue::new([P]))
        .unwrap_or_else(|e| panic!("{}", e.render()))
}

/// Metrics after a sample of every polled register of every device and a second of lines.
fn metrics(file: &BusFile) -> Metrics {
    let metrics = Metrics::new(file);
    let now = SystemTime::now();
    for device in &file.devices {
        let source = Arc::new(DeviceId {
            device: device.name.as_str().into(),
            model: P.model_name().to_string().into(),
            line: file.lines[device.line].name.as_str().into(),
            slave: device.slave,
        });
        for register in device.polls.iter().flat_map(|p| p.registers.iter()) {
            let value = match register.unit {
                Some(unit) => Value::Quantity(
                    Fixed::new(4_969_234, register.scale.unwrap_or(Scale::ONE)),
                    Some(unit),
                ),
                None => Value::Integer(42),
            };
            metrics.observe(&Event::Sample(Arc::new(Sample {
                source: Arc::clone(&source),
                register,
                value,
                requested: now,
                replied: now,
            })));
        }
    }
    for line in &file.lines {
        metrics.observe(&Event::Line(Arc::new(LineStats {
            line: line.name.as_str().into(),
            transactions: 12_345,
            errors: ErrorCounts::default(),
            busy: Duration::from_millis(600),
            elapsed: Duration::from_secs(1),
            open: true,
        })));
    }
    metrics
}

async fn scrape(address: SocketAddr) -> usize {
    let mut stream = tokio::net::TcpStream::connect(address).await.unwrap();
    stream
        .write_all(b"GET /metrics HTTP/1.1\r\nHost: bench\r\nConnection: close\r\n\r\n")
        .await
        .unwrap();
    let mut reply = Vec::new();
    stream.read_to_end(&mut reply).await.unwrap();
    assert!(reply.starts_with(b"HTTP/1.1 200"));
    reply.len()
}

fn quantiles(mut times: Vec<f64>) -> (f64, f64, f64) {
    times.sort_by(|a, b| a.total_cmp(b));
    let at = |q: f64| times[((times.len() - 1) as f64 * q) as usize];
    (at(0.5), at(0.99), at(1.0))
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() {
    println!("load average at start: {}", optobus_testkit::load_average());
    let file = file();
    let metrics = Arc::new(metrics(&file));
    let body = metrics.prometheus();
    let series = body.lines().filter(|l| !l.starts_with('#')).count();
    let ours = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let ours_address = ours.local_addr().unwrap();
    tokio::spawn(serve(ours, Arc::clone(&metrics)));
    let fixed = body.clone();
    let anchor = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let anchor_address = anchor.local_addr().unwrap();
    let router = Router::new().route("/metrics", get(move || std::future::ready(fixed.clone())));
    tokio::spawn(async move { axum::serve(anchor, router).await });
    let (mut ours_times, mut anchor_times) = (Vec::new(), Vec::new());
    let mut size = 0;
    for _ in 0..SCRAPES {
        let start = Instant::now();
        scrape(anchor_address).await;
        anchor_times.push(start.elapsed().as_secs_f64() * 1000.0);
        let start = Instant::now();
        size = scrape(ours_address).await;
        ours_times.push(start.elapsed().as_secs_f64() * 1000.0);
    }
    let (p50, p99, max) = quantiles(ours_times);
    let (a50, a99, amax) = quantiles(anchor_times);
    println!(
        "scrape of {DEVICES} devices ({series} series, {size} bytes), {SCRAPES} scrapes: \
             p50 {p50:.3} ms, p99 {p99:.3} ms, max {max:.3} ms; anchor (fixed body, same size): \
             p50 {a50:.3} ms, p99 {a99:.3} ms, max {amax:.3} ms; p99 ratio {:.2}",
        p99 / a99
    );
    println!("load average at end: {}", optobus_testkit::load_average());
}
