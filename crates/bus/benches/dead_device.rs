//! One dead device among 8 (each device's timeout 100 ms), on the byte-timed RS-485 emulator
//! at 115200 baud 8N1, every device polling its measurements as fast as the line allows.
//!
//! 1. The other seven's rates: trials alternate a bus file of the seven alone (the anchor)
//!    and the file of all eight with the eighth silent from the start; each trial counts the
//!    seven's polls over its whole run, the dead device's first timeouts and probes included.
//!    Prints each device's rate with the dead one over its rate without it, and the line time
//!    each request to the dead one cost the others (target: at most its timeout and the quiet
//!    a late reply needs after it, as the bus README promises: 0.2 s).
//! 2. Its return: the eighth is silent until some time after it went offline, then answers
//!    again. Prints the time from its return to its `Online` health event against the backoff
//!    period in effect then, the wait between its last failed probe and the probe that found
//!    it (target: within one backoff period). Probes are seen by the simulated device.
//! 3. A real line beside an absent device: a P series and a CCS (default timeout, 1 s) polled
//!    every 100 ms on a line-timed pty served by another process (this bench run again as the
//!    server), and a rangefinder at slave 25 that is not there (timeout 100 ms). Trials
//!    alternate the file without the absent device (the anchor) and with it; prints each live
//!    device's polls per second and its longest gap between two polls (targets: ≥ 7 a second,
//!    no gap over 0.4 s).
//!
//! Run with `cargo bench -p optobus-bus --bench dead_device`; `OPTOBUS_BENCH_ONLY=3` runs only
//! part 3 (`1` parts 1 and 2).

mod common;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use common::{bus_file, emulated_line, model_name, models, simulators};
use optobus_bus::{Bus, Event, Health};
use optobus_codec::LineFormat;
use optobus_simulator::{Line, Simulator};

const BAUD: u32 = 115_200;
const TRIALS: usize = 3;
/// The dead device's timeout (every device's in parts 1 and 2).
const DEAD_TIMEOUT: Duration = Duration::from_millis(100);
/// A trial's length; `OPTOBUS_BENCH_RUN_SECS` sets another (a long trial shows the steady
/// state, where the backoff has grown: the first failures and probes weigh less).
fn trial_length() -> Duration {
    std::env::var("OPTOBUS_BENCH_RUN_SECS")
        .ok()
        .and_then(|s| s.parse().ok())
        .map_or(Duration::from_secs(8), Duration::from_secs)
}
const GROUP: &str = "measurements";
/// How long after going offline the dead device returns, one trial each.
const RETURNS: [Duration; 3] = [
    Duration::from_millis(1_500),
    Duration::from_millis(4_000),
    Duration::from_millis(9_000),
];

fn devices(count: usize) -> Vec<String> {
    models()[..count]
        .iter()
        .enumerate()
        .map(|(i, model)| {
            format!(
                "{{ name: d{}, model: {}, slave: {}, timeout: {}ms, poll: [{{ read: {GROUP} }}] }}",
                i + 1,
                model_name(model),
                i + 1,
                DEAD_TIMEOUT.as_millis()
            )
        })
        .collect()
}

fn first_registers() -> Vec<&'static str> {
    models()
        .iter()
        .map(|m| optobus_bus::file::resolve(m, GROUP).unwrap()[0].name)
        .collect()
}

fn device_index(name: &str) -> usize {
    name[1..].parse::<usize>().unwrap() - 1
}

/// Polls per second of d1 to d7, with the eighth device dead (`with_dead`) or not in the file,
/// and the requests the dead one was sent.
async fn rates(with_dead: bool) -> (Vec<f64>, u64) {
    let count = if with_dead { 8 } else { 7 };
    let mut simulators = simulators(&models()[..count]);
    let asked = Arc::new(AtomicU64::new(0));
    if with_dead {
        let counter = Arc::clone(&asked);
        simulators[7] = simulators[7].clone().observe(move |exchange| {
            if exchange.slave == Some(8) {
                counter.fetch_add(1, Ordering::Relaxed);
            }
        });
        simulators[7].set_silent(true);
    }
    let (stream, _line) = emulated_line(simulators, LineFormat::new(BAUD));
    let bus = Bus::new(bus_file(
        &format!("serial: bench, baud: {BAUD}"),
        &devices(count),
    ))
    .with_stream("bench", stream);
    let mut events = bus.subscribe();
    let first = first_registers();
    let started = Instant::now();
    let running = bus.start().expect("starts");
    let mut polls = [0u64; 7];
    while started.elapsed() < trial_length() {
        if let Ok(Ok(Event::Sample(sample))) =
            tokio::time::timeout(Duration::from_millis(100), events.recv()).await
        {
            let index = device_index(&sample.source.device);
            if index < 7 && sample.register.name == first[index] {
                polls[index] += 1;
            }
        }
    }
    let elapsed = started.elapsed().as_secs_f64();
    drop(running);
    (
        polls.iter().map(|&p| p as f64 / elapsed).collect(),
        asked.load(Ordering::Relaxed),
    )
}

