//! The gateway: 4 Modbus TCP clients polling through a line's gateway while the bus keeps its
//! own schedule, on the byte-timed RS-485 emulator at 115200 baud 8N1 with 4 devices of
//! mixed families, each polling its measurements periodically.
//!
//! The clients, each reading one holding register of its own device that the bench pinned
//! to a value of its own: pymodbus (a Python script run as a subprocess), mbpoll (a
//! subprocess, its output parsed), our `TcpClient`, and a raw tokio socket. Third-party tools
//! that are missing are said so and left out. They connect through a relay in the bench that
//! timestamps each request and checks each reply on its way.
//!
//! Prints, for a first phase of the bus alone and a second with the clients:
//! - each client's reads, errors and wrong values (checked by the client, or its parsed
//!   output, against the pinned value; and by the relay) — target 0 wrong;
//! - what each request waited for: the transactions that started on the line between its
//!   arrival and its own (bus polls and other clients' requests, told apart by the device's
//!   own log of requests), and the wait against the longest bus transaction (target: at most
//!   one bus transaction before its own);
//! - the periodic polls' jitter as in the `jitter` bench, alone and with the clients;
//! - the anchor: the same registers read by a bare `RtuClient` on an equivalent emulated line
//!   in the same run (once the bus has stopped, not to take the CPU from it), its transaction
//!   times beside the gateway's round trips.
//!
//! Arrivals are stamped by the relay and line starts by the simulated devices, on one loaded
//! thread: a request counted behind more other clients' requests than there are other
//! clients was still on its way to the gateway's queue (in the TCP path), not waiting in it.
//!
//! It runs twice: with each client reading every 20 ms, as a PLC or SCADA polls, and with each
//! sending its next request the moment its reply arrives, which saturates the line.
//!
//! Run with `cargo bench -p optobus-bus --bench gateway`.

mod common;

use std::net::SocketAddr;
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime};

use common::{bus_file, emulated_line, ms, quantile};
use optobus_bus::{Bus, Event};
use optobus_codec::{LineFormat, ReadFunction, Request};
use optobus_device::DeviceInfo;
use optobus_simulator::Simulator;
use optobus_transport::{ReadRequest, RtuClient, RtuConfig, TcpClient, TcpConfig, Transport};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

const BAUD: u32 = 115_200;
const ALONE: Duration = Duration::from_secs(5);
const RUN: Duration = Duration::from_secs(10);
const PERIODS_MS: [u64; 4] = [50, 60, 80, 100];
const GROUP: &str = "measurements";

/// A device, the holding register its client reads, and the value pinned there.
struct Pinned {
    model: &'static DeviceInfo,
    register: &'static str,
    value: u16,
}

fn pinned() -> [Pinned; 4] {
    [
        (&optobus_p_series::DEVICE, "light_power", 425),
        (&optobus_ccs::DEVICE, "invalid_hold_count", 321),
        (&optobus_ccf::DEVICE, "invalid_hold_count", 123),
        (&optobus_rangefinder::DEVICE, "distance_offset", 77),
    ]
    .map(|(model, register, value)| Pinned {
        model,
        register,
        value,
    })
}

fn address(pinned: &Pinned) -> u16 {
    pinned.model.register(pinned.register).unwrap().address
}

/// A request the device at `slave` saw: when, and what.
#[derive(Clone, Copy)]
struct Seen {
    at: Instant,
    slave: u8,
    function: u8,
    address: u16,
}

/// The 4 simulators with their pinned values, logging what they see into `log`.
fn simulators(log: &Arc<Mutex<Vec<Seen>>>) -> Vec<Simulator> {
    pinned()
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let log = Arc::clone(log);
            let simulator = Simulator::new(p.model)
                .slave(i as u8 + 1)
                .sentinel_every(0)
                .observe(move |exchange| {
                    // Every device on the line sees every frame: log only those to it.
                    let Some(slave) = exchange.slave.filter(|&s| s == i as u8 + 1) else {
                        return;
                    };
                    if let Some(Request::Read { address, .. }) = exchange.request {
                        log.lock().unwrap().push(Seen {
                            at: Instant::now(),
                            slave,
                            function: exchange.function,
                            address: *address,
                        });
                    }
                });
            simulator.set(p.register, &[p.value]).unwrap();
            simulator
        })
        .collect()
}

