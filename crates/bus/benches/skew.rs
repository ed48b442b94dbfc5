//! Issue 32, point 2: how far apart a measurement's inputs are read. Two P series heads polled
//! every 20 ms for `gap = 20mm - top.distance_1 - bottom.distance_1`, on the simulator's
//! in-memory byte-timed RS-485 emulator at 115200 baud 8N1 (device turnaround 0; the same
//! emulator `line_share` and `jitter` use): first both heads on one line, then each on a line
//! of its own.
//!
//! For each it prints the p50, p99 and max of the measurement's skew (the time between its
//! first and last input's requests, as every value carries it) with the bus's measurement
//! groups (after), and with every poll on its own phase as before them (before; the bench-only
//! `Bus::without_measurement_groups`), trials interleaved. The anchor, measured in the same
//! run: one transaction's time, the median of the heads' request-to-reply times. Targets
//! (issue 32): p99 ≤ one transaction + 1 ms on one line, ≤ one transaction + 2 ms on two. A
//! second anchor: how late a plain 10 ms tokio interval beside the bus wakes (p99), what the
//! machine does to any wake-up in the same trials.
//!
//! Each runs first with tokio's clock paused (the emulated line's byte timing and the schedule
//! exact: what the schedule itself does), then on the wall clock (what the machine adds); and
//! each layout also with a third P series in no measurement (slave 3): on one line listed
//! between the heads and polled every 20 ms too, on two lines beside `top` every 50 ms. Run
//! with `cargo bench -p optobus-bus --bench skew`.

mod common;

use std::path::Path;
use std::time::Duration;

use tokio::time::Instant;

use common::{load, ms, quantile, runtime};
use optobus_bus::{Bus, BusFile, Catalogue, Event};
use optobus_codec::LineFormat;
use optobus_simulator::Simulator;

const BAUD: u32 = 115_200;
const TRIALS: usize = 4;
const TRIAL: Duration = Duration::from_secs(5);
/// The first values (the lines opening, the first round timing each poll) are left out.
const WARM_UP: Duration = Duration::from_millis(500);

#[derive(Clone, Copy, PartialEq)]
enum Layout {
    OneLine,
    TwoLines,
}

/// A third P series (slave 3) in no measurement: on one line listed between the heads and
/// polled every 20 ms too, on two lines beside `top` every 50 ms.
#[derive(Clone, Copy, PartialEq)]
enum Third {
    None,
    Beside,
}

fn bus_file(layout: Layout, third: Third) -> BusFile {
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
    let (lines, bottom_line) = match layout {
        Layout::OneLine => (
            format!("  - {{ name: a, serial: a, baud: {BAUD}, any_format: true }}\n"),
            "a",
        ),
        Layout::TwoLines => (
            format!(
                "  - {{ name: a, serial: a, baud: {BAUD}, any_format: true }}\n  - {{ name: b, serial: b, baud: {BAUD}, any_format: true }}\n"
            ),
            "b",
        ),
    };
    let other = match (third, layout) {
        (Third::None, _) => "",
        (Third::Beside, Layout::OneLine) => "  - { name: other, line: a, model: p-series, slave: 3, timeout: 100ms, poll: [{ read: distance_1, every: 20ms }] }\n",
        (Third::Beside, Layout::TwoLines) => "  - { name: other, line: a, model: p-series, slave: 3, timeout: 100ms, poll: [{ read: distance_1, every: 50ms }] }\n",
    };
    let text = format!(
        "lines:
{lines}devices:
  - {{ name: top, line: a, model: p-series, slave: 1, timeout: 100ms, poll: [{{ read: distance_1, every: 20ms }}] }}
{other}  - {{ name: bottom, line: {bottom_line}, model: p-series, slave: 2, timeout: 100ms, poll: [{{ read: distance_1, every: 20ms }}] }}
measurements:
  - name: gap
    expr: 20mm - top.distance_1 - bottom.distance_1
    unit: mm
    max_skew: 1s             # every value counted, however far apart its inputs
"
    );
    BusFile::parse("skew.yaml", &text, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}\n{text}", e.render()))
}

/// The two heads, each on the line it is on.
fn line_to(slaves: &[u8]) -> tokio::io::DuplexStream {
    let simulators = slaves
        .iter()
        .map(|&slave| {
            Simulator::new(&optobus_p_series::DEVICE)
                .slave(slave)
                .sentinel_every(0)
        })
        .collect();
    common::emulated_line(simulators, LineFormat::new(BAUD)).0
}

#[derive(Default)]
struct Run {
    /// Each value's skew, ms.
    skews: Vec<f64>,
    /// Each head's transaction (request to reply), ms.
    transactions: Vec<f64>,
    /// Values without one (an input missing).
    invalid: usize,
    /// How late a plain tokio interval of 10 ms beside the bus woke, ms: what the machine
    /// does to any wake-up.
    timer: Vec<f64>,
}

