//! An unsaturated line: 8 devices of mixed families on the byte-timed RS-485 emulator at
//! 115200 baud 8N1, each polling its measurements periodically (periods of 38 to 190 ms,
//! several of them multiples of each other so that ticks collide), the polls needing about
//! half of the line (≤ 70 %; the line's own utilisation is printed), then the same with the
//! periods doubled. Each runs twice: with tokio's clock paused (byte timing and schedule
//! exact: what the schedule itself does) and on the wall clock (what the machine adds).
//!
//! For every poll it prints the p50 and p99 of its period jitter, the deviation of the
//! interval between the requests of consecutive samples from the poll's period, against the
//! anchor measured in the same run: the longest transaction of the run (a poll's request
//! time to its reply time, t3.5 before it included) plus 1 ms (target: p99 ≤ that bound).
//! As a machine that preempts the bench stretches the longest transaction, a strict bound is
//! printed beside it: the longest poll's median transaction plus 1 ms. Ticks skipped (an
//! interval of 1.5 periods or more) are counted too. Two more anchors of the same run: the
//! jitter of a plain tokio interval of 10 ms beside the bus on the same runtime (what the
//! machine does to any timer), and the jitter an ideal non-preemptive earliest-deadline-first
//! line without a phase plan would give these polls with the run's median transaction times
//! (every poll first due at once, and first ticks packed back to back): what the bus's phase
//! plan is measured against. Run with
//! `cargo bench -p optobus-bus --bench jitter`; `OPTOBUS_SLEEP_THROUGH_REPLIES=1` makes the RTU
//! client sleep through each reply by its device's learned turnaround
//! (`timing::set_sleep_through_replies`, to compare).

mod common;

use std::collections::HashMap;
use std::time::{Duration, SystemTime};

use tokio::time::Instant;

use common::{bus_file, emulated_line, model_name, models, ms, quantile, simulators};
use optobus_bus::{Bus, Event};
use optobus_codec::LineFormat;

const BAUD: u32 = 115_200;
/// The periods at the heavier load (about half of the line); the lighter load doubles them.
const PERIODS_MS: [u64; 8] = [38, 45, 60, 75, 90, 120, 150, 190];
const RUN: Duration = Duration::from_secs(15);
/// The first polls (all due at once at the start) are left out.
const WARM_UP: Duration = Duration::from_millis(500);
const GROUP: &str = "measurements";

struct Poll {
    period: Duration,
    /// Request times of its samples.
    requested: Vec<SystemTime>,
    /// Its transactions' times, ms.
    took: Vec<f64>,
}

/// Jitter (ms) of a tokio interval of 10 ms running beside the bus on the same runtime: what
/// the machine and the runtime do to any timer, the bus aside.
async fn timer_probe(until: Instant) -> Vec<f64> {
    const TICK: Duration = Duration::from_millis(10);
    let mut interval = tokio::time::interval(TICK);
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut last = None;
    let mut jitter = Vec::new();
    while Instant::now() < until {
        interval.tick().await;
        let now = Instant::now();
        if let Some(last) = last {
            let interval: Duration = now - last;
            jitter.push((interval.as_secs_f64() - TICK.as_secs_f64()).abs() * 1e3);
        }
        last = Some(now);
    }
    jitter
}

/// The start times (ms) of each poll under an ideal non-preemptive earliest-deadline-first
/// line, each poll taking `took[i]` ms, first due at `first[i]`, missed ticks skipped: what
/// the schedule alone does to the periods, with no machine in the way.
fn model_starts(periods: &[f64], took: &[f64], first: &[f64], run: f64) -> Vec<Vec<f64>> {
    let mut due: Vec<f64> = first.to_vec();
    let mut starts = vec![Vec::new(); periods.len()];
    let mut now = 0.0;
    while now < run {
        let next = (0..periods.len())
            .filter(|&i| due[i] <= now)
            .min_by(|&a, &b| due[a].total_cmp(&due[b]));
        let Some(i) = next else {
            now = due.iter().copied().fold(f64::INFINITY, f64::min);
            continue;
        };
        starts[i].push(now);
        now += took[i];
        due[i] += periods[i];
        if due[i] <= now {
            due[i] += ((now - due[i]) / periods[i]).floor() * periods[i] + periods[i];
        }
    }
    starts
}

