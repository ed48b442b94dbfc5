//! The console's figures, each beside an anchor measured in the same run (the machine is
//! shared: the load average is printed):
//!
//! 1. `GET /api/values` with 20 devices polled as fast as their lines allow (4 lines at 115200
//!    baud, then at 4 Mbaud, where the bus itself keeps the cores busy): p50, p99 and max over
//!    sequential requests on one keep-alive connection, against `GET /api/status` (the same
//!    server, socket and framework, a trivial handler), requests interleaved.
//! 2. The live stream with 20 values sampled 50 times a second each, to one client reading it
//!    over a socket: samples received per second against the samples the bus sent (a
//!    subscriber counting them), the delay from a sample's reply to its arrival at the client
//!    (p50, p99, max) in the first and the last third of the run, batches dropped.
//! 3. The page's weight, and its first load in headless Chromium (navigation start to the
//!    first live value shown) against a reload of the same page (if chromedriver is here).
//! 4. A flood of line reads: 16 clients, each on its own keep-alive connection, reading a
//!    register through the console (`POST /api/devices/head/read`) as fast as they are
//!    answered, beside a device polled every 100 ms on a 115200 baud line: the polls' samples
//!    per second during the flood against their rate without it (anchor), trials of 2 s
//!    interleaved, reads answered and refused (`429`) per second.
//!
//! `cargo bench -p optobus-console --bench console [-- values|stream|page|flood]`;
//! `OPTOBUS_BENCH_SECS` sets the stream's run (default 15 s).

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use optobus_bus::{Bus, BusFile, Catalogue, Event, Running};
use optobus_console::HttpConfig;

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|text| text.split(' ').take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".into())
}

/// 20 P series heads on 4 simulated lines at `baud`, each polling `read` `every`.
fn twenty(baud: u32, read: &str, every: &str) -> BusFile {
    let mut text = String::from("lines:\n");
    for line in 0..4 {
        text +=
            &format!("  - {{ name: l{line}, simulated: true, baud: {baud}, any_format: true }}\n");
    }
    text += "devices:\n";
    for device in 0..20 {
        text += &format!(
            "  - {{ name: d{device}, model: p-series, line: l{}, slave: {}, timeout: 50ms, poll: [{{ read: {read}, every: {every} }}] }}\n",
            device % 4,
            device / 4 + 1
        );
    }
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
    BusFile::parse("bench.yaml", &text, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()))
}

/// One keep-alive HTTP/1.1 connection.
struct Connection {
    reader: BufReader<TcpStream>,
    host: String,
}

impl Connection {
    fn open(address: std::net::SocketAddr) -> Self {
        let stream = TcpStream::connect(address).unwrap();
        stream.set_nodelay(true).unwrap();
        Self {
            reader: BufReader::new(stream),
            host: address.to_string(),
        }
    }

    /// GETs `path`; its body's length.
    fn get(&mut self, path: &str) -> usize {
        write!(
            self.reader.get_mut(),
            "GET {path} HTTP/1.1\r\nHost: {}\r\n\r\n",
            self.host
        )
        .unwrap();
        let mut length = 0;
        let mut line = String::new();
        loop {
            line.clear();
            self.reader.read_line(&mut line).unwrap();
            if line == "\r\n" {
                break;
            }
            if let Some(value) = line.to_ascii_lowercase().strip_prefix("content-length:") {
                length = value.trim().parse().unwrap();
            }
        }
        let mut body = vec![0; length];
        self.reader.read_exact(&mut body).unwrap();
        length
    }
}

