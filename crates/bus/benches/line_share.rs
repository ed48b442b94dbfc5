//! A saturated line: 8 devices of mixed families polled as fast as the line allows, on the
//! byte-timed RS-485 emulator at 9600 and 115200 baud 8N1 (device turnaround 0).
//!
//! For the bus, the bus with its RTU client sleeping through each reply by its device's
//! learned turnaround ("learned", `timing::set_sleep_through_replies`) and, as
//! the anchor, a bare loop of driver cores on one `RtuClient` reading the same groups in turn
//! (trials interleaved), it prints each run's share of the line limit:
//! the characters that crossed the line (counted on the client's stream) plus two t3.5 per
//! transaction, over the time taken (target ≥ 0.97); the emulator's gap violations (t3.5 not
//! kept, target 0); and each device's share of the polls against an equal share (target within
//! ±10 %). Run with `cargo bench -p optobus-bus --bench line_share`.
//!
//! Trials are short and many, and the median and best are printed: a process preempted on a
//! loaded machine loses line time that no scheduler can make up, and that shows in a trial
//! or two rather than in all. Devices take turns, so within a trial their polls differ by one
//! when it ends mid-round; that spread is printed beside the shares, which are taken over all
//! trials of a run.

mod common;

use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::{load, models};
use optobus_bus::{Bus, BusFile, Catalogue, Event};
use optobus_codec::LineFormat;
use optobus_driver::{rtu_config, Core};
use optobus_simulator::{Line, Simulator};
use optobus_transport::timing::set_sleep_through_replies;
use optobus_transport::{Flow, RtuClient, RtuConfig, Shared, Tap};

/// The group each device polls.
const GROUP: &str = "measurements";

fn bus_file(format: LineFormat) -> BusFile {
    let catalogue = Catalogue::new(models());
    let mut text = format!(
        "lines:\n  - {{ name: bench, serial: bench, baud: {}, any_format: true }}\ndevices:\n",
        format.baud
    );
    for (index, model) in models().iter().enumerate() {
        text += &format!(
            "  - {{ name: d{}, model: {}, slave: {}, timeout: 500ms, poll: [{{ read: {GROUP} }}] }}\n",
            index + 1,
            model.family,
            index + 1
        );
    }
    BusFile::parse("bench.yaml", &text, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()))
}

/// The client's end of an emulated line, counting the bytes that cross it.
struct Counted<S> {
    stream: S,
    bytes: Arc<AtomicU64>,
    stats: optobus_simulator::LineStats,
}

/// An emulated line with the 8 simulators; the client's end counts the bytes on it.
fn line(format: LineFormat) -> Counted<impl optobus_bus::Stream> {
    let simulators: Vec<Simulator> = models()
        .iter()
        .enumerate()
        .map(|(i, model)| Simulator::new(model).slave(i as u8 + 1).sentinel_every(0))
        .collect();
    let line = Line::new(format);
    let stats = line.stats();
    let (stream, _server) = optobus_simulator::Slaves::new(simulators).duplex_line(line);
    let bytes = Arc::new(AtomicU64::new(0));
    let counter = Arc::clone(&bytes);
    let tap = Tap::new(stream, move |_: Flow, chunk: &[u8]| {
        counter.fetch_add(chunk.len() as u64, Ordering::Relaxed);
    });
    Counted {
        stream: tap,
        bytes,
        stats,
    }
}

struct Run {
    ratio: f64,
    /// The most and fewest polls of one device.
    spread: u64,
    /// Failed polls (bus: failed transactions).
    errors: u64,
    gap_violations: u64,
    polls: Vec<u64>,
}

fn limit_ratio(format: LineFormat, bytes: u64, transactions: u64, elapsed: Duration) -> f64 {
    let ideal = format.transmit_time(bytes as usize) + format.frame_gap() * 2 * transactions as u32;
    ideal.as_secs_f64() / (elapsed + format.frame_gap()).as_secs_f64()
}

fn spread(polls: &[u64]) -> u64 {
    polls.iter().max().unwrap_or(&0) - polls.iter().min().unwrap_or(&0)
}

fn shares(polls: &[u64]) -> Vec<f64> {
    let mean = polls.iter().sum::<u64>() as f64 / polls.len() as f64;
    polls.iter().map(|&p| p as f64 / mean).collect()
}