/// How late (ms) each tick of a 10 ms tokio interval came until `until`.
async fn timer_probe(until: Instant) -> Vec<f64> {
    const TICK: Duration = Duration::from_millis(10);
    let mut next = Instant::now() + TICK;
    let mut late = Vec::new();
    while next < until {
        tokio::time::sleep_until(next).await;
        late.push(ms(Instant::now().saturating_duration_since(next)));
        next += TICK;
    }
    late
}

async fn trial(layout: Layout, third: Third, grouped: bool, run: &mut Run) {
    let mut bus = Bus::new(bus_file(layout, third));
    let (a, b): (&[u8], &[u8]) = match (layout, third) {
        (Layout::OneLine, Third::None) => (&[1, 2], &[]),
        (Layout::OneLine, Third::Beside) => (&[1, 2, 3], &[]),
        (Layout::TwoLines, Third::None) => (&[1], &[2]),
        (Layout::TwoLines, Third::Beside) => (&[1, 3], &[2]),
    };
    bus = bus.with_stream("a", line_to(a));
    if layout == Layout::TwoLines {
        bus = bus.with_stream("b", line_to(b));
    }
    if !grouped {
        bus = bus.without_measurement_groups();
    }
    let mut events = bus.subscribe();
    let started = Instant::now();
    let running = bus.start().expect("starts");
    let probe = tokio::spawn(timer_probe(started + TRIAL));
    while started.elapsed() < TRIAL {
        let event = match tokio::time::timeout(Duration::from_millis(100), events.recv()).await {
            Ok(Ok(event)) => event,
            Ok(Err(error)) => panic!("{error}"),
            Err(_) => continue,
        };
        if started.elapsed() < WARM_UP {
            continue;
        }
        match event {
            Event::Measurement(value) => match value.value {
                Ok(_) => run.skews.push(ms(value.skew)),
                Err(_) => run.invalid += 1,
            },
            Event::Sample(sample) if &*sample.source.device != "other" => {
                if let Ok(took) = sample.replied.duration_since(sample.requested) {
                    run.transactions.push(ms(took));
                }
            }
            _ => {}
        }
    }
    drop(running);
    let late = probe.await.expect("the probe ran");
    run.timer
        .extend(late.into_iter().skip(WARM_UP.as_millis() as usize / 10));
}

fn main() {
    for (paused, clock) in [(true, "paused clock"), (false, "wall clock")] {
        let runtime = if paused {
            tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .start_paused(true)
                .build()
                .unwrap()
        } else {
            runtime()
        };
        println!("{clock}:");
        measure(&runtime);
    }
}

/// Both layouts, before and after, trials interleaved.
fn measure(runtime: &tokio::runtime::Runtime) {
    for (layout, third, name, allowance) in [
        (Layout::OneLine, Third::None, "one line", 1.0),
        (
            Layout::OneLine,
            Third::Beside,
            "one line, a third device between the heads",
            1.0,
        ),
        (Layout::TwoLines, Third::None, "two lines", 2.0),
        (
            Layout::TwoLines,
            Third::Beside,
            "two lines, a third device beside top",
            2.0,
        ),
    ] {
        let mut before = Run::default();
        let mut after = Run::default();
        for _ in 0..TRIALS {
            runtime.block_on(trial(layout, third, true, &mut after));
            runtime.block_on(trial(layout, third, false, &mut before));
        }
        let mut transactions = before.transactions.clone();
        transactions.extend(&after.transactions);
        let anchor = quantile(&transactions, 0.5);
        let target = anchor + allowance;
        println!(
            "{name}: one transaction (anchor, median of {}) {anchor:.3} ms; target p99 ≤ {target:.3} ms (anchor + {allowance} ms)  (load {})",
            transactions.len(),
            load()
        );
        for (label, run) in [("before", &before), ("after", &after)] {
            let p50 = quantile(&run.skews, 0.5);
            let p99 = quantile(&run.skews, 0.99);
            let max = quantile(&run.skews, 1.0);
            let timer = quantile(&run.timer, 0.99);
            println!(
                "  {label:<6}  a 10 ms tokio interval beside it woke late by p99 {timer:.3} ms (the machine's anchor)"
            );
            println!(
                "  {label:<6}  skew p50 {p50:.3} ms  p99 {p99:.3} ms  max {max:.3} ms  p99 / anchor {:.2}  p99 / target {:.2}  ({} values, {} invalid)",
                p99 / anchor,
                p99 / target,
                run.skews.len(),
                run.invalid
            );
            let far = run.skews.iter().filter(|&&s| s > target).count();
            if far > 0 {
                let mut shown: Vec<f64> =
                    run.skews.iter().copied().filter(|&s| s > target).collect();
                shown.sort_by(f64::total_cmp);
                shown.truncate(12);
                println!("          {far} above the target, the least of them (ms): {shown:.2?}");
            }
        }
    }
}