/// The dead device's return `after` it went offline: (time to its Online event, the backoff
/// period in effect, probes seen).
async fn recovery(after: Duration) -> (Duration, Duration, usize) {
    let probes = Arc::new(Mutex::new(Vec::new()));
    let seen = Arc::clone(&probes);
    let mut simulators = simulators(&models());
    simulators[7] = simulators[7].clone().observe(move |exchange| {
        if exchange.slave == Some(8) {
            seen.lock().unwrap().push(Instant::now());
        }
    });
    let dead = simulators[7].clone();
    dead.set_silent(true);
    let (stream, _line) = emulated_line(simulators, LineFormat::new(BAUD));
    let bus = Bus::new(bus_file(
        &format!("serial: bench, baud: {BAUD}"),
        &devices(8),
    ))
    .with_stream("bench", stream);
    let mut events = bus.subscribe();
    let _running = bus.start().expect("starts");
    let mut returned: Option<Instant> = None;
    let mut offline_at: Option<Instant> = None;
    loop {
        let wait = match (offline_at, returned) {
            (Some(at), None) => (at + after).saturating_duration_since(Instant::now()),
            _ => Duration::from_secs(1),
        };
        match tokio::time::timeout(wait, events.recv()).await {
            Ok(Ok(Event::Health(health))) if &*health.source.device == "d8" => {
                match health.health {
                    Health::Offline => offline_at = Some(Instant::now()),
                    Health::Online => {
                        let online = Instant::now();
                        let returned = returned.expect("online only after it returned");
                        let probes = probes.lock().unwrap().clone();
                        // The probe that found it, and the last one that did not.
                        let found = probes.iter().rev().find(|&&p| p >= returned).copied();
                        let before = probes.iter().rev().find(|&&p| p < returned).copied();
                        let backoff = match (found, before) {
                            (Some(found), Some(before)) => found - before,
                            _ => Duration::ZERO,
                        };
                        return (online - returned, backoff, probes.len());
                    }
                }
            }
            Err(_) if offline_at.is_some() && returned.is_none() => {
                dead.set_silent(false);
                returned = Some(Instant::now());
            }
            _ => {}
        }
    }
}

async fn run() {
    let mut without = Vec::new();
    let mut with = Vec::new();
    let mut asked = 0;
    for _ in 0..TRIALS {
        without.push(rates(false).await.0);
        let (rates, dead_asked) = rates(true).await;
        with.push(rates);
        asked += dead_asked;
    }
    println!(
        "{BAUD} baud 8N1, d8 dead (timeout 100 ms), {TRIALS} trials of {:.0} s each way, interleaved  (load {})",
        trial_length().as_secs_f64(),
        common::load()
    );
    let mut worst: f64 = f64::INFINITY;
    for device in 0..7 {
        let mean =
            |runs: &[Vec<f64>]| runs.iter().map(|r| r[device]).sum::<f64>() / runs.len() as f64;
        let (alone, beside) = (mean(&without), mean(&with));
        let ratio = beside / alone;
        worst = worst.min(ratio);
        println!(
            "  d{} {:<12} {:>6.1} polls/s without d8, {:>6.1} with d8 dead: ratio {ratio:.3}",
            device + 1,
            model_name(models()[device]),
            alone,
            beside
        );
    }
    // What each request to the dead device cost the others: their lost share of the run. The
    // bus README's promise: its own timeout, then the quiet a late reply to it needs (the
    // timeout again), nothing more (5 % for the transactions it delayed).
    let asked_per_trial = asked as f64 / TRIALS as f64;
    let per_request = (1.0 - worst) * trial_length().as_secs_f64() / asked_per_trial;
    let promised = 2.0 * DEAD_TIMEOUT.as_secs_f64();
    println!(
        "worst ratio {worst:.3}; d8 was asked {asked_per_trial:.1} times a trial; the seven lost {:.3} s a trial, {per_request:.3} s per request to d8 (target ≤ its timeout and the quiet after it, {promised:.3} s, + 5 %): {}",
        (1.0 - worst) * trial_length().as_secs_f64(),
        if per_request <= promised * 1.05 { "met" } else { "NOT met" }
    );
    for after in RETURNS {
        let (took, backoff, probes) = recovery(after).await;
        println!(
            "  d8 returns {:.1} s after going offline: online {:.3} s later, backoff in effect {:.3} s ({probes} requests seen): {:.2} of a backoff period  (load {})",
            after.as_secs_f64(),
            took.as_secs_f64(),
            backoff.as_secs_f64(),
            took.as_secs_f64() / backoff.as_secs_f64(),
            common::load()
        );
    }
}

/// The environment variable that makes this bench the pty server of part 3.
const SERVE_PTY: &str = "OPTOBUS_BENCH_SERVE_PTY";

/// Part 3's server: a P series at slave 1 and a CCS at slave 2 on a pty timed as 115200 8N1;
/// prints the pty's path and serves until its standard input closes (the bench ended).
async fn serve_pty() {
    let devices = [
        Simulator::new(&optobus_p_series::DEVICE).slave(1),
        Simulator::new(&optobus_ccs::DEVICE).slave(2),
    ];
    let pty = optobus_simulator::Slaves::new(devices)
        .serve_pty_line(Line::new(LineFormat::new(BAUD)))
        .expect("a pty");
    println!("{}", pty.path().display());
    let _ = tokio::task::spawn_blocking(|| std::io::stdin().read_line(&mut String::new())).await;
}