async fn bus_run(format: LineFormat, duration: Duration) -> Run {
    let counted = line(format);
    let bus = Bus::new(bus_file(format)).with_stream("bench", counted.stream);
    let mut events = bus.subscribe();
    let first_register: Vec<&str> = models()
        .iter()
        .map(|m| optobus_bus::file::resolve(m, GROUP).unwrap()[0].name)
        .collect();
    let started = Instant::now();
    let running = bus.start().expect("starts");
    let mut polls = vec![0u64; 8];
    let mut errors = 0;
    while started.elapsed() < duration {
        match tokio::time::timeout(Duration::from_millis(100), events.recv()).await {
            Ok(Ok(Event::Sample(sample))) => {
                let index: usize = sample.source.device[1..].parse::<usize>().unwrap() - 1;
                if sample.register.name == first_register[index] {
                    polls[index] += 1;
                }
            }
            Ok(Ok(Event::Line(line))) => errors = line.errors.total(),
            Ok(Err(e)) => panic!("{e}"),
            _ => {}
        }
    }
    let elapsed = started.elapsed();
    let transactions = counted.stats.frames();
    let bytes = counted.bytes.load(Ordering::Relaxed);
    drop(running);
    Run {
        spread: spread(&polls),
        ratio: limit_ratio(format, bytes, transactions, elapsed),
        errors,
        gap_violations: counted.stats.gap_violations(),
        polls: polls.clone(),
    }
}

async fn direct_run(format: LineFormat, duration: Duration) -> Run {
    let counted = line(format);
    let client = Shared::new(RtuClient::with_config(
        counted.stream,
        RtuConfig {
            line: Some(format),
            timeout: Duration::from_millis(500),
            ..rtu_config(&optobus_p_series::DEVICE)
        },
    ));
    let mut cores: Vec<(Core<_>, Vec<_>)> = models()
        .iter()
        .enumerate()
        .map(|(i, model)| {
            let registers = optobus_bus::file::resolve(model, GROUP).unwrap();
            (
                Core::new(client.clone(), i as u8 + 1, model).unwrap(),
                registers,
            )
        })
        .collect();
    let mut polls = vec![0u64; 8];
    let mut errors = 0;
    let started = Instant::now();
    'outer: loop {
        for (index, (core, registers)) in cores.iter_mut().enumerate() {
            if started.elapsed() >= duration {
                break 'outer;
            }
            match core.read_group(registers).await {
                Ok(_) => polls[index] += 1,
                Err(_) => errors += 1,
            }
        }
    }
    let elapsed = started.elapsed();
    Run {
        spread: spread(&polls),
        ratio: limit_ratio(
            format,
            counted.bytes.load(Ordering::Relaxed),
            counted.stats.frames(),
            elapsed,
        ),
        errors,
        gap_violations: counted.stats.gap_violations(),
        polls: polls.clone(),
    }
}

fn main() {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    // (baud, trials, trial length): enough polls per device for its share to mean something.
    for (baud, trials, duration) in [
        (9600, 4, Duration::from_secs(6)),
        (115_200, 8, Duration::from_secs(1)),
    ] {
        let format = LineFormat::new(baud);
        let mut ours = Vec::new();
        let mut learned = Vec::new();
        let mut anchor = Vec::new();
        for _ in 0..trials {
            ours.push(runtime.block_on(bus_run(format, duration)));
            set_sleep_through_replies(true);
            learned.push(runtime.block_on(bus_run(format, duration)));
            set_sleep_through_replies(false);
            anchor.push(runtime.block_on(direct_run(format, duration)));
        }
        let report = |name: &str, runs: &[Run]| {
            let ratio = common::median(&runs.iter().map(|r| r.ratio).collect::<Vec<_>>());
            let best = runs.iter().map(|r| r.ratio).fold(0.0, f64::max);
            let spread = runs.iter().map(|r| r.spread).max().unwrap_or(0);
            let gaps: u64 = runs.iter().map(|r| r.gap_violations).sum();
            let errors: u64 = runs.iter().map(|r| r.errors).sum();
            // Over all trials: each device's polls against an equal share.
            let total: Vec<u64> = (0..8)
                .map(|d| runs.iter().map(|r| r.polls[d]).sum())
                .collect();
            let worst = shares(&total)
                .iter()
                .map(|s| (s - 1.0).abs())
                .fold(0.0, f64::max);
            println!(
                "{baud:>6} baud  {name:<7} line limit ratio median {ratio:.3} best {best:.3}  gap violations {gaps}  errors {errors}  worst device share of all polls off equal by {:.1} % (polls per device differ by at most {spread} in a trial)  (load {})",
                worst * 100.0,
                load()
            );
            ratio
        };
        let bus = report("bus", &ours);
        let bus_learned = report("learned", &learned);
        let direct = report("direct", &anchor);
        println!(
            "{baud:>6} baud  bus / direct {:.3}  learned / direct {:.3}",
            bus / direct,
            bus_learned / direct
        );
    }
}