fn percentile(sorted: &[Duration], p: f64) -> Duration {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn show(name: &str, mut times: Vec<Duration>) -> Duration {
    times.sort();
    let p99 = percentile(&times, 0.99);
    println!(
        "  {name:<14} p50 {:>8.3} ms  p99 {:>8.3} ms  max {:>8.3} ms  ({} requests)",
        percentile(&times, 0.5).as_secs_f64() * 1e3,
        p99.as_secs_f64() * 1e3,
        times.last().unwrap().as_secs_f64() * 1e3,
        times.len()
    );
    p99
}

async fn latest_values(runtime: &tokio::runtime::Handle, baud: u32) {
    let running = Bus::new(twenty(baud, "measurements", "fastest"))
        .start()
        .unwrap();
    let server = optobus_console::serve(&running, &HttpConfig::new("127.0.0.1:0".parse().unwrap()))
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_secs(2)).await;
    let address = server.address();
    let (values, status, bytes) = runtime
        .spawn_blocking(move || {
            let mut connection = Connection::open(address);
            let (mut values, mut status) = (Vec::new(), Vec::new());
            let mut bytes = 0;
            for _ in 0..2000 {
                let started = Instant::now();
                bytes = connection.get("/api/values");
                values.push(started.elapsed());
                let started = Instant::now();
                connection.get("/api/status");
                status.push(started.elapsed());
            }
            (values, status, bytes)
        })
        .await
        .unwrap();
    let samples = running_samples(&running);
    println!(
        "1. latest values, 20 devices polled as fast as 4 lines at {baud} baud allow ({samples}):"
    );
    let p99 = show("/api/values", values);
    let anchor = show("/api/status", status);
    println!(
        "  /api/values is {bytes} bytes; its p99 is {:.2} × the anchor's, {:.3} ms against the 5 ms goal",
        p99.as_secs_f64() / anchor.as_secs_f64(),
        p99.as_secs_f64() * 1e3
    );
}

/// The samples a second the bus sends, counted for one second.
fn running_samples(running: &Running) -> String {
    let mut events = running.subscribe();
    let counted = std::thread::scope(|_| {
        let until = Instant::now() + Duration::from_secs(1);
        let mut count = 0u64;
        while Instant::now() < until {
            match events.try_recv() {
                Ok(Event::Sample(_)) => count += 1,
                Ok(_) => {}
                Err(_) => std::thread::sleep(Duration::from_millis(1)),
            }
        }
        count
    });
    format!("{counted} samples/s while measured")
}

fn now_ms() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
        * 1e3
}

async fn live_stream(runtime: &tokio::runtime::Handle, seconds: u64) {
    let running = Bus::new(twenty(4_000_000, "distance_1", "20ms"))
        .start()
        .unwrap();
    let mut events = running.subscribe();
    let server = optobus_console::serve(&running, &HttpConfig::new("127.0.0.1:0".parse().unwrap()))
        .await
        .unwrap();
    let address = server.address();
    let run = Duration::from_secs(seconds);
    let client = runtime.spawn_blocking(move || {
        let mut stream = TcpStream::connect(address).unwrap();
        write!(
            stream,
            "GET /api/stream HTTP/1.1\r\nHost: {address}\r\n\r\n"
        )
        .unwrap();
        stream
            .set_read_timeout(Some(Duration::from_millis(200)))
            .unwrap();
        let mut reader = BufReader::new(stream);
        let started = Instant::now();
        let mut delays: Vec<(f64, f64)> = Vec::new();
        let mut received = 0u64;
        let mut line = String::new();
        while started.elapsed() < run {
            line.clear();
            if reader.read_line(&mut line).is_err() {
                continue;
            }
            let Some(data) = line.trim_end().strip_prefix("data: ") else {
                continue;
            };
            let Ok(batch) = serde_json::from_str::<serde_json::Value>(data) else {
                continue;
            };
            let arrived = now_ms();
            let at = started.elapsed().as_secs_f64();
            for sample in batch["samples"].as_array().into_iter().flatten() {
                received += 1;
                delays.push((at, arrived - sample["time"].as_f64().unwrap_or(arrived)));
            }
        }
        (received, delays)
    });
    let counter = tokio::spawn(async move {
        let mut sent = 0u64;
        let until = tokio::time::Instant::now() + run;
        while let Ok(Ok(event)) = tokio::time::timeout_at(until, events.recv()).await {
            if matches!(event, Event::Sample(_)) {
                sent += 1;
            }
        }
        sent
    });
    let (received, delays) = client.await.unwrap();
    let sent = counter.await.unwrap();
    let secs = run.as_secs_f64();
    println!(
        "2. live stream, 20 values polled every 20 ms, one client over a socket, {seconds} s:"
    );
    println!(
        "  received {:.0} samples/s, the bus sent {:.0} samples/s (anchor): {:.3} of them",
        received as f64 / secs,
        sent as f64 / secs,
        received as f64 / sent.max(1) as f64
    );
    let third = secs / 3.0;
    for (name, range) in [
        ("first third", 0.0..third),
        ("last third", 2.0 * third..secs),
    ] {
        let mut part: Vec<f64> = delays
            .iter()
            .filter(|(at, _)| range.contains(at))
            .map(|(_, delay)| *delay)
            .collect();
        part.sort_by(f64::total_cmp);
        if part.is_empty() {
            continue;
        }
        let at = |p: f64| part[((part.len() - 1) as f64 * p).round() as usize];
        println!(
            "  delay reply → client, {name:<11}: p50 {:>6.1} ms  p99 {:>6.1} ms  max {:>6.1} ms",
            at(0.5),
            at(0.99),
            at(1.0)
        );
    }
    println!(
        "  batches dropped for the client: {}; batch every {} ms, queue {} batches",
        server.console().dropped_batches(),
        optobus_console::BATCH_EVERY.as_millis(),
        optobus_console::BATCH_QUEUE
    );
}

