//! An unattended gateway under stalled consumers, hostile clients and a lost port: the
//! figures of issue 28, measured on the `optobus` binary as a plant runs it.
//!
//! 1. **Stalled consumers.** `optobus run --demo --json` with its gateway, console, /metrics
//!    and MQTT to a real mosquitto, in three phases of equal length: everything read (the
//!    anchor); stdout no longer read and three console streams opened and never read; the
//!    broker frozen as well (SIGSTOP). Each phase: a gateway client reading a register every
//!    20 ms (answered, wrong values against the value read at the start), /metrics and
//!    /api/status asked twice a second, the line's transactions counted on /metrics, and the
//!    samples a subscriber heard from the broker.
//! 2. **Gateway floods.** Seven clients sending 2-byte FC03 PDUs as fast as they are answered,
//!    then seven reading a unit that is not on the line (each read costs the line a timeout):
//!    the head's polls per second on stdout over its rate just before, and the process's
//!    resident memory.
//! 3. **Silent clients.** Eight gateway connections that never send: how long a ninth client
//!    waits for its first answer; an HTTP request left unfinished on the console's and on
//!    /metrics's port: how long until the server closes it.
//! 4. **A killed port.** A P series and a CCS on a line-timed pty served by `optobus simulate`
//!    in another process; the simulator killed: how long until /metrics shows both devices
//!    down.
//!
//! A missing peer (mosquitto) is named and its part left out. `OPTOBUS_BENCH_PHASE_SECS` sets
//! a phase's length (8 s by default). Run with `cargo bench -p optobus-cli --bench unattended`.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

fn phase() -> Duration {
    std::env::var("OPTOBUS_BENCH_PHASE_SECS")
        .ok()
        .and_then(|s| s.parse().ok())
        .map_or(Duration::from_secs(8), Duration::from_secs)
}

fn free_address() -> SocketAddr {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
}

/// Resident memory of process `pid` in MB.
fn rss_mb(pid: u32) -> f64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next()?.parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn installed(program: &str) -> bool {
    let found = Command::new(program)
        .arg("-h")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok();
    if !found {
        println!("  ({program} is not installed: its part is left out)");
    }
    found
}

/// The status line and body of `GET path`, if the server answers within `wait`.
fn http_get(address: SocketAddr, path: &str, wait: Duration) -> Option<(u16, String)> {
    let mut stream = TcpStream::connect_timeout(&address, wait).ok()?;
    stream.set_read_timeout(Some(wait)).ok()?;
    stream.set_write_timeout(Some(wait)).ok()?;
    write!(
        stream,
        "GET {path} HTTP/1.1\r\nHost: {address}\r\nConnection: close\r\n\r\n"
    )
    .ok()?;
    let mut text = String::new();
    stream.read_to_string(&mut text).ok()?;
    let status = text.split_whitespace().nth(1)?.parse().ok()?;
    Some((status, text))
}

/// Sums every series named `name` in a metrics exposition.
fn metric_sum(text: &str, name: &str) -> f64 {
    text.lines()
        .filter(|l| l.starts_with(name) && l[name.len()..].starts_with([' ', '{']))
        .filter_map(|l| l.rsplit(' ').next()?.parse::<f64>().ok())
        .sum()
}

/// One Modbus TCP read of holding registers: the reply's bytes after the MBAP header, or
/// `None` when no reply came within a second.
fn modbus_read(
    stream: &mut TcpStream,
    id: u16,
    unit: u8,
    address: u16,
    count: u16,
) -> Option<Vec<u8>> {
    let mut request = Vec::with_capacity(12);
    request.extend(id.to_be_bytes());
    request.extend([0, 0, 0, 6, unit, 3]);
    request.extend(address.to_be_bytes());
    request.extend(count.to_be_bytes());
    stream.write_all(&request).ok()?;
    reply(stream, id)
}

/// The PDU of the reply to transaction `id`.
fn reply(stream: &mut TcpStream, id: u16) -> Option<Vec<u8>> {
    let mut header = [0u8; 7];
    stream.read_exact(&mut header).ok()?;
    let len = usize::from(u16::from_be_bytes([header[4], header[5]]));
    let mut pdu = vec![0u8; len.checked_sub(1)?];
    stream.read_exact(&mut pdu).ok()?;
    (u16::from_be_bytes([header[0], header[1]]) == id).then_some(pdu)
}