/// One request that passed the relay.
#[derive(Clone, Copy)]
struct Passed {
    arrived: Instant,
    replied: Instant,
    unit: u8,
    function: u8,
    address: u16,
    /// The reply held the pinned value (false: an exception or another value).
    right: bool,
    exception: bool,
}

/// Passes each client's connection on to the gateway, one request at a time, noting when
/// each request came and its reply went back, and whether the reply held the pinned value.
async fn relay(listener: TcpListener, gateway: SocketAddr, log: Arc<Mutex<Vec<Passed>>>) {
    while let Ok((mut socket, _)) = listener.accept().await {
        let log = Arc::clone(&log);
        tokio::spawn(async move {
            let _ = socket.set_nodelay(true);
            let Ok(mut upstream) = TcpStream::connect(gateway).await else {
                return;
            };
            let _ = upstream.set_nodelay(true);
            let mut request = vec![0u8; 260];
            let mut reply = vec![0u8; 260];
            loop {
                if socket.read_exact(&mut request[..7]).await.is_err() {
                    return;
                }
                let arrived = Instant::now();
                let len = usize::from(u16::from_be_bytes([request[4], request[5]])) - 1;
                if socket.read_exact(&mut request[7..7 + len]).await.is_err() {
                    return;
                }
                if upstream.write_all(&request[..7 + len]).await.is_err()
                    || upstream.read_exact(&mut reply[..7]).await.is_err()
                {
                    return;
                }
                let back = usize::from(u16::from_be_bytes([reply[4], reply[5]])) - 1;
                if upstream.read_exact(&mut reply[7..7 + back]).await.is_err() {
                    return;
                }
                let replied = Instant::now();
                let unit = request[6];
                let expected = pinned()
                    .get(usize::from(unit).wrapping_sub(1))
                    .map(|p| p.value);
                let value = (back >= 4 && reply[7] == 0x03 && reply[8] == 2)
                    .then(|| u16::from_be_bytes([reply[9], reply[10]]));
                log.lock().unwrap().push(Passed {
                    arrived,
                    replied,
                    unit,
                    function: request[7],
                    address: u16::from_be_bytes([request[8], request[9]]),
                    right: value.is_some() && value == expected,
                    exception: reply[7] & 0x80 != 0,
                });
                if socket.write_all(&reply[..7 + back]).await.is_err() {
                    return;
                }
            }
        });
    }
}

/// What a client got.
#[derive(Debug, Default)]
struct Tally {
    name: String,
    reads: u64,
    errors: u64,
    wrong: u64,
    note: Option<String>,
}

impl Tally {
    /// A client's tally, before its first read.
    fn new(name: &str) -> Self {
        Self {
            name: name.to_owned(),
            ..Self::default()
        }
    }

    fn value(&mut self, value: Option<u16>, expected: u16) {
        self.reads += 1;
        match value {
            Some(v) if v == expected => {}
            Some(_) => self.wrong += 1,
            None => self.errors += 1,
        }
    }
}

fn missing(name: &str, why: String) -> Tally {
    Tally {
        note: Some(why),
        ..Tally::new(name)
    }
}

/// pymodbus, reading unit 1's pinned register for `RUN`.
fn pymodbus(port: u16, pace: Option<Duration>) -> Tally {
    let name = "pymodbus";
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/pymodbus_client.py");
    let p = &pinned()[0];
    let output = Command::new("python3")
        .args([script, "127.0.0.1", &port.to_string(), "1"])
        .arg(address(p).to_string())
        .args(["1", &RUN.as_secs_f64().to_string()])
        .arg(pace.unwrap_or_default().as_secs_f64().to_string())
        .stderr(Stdio::piped())
        .output();
    let output = match output {
        Ok(output) if output.status.success() => output,
        Ok(output) => {
            return missing(
                name,
                format!(
                    "not run: {}",
                    String::from_utf8_lossy(&output.stderr)
                        .lines()
                        .last()
                        .unwrap_or("")
                ),
            )
        }
        Err(error) => return missing(name, format!("not run: python3: {error}")),
    };
    let mut tally = Tally::new(name);
    for line in String::from_utf8_lossy(&output.stdout).lines() {
        if let Some(values) = line.strip_prefix("ok ") {
            tally.value(values.trim().parse().ok(), p.value);
        } else if line.starts_with("error") {
            tally.value(None, p.value);
            tally.note.get_or_insert_with(|| line.to_owned());
        }
    }
    tally
}