async fn page_load() {
    println!(
        "3. the page: {} bytes embedded (HTML, script, style)",
        optobus_console::PAGE_BYTES
    );
    let driver_here = std::process::Command::new("chromedriver")
        .arg("--version")
        .stdout(std::process::Stdio::null())
        .status()
        .is_ok();
    if !driver_here || !Path::new("/usr/bin/chromium").exists() {
        println!("  first load: skipped, chromium and chromedriver are not installed");
        return;
    }
    let running = Bus::new(twenty(115_200, "measurements", "50ms"))
        .start()
        .unwrap();
    let server = optobus_console::serve(&running, &HttpConfig::new("127.0.0.1:0".parse().unwrap()))
        .await
        .unwrap();
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let mut driver = std::process::Command::new("chromedriver")
        .arg(format!("--port={port}"))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let mut capabilities = fantoccini::wd::Capabilities::new();
    capabilities.insert("browserName".into(), serde_json::json!("chrome"));
    capabilities.insert(
        "goog:chromeOptions".into(),
        serde_json::json!({"binary": "/usr/bin/chromium", "args": ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"]}),
    );
    let connector = hyper_util::client::legacy::connect::HttpConnector::new();
    let mut client = None;
    for _ in 0..100 {
        if let Ok(c) = fantoccini::ClientBuilder::new(connector.clone())
            .capabilities(capabilities.clone())
            .connect(&format!("http://127.0.0.1:{port}"))
            .await
        {
            client = Some(c);
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let client = client.expect("a chromedriver session");
    // Navigation start to the page loaded, and to the first live value on screen (polled
    // every 2 ms in the page).
    let script = "const done = arguments[arguments.length - 1]; \
                  const look = () => { const v = document.querySelector('[data-value]'); \
                    if (v && v.textContent) { \
                      const t = performance.getEntriesByType('navigation')[0]; \
                      done([t.loadEventEnd, performance.now()]); \
                    } else { setTimeout(look, 2); } }; look();";
    let measure = |first: bool| {
        let client = client.clone();
        let url = server.url();
        async move {
            if first {
                client.goto(&url).await.unwrap();
            } else {
                client.refresh().await.unwrap();
            }
            let timing = client.execute_async(script, vec![]).await.unwrap();
            (
                timing[0].as_f64().unwrap_or(0.0),
                timing[1].as_f64().unwrap_or(0.0),
            )
        }
    };
    let (load, shown) = measure(true).await;
    let (reload, reshown) = measure(false).await;
    println!(
        "  first load {load:.1} ms, first live value shown by {shown:.1} ms; reload (anchor) {reload:.1} ms, {reshown:.1} ms"
    );
    let _ = client.close().await;
    let _ = driver.kill();
    let _ = driver.wait();
}

/// One client of the flood: POSTs reads on one keep-alive connection until `stop`; (answered,
/// refused as busy).
fn flood_client(address: std::net::SocketAddr, stop: &std::sync::atomic::AtomicBool) -> (u64, u64) {
    let body = r#"{"register": "distance_1"}"#;
    let request = format!(
        "POST /api/devices/head/read HTTP/1.1\r\nHost: {address}\r\ncontent-type: application/json\r\ncontent-length: {}\r\n\r\n{body}",
        body.len()
    );
    let mut connection = Connection::open(address);
    let (mut answered, mut refused) = (0, 0);
    let mut line = String::new();
    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
        connection
            .reader
            .get_mut()
            .write_all(request.as_bytes())
            .unwrap();
        let mut status = 0;
        let mut length = 0;
        loop {
            line.clear();
            connection.reader.read_line(&mut line).unwrap();
            if line == "\r\n" {
                break;
            }
            if let Some(code) = line.strip_prefix("HTTP/1.1 ") {
                status = code[..3].parse().unwrap_or(0);
            }
            if let Some(value) = line.to_ascii_lowercase().strip_prefix("content-length:") {
                length = value.trim().parse().unwrap();
            }
        }
        let mut reply = vec![0; length];
        connection.reader.read_exact(&mut reply).unwrap();
        match status {
            200 => answered += 1,
            429 => refused += 1,
            other => panic!(
                "a read answered {other}: {}",
                String::from_utf8_lossy(&reply)
            ),
        }
    }
    (answered, refused)
}

async fn read_flood(runtime: &tokio::runtime::Handle) {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    let text = "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 100ms, poll: [{ read: distance_1, every: 100ms }] }
";
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
    let file = BusFile::parse("flood.yaml", text, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()));
    let running = Bus::new(file).start().unwrap();
    let server = optobus_console::serve(&running, &HttpConfig::new("127.0.0.1:0".parse().unwrap()))
        .await
        .unwrap();
    let address = server.address();
    let trial = Duration::from_secs(2);
    let (mut quiet, mut flooded) = (Vec::new(), Vec::new());
    let (mut answered, mut refused) = (0u64, 0u64);
    tokio::time::sleep(Duration::from_secs(1)).await;
    for _ in 0..5 {
        for flood in [false, true] {
            let stop = Arc::new(AtomicBool::new(false));
            let clients: Vec<_> = (0..if flood { 16 } else { 0 })
                .map(|_| {
                    let stop = Arc::clone(&stop);
                    runtime.spawn_blocking(move || flood_client(address, &stop))
                })
                .collect();
            let mut events = running.subscribe();
            let until = tokio::time::Instant::now() + trial;
            let mut samples = 0u64;
            while let Ok(Ok(event)) = tokio::time::timeout_at(until, events.recv()).await {
                if matches!(event, Event::Sample(_)) {
                    samples += 1;
                }
            }
            stop.store(true, Ordering::Relaxed);
            for client in clients {
                let (a, r) = client.await.unwrap();
                answered += a;
                refused += r;
            }
            let rate = samples as f64 / trial.as_secs_f64();
            if flood {
                flooded.push(rate)
            } else {
                quiet.push(rate)
            }
        }
    }
    let mean = |rates: &[f64]| rates.iter().sum::<f64>() / rates.len() as f64;
    let flood_secs = 5.0 * trial.as_secs_f64();
    println!("4. 16 clients reading through the console as fast as they are answered, 5 × 2 s interleaved:");
    println!(
        "  poll samples/s without the flood (anchor) {:.1}, during it {:.1}: {:.2} of the rate (issue: ≥ 0.30, goal ≥ 0.90); trials {quiet:?} / {flooded:?}",
        mean(&quiet),
        mean(&flooded),
        mean(&flooded) / mean(&quiet)
    );
    println!(
        "  reads answered {:.1}/s, refused 429 {:.1}/s; the console counted {} busy refusals",
        answered as f64 / flood_secs,
        refused as f64 / flood_secs,
        running.handle().busy_refusals(optobus_bus::Source::Console)
    );
}

fn main() {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let seconds = std::env::var("OPTOBUS_BENCH_SECS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(15);
    println!("optobus-console bench; load average {}", load_average());
    let handle = runtime.handle().clone();
    // `cargo bench -p optobus-console --bench console -- flood` runs one part (values, stream,
    // page, flood).
    let only: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let runs = |part: &str| only.is_empty() || only.iter().any(|o| o == part);
    runtime.block_on(async {
        if runs("values") {
            latest_values(&handle, 115_200).await;
            latest_values(&handle, 4_000_000).await;
        }
        if runs("stream") {
            live_stream(&handle, seconds).await;
        }
        if runs("page") {
            page_load().await;
        }
        if runs("flood") {
            read_flood(&handle).await;
        }
    });
    println!("load average afterwards {}", load_average());
}