/// A pty served by another process (this bench binary as the server of part 3).
struct PtyServer {
    child: std::process::Child,
    path: String,
}

impl PtyServer {
    fn start() -> Self {
        let mut child = std::process::Command::new(std::env::current_exe().unwrap())
            .env(SERVE_PTY, "1")
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .spawn()
            .expect("the pty server starts");
        let mut path = String::new();
        std::io::BufRead::read_line(
            &mut std::io::BufReader::new(child.stdout.take().unwrap()),
            &mut path,
        )
        .unwrap();
        Self {
            child,
            path: path.trim().to_owned(),
        }
    }
}

impl Drop for PtyServer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Polls per second and the longest gap between two polls of the head (slave 1) and the
/// confocal (slave 2), beside an absent rangefinder (`absent`) or without it.
async fn beside_absent(server: &PtyServer, absent: bool) -> [(f64, Duration); 2] {
    let mut devices = vec![
        "{ name: head, model: p-series, slave: 1, poll: [{ read: measurements, every: 100ms }] }"
            .to_owned(),
        "{ name: confocal, model: ccs, slave: 2, poll: [{ read: measurements, every: 100ms }] }"
            .to_owned(),
    ];
    if absent {
        devices.push(
            "{ name: absent, model: rangefinder, slave: 25, timeout: 100ms, poll: [{ read: measurements, every: 100ms }] }"
                .to_owned(),
        );
    }
    let file = bus_file(&format!("serial: {}, baud: {BAUD}", server.path), &devices);
    let bus = Bus::new(file);
    let mut events = bus.subscribe();
    let running = bus.start().expect("starts");
    let mut polls: [Vec<std::time::SystemTime>; 2] = Default::default();
    let started = Instant::now();
    while started.elapsed() < trial_length() {
        if let Ok(Ok(Event::Sample(sample))) =
            tokio::time::timeout(Duration::from_millis(100), events.recv()).await
        {
            let index = match &*sample.source.device {
                "head" => 0,
                "confocal" => 1,
                _ => continue,
            };
            // One sample per poll: the poll's request time tells them apart.
            if polls[index].last() != Some(&sample.requested) {
                polls[index].push(sample.requested);
            }
        }
    }
    let elapsed = started.elapsed().as_secs_f64();
    drop(running);
    // The line's last request may still be answered: let the server finish before the next
    // trial opens the port, or that trial's first request gets two replies (a fault whose
    // recovery, the default timeout of 1 s, would show as a gap that is no device's doing).
    tokio::time::sleep(Duration::from_millis(50)).await;
    polls.map(|times| {
        let gap = times
            .windows(2)
            .map(|pair| pair[1].duration_since(pair[0]).unwrap_or_default())
            .max()
            .unwrap_or(Duration::MAX);
        (times.len() as f64 / elapsed, gap)
    })
}

async fn real_line() {
    let server = PtyServer::start();
    let mut without = Vec::new();
    let mut with = Vec::new();
    for _ in 0..TRIALS {
        without.push(beside_absent(&server, false).await);
        with.push(beside_absent(&server, true).await);
    }
    println!(
        "a line-timed pty served by another process, {BAUD} baud 8N1: head (p-series) and confocal (ccs) every 100 ms, default timeout; absent rangefinder at slave 25, timeout 100 ms; {TRIALS} trials of {:.0} s each way, interleaved  (load {})",
        trial_length().as_secs_f64(),
        common::load()
    );
    for (index, name) in ["head", "confocal"].into_iter().enumerate() {
        let mean = |runs: &[[(f64, Duration); 2]]| {
            runs.iter().map(|r| r[index].0).sum::<f64>() / runs.len() as f64
        };
        let longest = |runs: &[[(f64, Duration); 2]]| {
            runs.iter().map(|r| r[index].1).max().unwrap_or_default()
        };
        let (alone, beside) = (mean(&without), mean(&with));
        println!(
            "  {name:<9} {alone:>5.2} polls/s alone (longest gap {:.3} s), {beside:>5.2} beside the absent device (longest gap {:.3} s): ratio {:.3}; targets ≥ 7/s and ≤ 0.4 s: {}",
            longest(&without).as_secs_f64(),
            longest(&with).as_secs_f64(),
            beside / alone,
            if beside >= 7.0 && longest(&with) <= Duration::from_millis(400) {
                "met"
            } else {
                "NOT met"
            }
        );
    }
}

fn main() {
    if std::env::var_os(SERVE_PTY).is_some() {
        common::runtime().block_on(serve_pty());
        return;
    }
    let only = std::env::var("OPTOBUS_BENCH_ONLY").ok();
    common::runtime().block_on(async {
        if only.as_deref() != Some("3") {
            run().await;
        }
        if only.as_deref() != Some("1") {
            real_line().await;
        }
    });
}