fn connect(address: SocketAddr) -> Option<TcpStream> {
    let stream = TcpStream::connect_timeout(&address, Duration::from_secs(1)).ok()?;
    stream.set_read_timeout(Some(Duration::from_secs(1))).ok()?;
    stream.set_nodelay(true).ok()?;
    Some(stream)
}

/// A process killed when dropped.
struct Running(Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A mosquitto on a free port.
fn broker() -> (Running, SocketAddr) {
    let address = free_address();
    let config = std::env::temp_dir().join(format!("optobus-unattended-{}.conf", address.port()));
    std::fs::write(
        &config,
        format!(
            "listener {} 127.0.0.1\nallow_anonymous true\n",
            address.port()
        ),
    )
    .unwrap();
    let child = optobus_testkit::spawn_mosquitto(&config);
    let deadline = Instant::now() + Duration::from_secs(10);
    while TcpStream::connect(address).is_err() && Instant::now() < deadline {
        thread::sleep(Duration::from_millis(50));
    }
    (Running(child), address)
}

/// A subscriber to every topic under `optobus/`: the messages it heard.
fn subscriber(broker: SocketAddr) -> (Running, Arc<AtomicU64>) {
    let mut child = Command::new("mosquitto_sub")
        .args([
            "-h",
            "127.0.0.1",
            "-p",
            &broker.port().to_string(),
            "-t",
            "optobus/#",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("mosquitto_sub starts");
    let heard = Arc::new(AtomicU64::new(0));
    let count = Arc::clone(&heard);
    let out = child.stdout.take().unwrap();
    thread::spawn(move || {
        for _ in BufReader::new(out).lines() {
            count.fetch_add(1, Ordering::Relaxed);
        }
    });
    (Running(child), heard)
}

/// `optobus run --demo --json` with the given outputs; its stdout read by a thread while
/// `reading` holds, counting the head's polls (distinct reply times).
struct Gateway {
    process: Running,
    gateway: SocketAddr,
    http: SocketAddr,
    metrics: SocketAddr,
    reading: Arc<AtomicBool>,
    head_polls: Arc<AtomicU64>,
}

impl Gateway {
    fn start(mqtt: Option<SocketAddr>) -> Self {
        let (gateway, http, metrics) = (free_address(), free_address(), free_address());
        let mut command = Command::new(env!("CARGO_BIN_EXE_optobus"));
        command.args(["run", "--demo", "--json"]);
        command.args(["--gateway", &gateway.to_string()]);
        command.args(["--http", &http.to_string()]);
        command.args(["--prometheus", &metrics.to_string()]);
        if let Some(broker) = mqtt {
            command.args(["--mqtt", &broker.to_string()]);
        }
        let mut child = command
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("optobus starts");
        let reading = Arc::new(AtomicBool::new(true));
        let head_polls = Arc::new(AtomicU64::new(0));
        let (go_on, polls) = (Arc::clone(&reading), Arc::clone(&head_polls));
        let out = child.stdout.take().unwrap();
        thread::spawn(move || {
            let mut last = String::new();
            let mut lines = BufReader::new(out).lines();
            loop {
                while !go_on.load(Ordering::Relaxed) {
                    thread::sleep(Duration::from_millis(50));
                }
                let Some(Ok(line)) = lines.next() else { return };
                let Ok(sample) = serde_json::from_str::<serde_json::Value>(&line) else {
                    continue;
                };
                // A poll's samples share their reply time.
                if sample["device"] == "head" {
                    let time = sample["time"].to_string();
                    if time != last {
                        polls.fetch_add(1, Ordering::Relaxed);
                        last = time;
                    }
                }
            }
        });
        let deadline = Instant::now() + Duration::from_secs(20);
        while (connect(gateway).is_none()
            || http_get(metrics, "/metrics", Duration::from_secs(1)).is_none())
            && Instant::now() < deadline
        {
            thread::sleep(Duration::from_millis(100));
        }
        Self {
            process: Running(child),
            gateway,
            http,
            metrics,
            reading,
            head_polls,
        }
    }

    fn pid(&self) -> u32 {
        self.process.0.id()
    }

    fn transactions(&self) -> Option<f64> {
        let (_, text) = http_get(self.metrics, "/metrics", Duration::from_secs(2))?;
        Some(metric_sum(&text, "optobus_line_transactions_total"))
    }
}

/// What one phase of part 1 saw.
#[derive(Default)]
struct Seen {
    asked: u64,
    answered: u64,
    wrong: u64,
    metrics: (u64, u64),
    status: (u64, u64),
    transactions: Option<f64>,
    heard: u64,
}

/// Runs a gateway client reading every 20 ms and the HTTP askers for one phase.
fn watch_phase(gateway: &Gateway, expected: &[u8], heard: Option<&AtomicU64>) -> Seen {
    let light_power = optobus_p_series::DEVICE
        .register("light_power")
        .unwrap()
        .address;
    let before = gateway.transactions();
    let heard_before = heard.map_or(0, |h| h.load(Ordering::Relaxed));
    let end = Instant::now() + phase();
    let address = gateway.gateway;
    let expected = expected.to_vec();
    let client = thread::spawn(move || {
        let mut seen = Seen::default();
        let mut stream = None;
        let mut id = 0u16;
        while Instant::now() < end {
            id = id.wrapping_add(1);
            seen.asked += 1;
            if stream.is_none() {
                stream = connect(address);
            }
            match stream
                .as_mut()
                .and_then(|s| modbus_read(s, id, 1, light_power, 1))
            {
                Some(pdu) if pdu == expected => seen.answered += 1,
                Some(_) => {
                    seen.answered += 1;
                    seen.wrong += 1;
                }
                None => stream = None,
            }
            thread::sleep(Duration::from_millis(20));
        }
        seen
    });
    let (metrics, http) = (gateway.metrics, gateway.http);
    let askers = thread::spawn(move || {
        let (mut m, mut s) = ((0, 0), (0, 0));
        while Instant::now() < end {
            m.0 += 1;
            m.1 += u64::from(
                http_get(metrics, "/metrics", Duration::from_secs(2)).is_some_and(|r| r.0 == 200),
            );
            s.0 += 1;
            s.1 += u64::from(
                http_get(http, "/api/status", Duration::from_secs(2)).is_some_and(|r| r.0 == 200),
            );
            thread::sleep(Duration::from_millis(500));
        }
        (m, s)
    });
    let mut seen = client.join().unwrap();
    (seen.metrics, seen.status) = askers.join().unwrap();
    seen.transactions = match (before, gateway.transactions()) {
        (Some(a), Some(b)) => Some(b - a),
        _ => None,
    };
    seen.heard = heard.map_or(0, |h| h.load(Ordering::Relaxed)) - heard_before;
    seen
}

fn stalled_consumers() {
    let mosquitto = installed("mosquitto") && installed("mosquitto_sub");
    let (mut broker, address) = if mosquitto {
        let (broker, address) = broker();
        (Some(broker), Some(address))
    } else {
        (None, None)
    };
    let subscriber = address.map(subscriber);
    let gateway = Gateway::start(address);
    let light_power = optobus_p_series::DEVICE
        .register("light_power")
        .unwrap()
        .address;
    let expected = connect(gateway.gateway)
        .and_then(|mut s| modbus_read(&mut s, 1, 1, light_power, 1))
        .expect("the gateway answers");
    let heard = subscriber.as_ref().map(|(_, heard)| heard.as_ref());
    println!(
        "1. stalled consumers: optobus run --demo --json, gateway, console, /metrics{}; phases of {:.0} s  (load {})",
        if mosquitto { ", MQTT" } else { "" },
        phase().as_secs_f64(),
        optobus_testkit::load_average()
    );
    let mut streams = Vec::new();
    for name in [
        "everything read (anchor)",
        "stdout and 3 streams unread",
        "and the broker frozen",
    ] {
        match name {
            "stdout and 3 streams unread" => {
                gateway.reading.store(false, Ordering::Relaxed);
                for _ in 0..3 {
                    if let Ok(mut stream) = TcpStream::connect(gateway.http) {
                        let _ = write!(
                            stream,
                            "GET /api/stream HTTP/1.1\r\nHost: {}\r\n\r\n",
                            gateway.http
                        );
                        streams.push(stream);
                    }
                }
            }
            "and the broker frozen" => {
                if let Some(broker) = &broker {
                    let _ = Command::new("kill")
                        .args(["-STOP", &broker.0.id().to_string()])
                        .status();
                }
            }
            _ => {}
        }
        let seen = watch_phase(&gateway, &expected, heard);
        println!(
            "  {name:<28} gateway {:>4}/{:<4} answered ({:.3}), {} wrong; /metrics {}/{}, /api/status {}/{}; line transactions +{}; MQTT heard {}; RSS {:.0} MB",
            seen.answered,
            seen.asked,
            seen.answered as f64 / seen.asked.max(1) as f64,
            seen.wrong,
            seen.metrics.1,
            seen.metrics.0,
            seen.status.1,
            seen.status.0,
            seen.transactions.map_or("?".to_owned(), |t| format!("{t:.0}")),
            seen.heard,
            rss_mb(gateway.pid())
        );
    }
    if let Some(broker) = &mut broker {
        let _ = Command::new("kill")
            .args(["-CONT", &broker.0.id().to_string()])
            .status();
    }
}

/// Seven gateway clients sending `request(id)` as fast as they are answered: the head's polls
/// per second during the flood over its rate just before.
fn gateway_flood(what: &str, request: fn(u16) -> Vec<u8>) {
    let gateway = Gateway::start(None);
    thread::sleep(Duration::from_secs(2));
    let polls = || gateway.head_polls.load(Ordering::Relaxed);
    let (before, started) = (polls(), Instant::now());
    thread::sleep(phase());
    let alone = (polls() - before) as f64 / started.elapsed().as_secs_f64();
    let stop = Arc::new(AtomicBool::new(false));
    let answered = Arc::new(AtomicU64::new(0));
    let clients: Vec<_> = (0..7)
        .map(|_| {
            let (stop, answered) = (Arc::clone(&stop), Arc::clone(&answered));
            let address = gateway.gateway;
            thread::spawn(move || {
                let mut id = 0u16;
                while !stop.load(Ordering::Relaxed) {
                    let Some(mut stream) = connect(address) else {
                        thread::sleep(Duration::from_millis(10));
                        continue;
                    };
                    stream.set_read_timeout(Some(Duration::from_secs(30))).ok();
                    while !stop.load(Ordering::Relaxed) {
                        id = id.wrapping_add(1);
                        if stream.write_all(&request(id)).is_err()
                            || reply(&mut stream, id).is_none()
                        {
                            break;
                        }
                        answered.fetch_add(1, Ordering::Relaxed);
                    }
                }
            })
        })
        .collect();
    let (before, started) = (polls(), Instant::now());
    thread::sleep(phase());
    let flooded = (polls() - before) as f64 / started.elapsed().as_secs_f64();
    stop.store(true, Ordering::Relaxed);
    for client in clients {
        let _ = client.join();
    }
    println!(
        "  {what}: {} answered in {:.0} s; the head's polls {flooded:.2}/s against {alone:.2}/s before: ratio {:.3} (target ≥ 0.3, goal ≥ 0.9); RSS {:.0} MB  (load {})",
        answered.load(Ordering::Relaxed),
        phase().as_secs_f64(),
        flooded / alone,
        rss_mb(gateway.pid()),
        optobus_testkit::load_average()
    );
}

/// A Modbus TCP request of transaction `id`: unit, then the PDU.
fn request(id: u16, unit_and_pdu: &[u8]) -> Vec<u8> {
    let mut request = id.to_be_bytes().to_vec();
    let len = u16::try_from(unit_and_pdu.len()).unwrap_or(u16::MAX);
    request.extend([0, 0]);
    request.extend(len.to_be_bytes());
    request.extend(unit_and_pdu);
    request
}

fn gateway_floods() {
    println!("2. gateway floods, 7 clients each:");
    gateway_flood("2-byte FC03 PDUs to the head", |id| request(id, &[1, 3, 0]));
    gateway_flood("reads of unit 99, on the line but absent", |id| {
        request(id, &[99, 3, 0, 0, 0, 1])
    });
}

/// How long until `address` closes a connection that sent `sent` and nothing more (at most
/// `cap`).
fn closed_after(address: SocketAddr, sent: &[u8], cap: Duration) -> Option<Duration> {
    let mut stream = TcpStream::connect(address).ok()?;
    stream.write_all(sent).ok()?;
    let started = Instant::now();
    stream.set_read_timeout(Some(cap)).ok()?;
    let mut buf = [0u8; 1024];
    loop {
        match stream.read(&mut buf) {
            Ok(0) => return Some(started.elapsed()),
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => {
                return Some(started.elapsed())
            }
            // Still open when the cap ran out.
            Err(_) => return None,
        }
    }
}

fn silent_clients() {
    let gateway = Gateway::start(None);
    let silent: Vec<TcpStream> = (0..8)
        .filter_map(|_| TcpStream::connect(gateway.gateway).ok())
        .collect();
    thread::sleep(Duration::from_millis(200));
    let light_power = optobus_p_series::DEVICE
        .register("light_power")
        .unwrap()
        .address;
    let started = Instant::now();
    let cap = Duration::from_secs(60);
    let mut served = None;
    while started.elapsed() < cap {
        if let Some(mut stream) = connect(gateway.gateway) {
            if modbus_read(&mut stream, 1, 1, light_power, 1).is_some() {
                served = Some(started.elapsed());
                break;
            }
        }
        thread::sleep(Duration::from_millis(250));
    }
    let shown = |d: Option<Duration>| {
        d.map_or(format!("not within {} s", cap.as_secs()), |d| {
            format!("{:.2} s", d.as_secs_f64())
        })
    };
    println!(
        "3. silent clients: with {} silent gateway connections a new client is served after {} (target ≤ 15 s)  (load {})",
        silent.len(),
        shown(served),
        optobus_testkit::load_average()
    );
    let unfinished = b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n";
    let cap = Duration::from_secs(90);
    let shown = |d: Option<Duration>| {
        d.map_or(format!("open after {} s", cap.as_secs()), |d| {
            format!("closed after {:.2} s", d.as_secs_f64())
        })
    };
    println!(
        "   an unfinished HTTP request: console {}, /metrics {} (target ≤ 40 s)",
        shown(closed_after(gateway.http, unfinished, cap)),
        shown(closed_after(gateway.metrics, unfinished, cap))
    );
}

fn killed_port() {
    let folder = std::env::temp_dir().join(format!("optobus-unattended-{}", std::process::id()));
    std::fs::create_dir_all(&folder).unwrap();
    let simulated = folder.join("simulated.yaml");
    let devices = "devices:
  - { name: head, model: p-series, slave: 1, poll: [{ read: measurements, every: 100ms }] }
  - { name: confocal, model: ccs, slave: 2, poll: [{ read: measurements, every: 100ms }] }
";
    std::fs::write(
        &simulated,
        format!("lines: [{{ name: rs485, simulated: true, baud: 115200, any_format: true }}]\n{devices}"),
    )
    .unwrap();
    let mut simulator = Command::new(env!("CARGO_BIN_EXE_optobus"))
        .args(["simulate", "--bus"])
        .arg(&simulated)
        .args(["--pty", "--line-timing"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("optobus simulate starts");
    let mut path = String::new();
    BufReader::new(simulator.stdout.take().unwrap())
        .read_line(&mut path)
        .unwrap();
    let simulator = Running(simulator);
    let bus = folder.join("bus.yaml");
    std::fs::write(
        &bus,
        format!(
            "lines: [{{ name: rs485, serial: {}, baud: 115200, any_format: true }}]\n{devices}",
            path.trim()
        ),
    )
    .unwrap();
    let metrics = free_address();
    let run = Running(
        Command::new(env!("CARGO_BIN_EXE_optobus"))
            .arg("run")
            .arg(&bus)
            .args(["--json", "--prometheus", &metrics.to_string()])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("optobus run starts"),
    );
    let up = || {
        http_get(metrics, "/metrics", Duration::from_secs(2))
            .map(|(_, text)| metric_sum(&text, "optobus_device_up"))
    };
    let deadline = Instant::now() + Duration::from_secs(20);
    while up() != Some(2.0) && Instant::now() < deadline {
        thread::sleep(Duration::from_millis(100));
    }
    let readings_before =
        http_get(metrics, "/metrics", Duration::from_secs(2)).map_or(0, |(_, text)| {
            text.lines()
                .filter(|l| l.starts_with("optobus_reading_"))
                .count()
        });
    drop(simulator);
    let killed = Instant::now();
    let cap = Duration::from_secs(60);
    while up() != Some(0.0) && killed.elapsed() < cap {
        thread::sleep(Duration::from_millis(50));
    }
    let down = (up() == Some(0.0)).then(|| killed.elapsed());
    let readings_after =
        http_get(metrics, "/metrics", Duration::from_secs(2)).map_or(0, |(_, text)| {
            text.lines()
                .filter(|l| l.starts_with("optobus_reading_"))
                .count()
        });
    println!(
        "4. a killed port: both devices down on /metrics {} after the simulator was killed (target ≤ 10 s); reading series {readings_before} before, {readings_after} after  (load {})",
        down.map_or(format!("not within {} s", cap.as_secs()), |d| format!("{:.2} s", d.as_secs_f64())),
        optobus_testkit::load_average()
    );
    drop(run);
    let _ = std::fs::remove_dir_all(&folder);
}

fn main() {
    stalled_consumers();
    gateway_floods();
    silent_clients();
    killed_port();
}