/// mbpoll, polling unit 2's pinned register until told to stop after `RUN`.
fn mbpoll(port: u16, pace: Option<Duration>) -> Tally {
    let name = "mbpoll";
    let p = &pinned()[1];
    let child = Command::new("stdbuf")
        .args([
            "-oL",
            "mbpoll",
            "-m",
            "tcp",
            "-p",
            &port.to_string(),
            "-a",
            "2",
        ])
        .args(["-r", &address(p).to_string(), "-c", "1", "-t", "4", "-0"])
        // mbpoll waits at least 10 ms between its polls.
        .args([
            "-l",
            &pace.map_or(10, |p| p.as_millis().max(10)).to_string(),
        ])
        .args(["-o", "2", "127.0.0.1"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn();
    let child = match child {
        Ok(child) if std::path::Path::new("/usr/bin/mbpoll").exists() || which("mbpoll") => child,
        Ok(mut child) => {
            let _ = child.kill();
            return missing(name, "not run: mbpoll is not installed".to_owned());
        }
        Err(error) => return missing(name, format!("not run: {error}")),
    };
    std::thread::sleep(RUN);
    // Ctrl-C, as a user stops it (it prints what it has and exits).
    let _ = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status();
    let output = child.wait_with_output().expect("mbpoll ends");
    let mut tally = Tally::new(name);
    let text = String::from_utf8_lossy(&output.stdout);
    for line in text.lines() {
        let line = line.trim();
        if let Some(rest) = line.strip_prefix(&format!("[{}]:", address(p))) {
            tally.value(rest.trim().parse().ok(), p.value);
        } else if !line.contains("frames transmitted")
            && (line.contains("failed") || line.contains("rror"))
        {
            tally.value(None, p.value);
            tally.note.get_or_insert_with(|| line.to_owned());
        }
    }
    if tally.reads == 0 {
        tally.note = Some(format!(
            "no reads parsed: {}",
            text.lines().take(3).collect::<Vec<_>>().join(" / ")
        ));
    }
    tally
}

fn which(tool: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {tool}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// A client's pace: a read every `pace` (late ticks skipped), or back to back.
fn pacer(pace: Option<Duration>) -> tokio::time::Interval {
    let mut tick = tokio::time::interval(pace.unwrap_or(Duration::from_nanos(1)));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    tick
}

/// Our `TcpClient`, reading unit 3's pinned register for `RUN`.
async fn our_client(address: SocketAddr, pace: Option<Duration>) -> Tally {
    let p = &pinned()[2];
    let mut tally = Tally::new("TcpClient");
    let mut client = match TcpClient::connect(address, TcpConfig::default()).await {
        Ok(client) => client,
        Err(error) => return missing("TcpClient", format!("cannot connect: {error}")),
    };
    let read = ReadRequest::new(ReadFunction::Holding, self::address(p), 1);
    let until = Instant::now() + RUN;
    let mut tick = pacer(pace);
    while Instant::now() < until {
        tick.tick().await;
        let value = client.read_words(3, read).await.ok().map(|w| w[0]);
        tally.value(value, p.value);
    }
    tally
}

/// A raw socket, reading unit 4's pinned register for `RUN`.
async fn raw_client(address: SocketAddr, pace: Option<Duration>) -> Tally {
    let p = &pinned()[3];
    let mut tally = Tally::new("raw socket");
    let Ok(mut socket) = TcpStream::connect(address).await else {
        return missing("raw socket", "cannot connect".to_owned());
    };
    let _ = socket.set_nodelay(true);
    let [high, low] = self::address(p).to_be_bytes();
    let until = Instant::now() + RUN;
    let mut transaction = 0u16;
    let mut tick = pacer(pace);
    while Instant::now() < until {
        tick.tick().await;
        transaction = transaction.wrapping_add(1);
        let [t1, t2] = transaction.to_be_bytes();
        let frame = [t1, t2, 0, 0, 0, 6, 4, 0x03, high, low, 0, 1];
        let mut reply = [0u8; 11];
        if socket.write_all(&frame).await.is_err()
            || socket.read_exact(&mut reply[..9]).await.is_err()
        {
            tally.value(None, p.value);
            break;
        }
        let value = if reply[7] == 0x03 && reply[8] == 2 {
            socket.read_exact(&mut reply[9..]).await.ok();
            (reply[..2] == [t1, t2]).then(|| u16::from_be_bytes([reply[9], reply[10]]))
        } else {
            None
        };
        tally.value(value, p.value);
    }
    tally
}

/// The anchor: a bare `RtuClient` reading the 4 pinned registers in turn on its own emulated
/// line for `RUN`: its transaction times (ms) and wrong values.
async fn direct_rtu() -> (Vec<f64>, u64, u64) {
    let log = Arc::new(Mutex::new(Vec::new()));
    let format = LineFormat::new(BAUD);
    let (stream, _line) = emulated_line(simulators(&log), format);
    let mut client = RtuClient::with_config(
        stream,
        RtuConfig {
            line: Some(format),
            timeout: Duration::from_millis(200),
            ..RtuConfig::default()
        },
    );
    let mut times = Vec::new();
    let mut wrong = 0;
    let mut errors = 0;
    let until = Instant::now() + RUN;
    'run: loop {
        for (i, p) in pinned().iter().enumerate() {
            if Instant::now() >= until {
                break 'run;
            }
            let started = Instant::now();
            let read = ReadRequest::new(ReadFunction::Holding, address(p), 1);
            match client.read_words(i as u8 + 1, read).await {
                Ok(words) if words == [p.value] => times.push(ms(started.elapsed())),
                Ok(_) => wrong += 1,
                Err(_) => errors += 1,
            }
        }
    }
    (times, wrong, errors)
}

/// Per poll: the p50 and p99 of its period jitter (ms), and the ticks it skipped (intervals of
/// 1.5 periods or more) between `from` and `to`.
fn jitter(
    requested: &[Vec<SystemTime>],
    from: SystemTime,
    to: SystemTime,
) -> Vec<(f64, f64, usize)> {
    requested
        .iter()
        .zip(PERIODS_MS)
        .map(|(times, period)| {
            let inside: Vec<&SystemTime> = times.iter().filter(|&&t| t >= from && t < to).collect();
            let intervals: Vec<f64> = inside
                .windows(2)
                .map(|pair| ms(pair[1].duration_since(*pair[0]).unwrap_or_default()))
                .collect();
            let jitter: Vec<f64> = intervals
                .iter()
                .map(|interval| (interval - period as f64).abs())
                .collect();
            let skipped = intervals
                .iter()
                .filter(|&&interval| interval >= 1.5 * period as f64)
                .count();
            (quantile(&jitter, 0.5), quantile(&jitter, 0.99), skipped)
        })
        .collect()
}

/// How often each client reads in the paced run: as a PLC or SCADA polls its sensors.
const PACED: Duration = Duration::from_millis(20);

fn main() {
    common::runtime().block_on(run(Some(PACED)));
    common::runtime().block_on(run(None));
}

/// One run: the clients reading every `pace`, or each sending its next request the moment its
/// reply arrives (saturating the line).
async fn run(pace: Option<Duration>) {
    match pace {
        Some(pace) => println!("clients polling every {} ms each:", pace.as_millis()),
        None => println!("clients sending each next request as soon as the reply arrives:"),
    }
    let format = LineFormat::new(BAUD);
    let line_log = Arc::new(Mutex::new(Vec::new()));
    let devices: Vec<String> = pinned()
        .iter()
        .zip(PERIODS_MS)
        .enumerate()
        .map(|(i, (p, every))| {
            format!(
                "{{ name: d{}, model: {}, slave: {}, timeout: 200ms, poll: [{{ read: {GROUP}, every: {every}ms }}] }}",
                i + 1,
                common::model_name(p.model),
                i + 1
            )
        })
        .collect();
    let (stream, line) = emulated_line(simulators(&line_log), format);
    let file = bus_file(
        &format!("serial: bench, baud: {BAUD}, gateway: {{ listen: 127.0.0.1:0, clients: 8 }}"),
        &devices,
    );
    let bus = Bus::new(file).with_stream("bench", stream);
    let mut events = bus.subscribe();
    let running = bus.start().expect("the gateway listens");
    let gateway = running.gateway_address("bench").unwrap();
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let relay_address = listener.local_addr().unwrap();
    let passed = Arc::new(Mutex::new(Vec::new()));
    tokio::spawn(relay(listener, gateway, Arc::clone(&passed)));

    let first: Vec<&str> = pinned()
        .iter()
        .map(|p| optobus_bus::file::resolve(p.model, GROUP).unwrap()[0].name)
        .collect();
    let mut requested = vec![Vec::new(); 4];
    let mut took = vec![Vec::new(); 4];
    let started = SystemTime::now();
    let clients_from = started + ALONE;
    let clients_to = clients_from + RUN;
    let mut clients: Option<std::thread::JoinHandle<_>> = None;
    let mut utilisation = 0.0;
    // The bus runs until every client is done.
    while clients.as_ref().is_none_or(|c| !c.is_finished()) {
        if clients.is_none() && SystemTime::now() >= clients_from {
            let port = relay_address.port();
            clients = Some(std::thread::spawn(move || {
                let python = std::thread::spawn(move || pymodbus(port, pace));
                let mbpoll = std::thread::spawn(move || mbpoll(port, pace));
                let ours = common::runtime().block_on(async {
                    tokio::join!(
                        our_client(relay_address, pace),
                        raw_client(relay_address, pace)
                    )
                });
                vec![
                    python.join().unwrap(),
                    mbpoll.join().unwrap(),
                    ours.0,
                    ours.1,
                ]
            }));
        }
        match tokio::time::timeout(Duration::from_millis(50), events.recv()).await {
            Ok(Ok(Event::Sample(sample))) => {
                let i = usize::from(sample.source.slave) - 1;
                if sample.register.name == first[i] {
                    requested[i].push(sample.requested);
                    took[i].push(ms(sample
                        .replied
                        .duration_since(sample.requested)
                        .unwrap_or_default()));
                }
            }
            Ok(Ok(Event::Line(stats))) => utilisation = stats.utilisation(),
            _ => {}
        }
    }
    let tallies = clients.unwrap().join().unwrap();
    drop(running);
    // The anchor, on its own line once the bus has stopped (not to share the CPU with it).
    let (direct_times, direct_wrong, direct_errors) = direct_rtu().await;

    println!(
        "{BAUD} baud 8N1, 4 devices polled every {PERIODS_MS:?} ms, {:.0} s alone then {:.0} s with 4 gateway clients: line utilisation {utilisation:.2} overall, {} gap violations  (load {})",
        ALONE.as_secs_f64(),
        RUN.as_secs_f64(),
        line.gap_violations(),
        common::load()
    );
    let mut wrong_total = 0;
    for tally in &tallies {
        wrong_total += tally.wrong;
        println!(
            "  client {:<10} {:>5} reads, {:>3} errors, {} wrong values{}",
            tally.name,
            tally.reads,
            tally.errors,
            tally.wrong,
            tally
                .note
                .as_deref()
                .map(|n| format!("  ({n})"))
                .unwrap_or_default()
        );
    }
    let passed = passed.lock().unwrap().clone();
    let relay_wrong = passed.iter().filter(|p| !p.right && !p.exception).count();
    let exceptions = passed.iter().filter(|p| p.exception).count();
    println!(
        "  relay: {} requests passed, {relay_wrong} replies with a wrong value, {exceptions} exceptions; clients' wrong values {wrong_total}",
        passed.len()
    );

    // What each request waited for on the line.
    let gap = format.frame_gap();
    let request_time = format.transmit_time(8) + gap;
    let line_log = line_log.lock().unwrap().clone();
    let clients_registers: Vec<(u8, u16)> = pinned()
        .iter()
        .enumerate()
        .map(|(i, p)| (i as u8 + 1, address(p)))
        .collect();
    let start_of = |seen: &Seen| seen.at - request_time;
    let mut polls_before = Vec::new();
    let mut others_before = Vec::new();
    let mut waits = Vec::new();
    let mut round_trips = Vec::new();
    let mut unmatched = 0;
    for request in &passed {
        round_trips.push(ms(request.replied - request.arrived));
        let own = line_log.iter().find(|s| {
            s.slave == request.unit
                && s.function == request.function
                && s.address == request.address
                && start_of(s) + Duration::from_micros(200) >= request.arrived
        });
        let Some(own) = own else {
            unmatched += 1;
            continue;
        };
        // Bus requests in a row to one device are one poll (a group may take several).
        let (mut polls, mut others, mut last_poll_slave) = (0, 0, None);
        for seen in &line_log {
            if start_of(seen) >= request.arrived && start_of(seen) < start_of(own) {
                if clients_registers.contains(&(seen.slave, seen.address)) && seen.function == 0x03
                {
                    others += 1;
                    last_poll_slave = None;
                } else if last_poll_slave != Some(seen.slave) {
                    polls += 1;
                    last_poll_slave = Some(seen.slave);
                }
            }
        }
        polls_before.push(polls as f64);
        others_before.push(others as f64);
        waits.push(ms(start_of(own).saturating_duration_since(request.arrived)));
    }
    let count_at_most = |values: &[f64], n: f64| values.iter().filter(|&&v| v <= n).count();
    let longest_poll = took.iter().flatten().copied().fold(0.0, f64::max);
    let typical_poll = took.iter().map(|t| quantile(t, 0.5)).fold(0.0, f64::max);
    println!(
        "  waits of {} requests ({unmatched} not matched to the line): bus polls started before its own: max {}  p99 {}  ≤ 1 for {:.2} %; other clients' requests before its own: max {}  p99 {}",
        waits.len(),
        quantile(&polls_before, 1.0),
        quantile(&polls_before, 0.99),
        100.0 * count_at_most(&polls_before, 1.0) as f64 / polls_before.len().max(1) as f64,
        quantile(&others_before, 1.0),
        quantile(&others_before, 0.99),
    );
    println!(
        "  wait from arrival to its own request: p50 {:.3} ms  p99 {:.3} ms  max {:.3} ms; longest bus transaction {longest_poll:.3} ms (the longest poll's median {typical_poll:.3} ms)",
        quantile(&waits, 0.5),
        quantile(&waits, 0.99),
        quantile(&waits, 1.0),
    );
    println!(
        "  round trip through relay and gateway: p50 {:.3} ms  p99 {:.3} ms; direct RtuClient on an equivalent line: {} reads, {direct_wrong} wrong, {direct_errors} errors, p50 {:.3} ms  p99 {:.3} ms: gateway / direct p50 {:.2}",
        quantile(&round_trips, 0.5),
        quantile(&round_trips, 0.99),
        direct_times.len(),
        quantile(&direct_times, 0.5),
        quantile(&direct_times, 0.99),
        quantile(&round_trips, 0.5) / quantile(&direct_times, 0.5),
    );
    println!(
        "  reads per second: {:.0} through the gateway (4 clients, beside the bus's polls), {:.0} by the bare RtuClient alone on its line: {:.2}",
        passed.len() as f64 / RUN.as_secs_f64(),
        direct_times.len() as f64 / RUN.as_secs_f64(),
        passed.len() as f64 / direct_times.len().max(1) as f64
    );
    let alone = jitter(
        &requested,
        started + Duration::from_millis(500),
        clients_from,
    );
    let with = jitter(&requested, clients_from, clients_to);
    for (i, ((a50, a99, a_skipped), (w50, w99, w_skipped))) in alone.iter().zip(&with).enumerate() {
        println!(
            "  poll d{} every {:>3} ms: jitter alone p50 {a50:.3} p99 {a99:.3} ms, {a_skipped} ticks skipped; with the clients p50 {w50:.3} p99 {w99:.3} ms, {w_skipped} ticks skipped (bound: longest transaction + 1 ms = {:.3} ms)",
            i + 1,
            PERIODS_MS[i],
            longest_poll + 1.0
        );
    }
}