fn jitters(starts: &[f64], period: f64) -> Vec<f64> {
    starts
        .windows(2)
        .map(|pair| (pair[1] - pair[0] - period).abs())
        .collect()
}

async fn run(periods: [u64; 8], clock: &str) {
    let format = LineFormat::new(BAUD);
    let devices: Vec<String> = models()
        .iter()
        .zip(periods)
        .enumerate()
        .map(|(i, (model, every))| {
            format!(
                "{{ name: d{}, model: {}, slave: {}, timeout: 500ms, poll: [{{ read: {GROUP}, every: {every}ms }}] }}",
                i + 1,
                model_name(model),
                i + 1
            )
        })
        .collect();
    let (stream, line) = emulated_line(simulators(&models()), format);
    let bus = Bus::new(bus_file(&format!("serial: bench, baud: {BAUD}"), &devices))
        .with_stream("bench", stream);
    let mut events = bus.subscribe();
    let first: Vec<&str> = models()
        .iter()
        .map(|m| optobus_bus::file::resolve(m, GROUP).unwrap()[0].name)
        .collect();
    let mut polls: HashMap<String, Poll> = (0..8)
        .map(|i| {
            (
                format!("d{}", i + 1),
                Poll {
                    period: Duration::from_millis(periods[i]),
                    requested: Vec::new(),
                    took: Vec::new(),
                },
            )
        })
        .collect();
    let started = Instant::now();
    // Samples carry the line's wall-clock mapping of its (possibly paused) clock.
    let mut warm_until: Option<SystemTime> = None;
    let running = bus.start().expect("starts");
    let probe = tokio::spawn(timer_probe(started + RUN));
    let mut longest = Duration::ZERO;
    let mut utilisation = (0.0, 0u64);
    let mut lagged = 0;
    while started.elapsed() < RUN {
        match tokio::time::timeout(Duration::from_millis(100), events.recv()).await {
            Ok(Ok(Event::Sample(sample))) => {
                let index: usize = sample.source.device[1..].parse::<usize>().unwrap() - 1;
                let warm_until = *warm_until.get_or_insert(sample.requested + WARM_UP);
                if sample.register.name != first[index] || sample.requested < warm_until {
                    continue;
                }
                let took = sample
                    .replied
                    .duration_since(sample.requested)
                    .unwrap_or_default();
                longest = longest.max(took);
                let poll = polls.get_mut(&*sample.source.device).unwrap();
                poll.requested.push(sample.requested);
                poll.took.push(ms(took));
            }
            Ok(Ok(Event::Line(stats))) => {
                utilisation = (stats.utilisation(), stats.errors.total());
            }
            Ok(Err(tokio::sync::broadcast::error::RecvError::Lagged(n))) => lagged += n,
            _ => {}
        }
    }
    drop(running);
    let probe = probe.await.unwrap();
    let bound = longest + Duration::from_millis(1);
    // A preempted process stretches the longest transaction: the strict bound takes the
    // longest poll's typical (median) transaction instead.
    let typical = polls
        .values()
        .map(|p| quantile(&p.took, 0.5))
        .fold(0.0, f64::max);
    let strict = typical + 1.0;
    println!(
        "{clock}: {BAUD} baud 8N1, 8 periodic polls, {:.0} s: line utilisation {:.2}, {} line errors, {} gap violations, {} events lost by the bench  (load {})",
        RUN.as_secs_f64(),
        utilisation.0,
        utilisation.1,
        line.gap_violations(),
        lagged,
        common::load()
    );
    println!(
        "longest transaction {:.3} ms: bound = longest + 1 ms = {:.3} ms; longest poll's median transaction {typical:.3} ms: strict bound {strict:.3} ms",
        ms(longest),
        ms(bound)
    );
    println!(
        "  beside it, a tokio interval of 10 ms on the same runtime: jitter p50 {:.3} ms  p99 {:.3} ms  max {:.3} ms",
        quantile(&probe, 0.5),
        quantile(&probe, 0.99),
        quantile(&probe, 1.0)
    );
    let names: Vec<String> = (1..=8).map(|i| format!("d{i}")).collect();
    let periods: Vec<f64> = names.iter().map(|n| ms(polls[n].period)).collect();
    let took: Vec<f64> = names
        .iter()
        .map(|n| quantile(&polls[n].took, 0.5))
        .collect();
    // As the bus starts them: every poll first due at once.
    let model = model_starts(&periods, &took, &[0.0; 8], ms(RUN));
    // First ticks staggered by the polls before them, so that they do not start together.
    let first: Vec<f64> = took
        .iter()
        .scan(0.0, |at, t| {
            let first = *at;
            *at += t;
            Some(first)
        })
        .collect();
    let staggered = model_starts(&periods, &took, &first, ms(RUN));
    let mut worst: f64 = 0.0;
    for i in 0..8 {
        let name = format!("d{}", i + 1);
        let poll = &polls[&name];
        let mut jitter = Vec::new();
        let mut skipped = 0;
        for pair in poll.requested.windows(2) {
            let interval = pair[1].duration_since(pair[0]).unwrap_or_default();
            if interval.as_secs_f64() >= 1.5 * poll.period.as_secs_f64() {
                skipped += 1;
            }
            jitter.push((interval.as_secs_f64() - poll.period.as_secs_f64()).abs() * 1e3);
        }
        let (p50, p99) = (quantile(&jitter, 0.5), quantile(&jitter, 0.99));
        worst = worst.max(p99);
        println!(
            "  {name} {:<12} every {:>3} ms, transaction p50 {:.3} ms: {:>4} intervals, jitter p50 {p50:.3} ms  p99 {p99:.3} ms  max {:.3} ms  skipped ticks {skipped}  p99/bound {:.2}  p99/strict {:.2}  (ideal schedule: p99 {:.3} ms, first ticks staggered: p99 {:.3} ms)",
            model_name(models()[i]),
            poll.period.as_millis(),
            quantile(&poll.took, 0.5),
            jitter.len(),
            quantile(&jitter, 1.0),
            p99 / ms(bound),
            p99 / strict,
            quantile(&jitters(&model[i], ms(poll.period)), 0.99),
            quantile(&jitters(&staggered[i], ms(poll.period)), 0.99),
        );
    }
    let verdict = |bound: f64| if worst <= bound { "met" } else { "NOT met" };
    println!(
        "worst p99 {worst:.3} ms: bound {:.3} ms {}, strict bound {strict:.3} ms {}",
        ms(bound),
        verdict(ms(bound)),
        verdict(strict)
    );
}

fn main() {
    if std::env::var("OPTOBUS_SLEEP_THROUGH_REPLIES").is_ok_and(|on| on == "1") {
        optobus_transport::timing::set_sleep_through_replies(true);
        println!("replies slept through by learned turnarounds (OPTOBUS_SLEEP_THROUGH_REPLIES=1)");
    }
    // Tokio's clock paused: time moves only when every task waits, so the line's byte timing
    // and the schedule are exact and the machine's load plays no part: what the schedule
    // itself does.
    let paused = || {
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .start_paused(true)
            .build()
            .unwrap()
    };
    paused().block_on(run(PERIODS_MS, "schedule alone (paused clock)"));
    paused().block_on(run(
        PERIODS_MS.map(|p| p * 2),
        "schedule alone (paused clock)",
    ));
    let runtime = common::runtime();
    runtime.block_on(run(PERIODS_MS, "wall clock"));
    runtime.block_on(run(PERIODS_MS.map(|p| p * 2), "wall clock"));
}
