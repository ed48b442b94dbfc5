//! Issue 32, point 2: how far apart a measurement's inputs are read. Two P series heads polled
//! every 20 ms for `gap = 20mm - top.distance_1 - bottom.distance_1`, on the simulator's
//! in-memory byte-timed RS-485 emulator at 115200 baud 8N1 (device turnaround 0; the same
//! emulator `line_share` and `jitter` use), on the wall clock: first both heads on one line,
//! then each on a line of its own.
//!
//! For each it prints the p50, p99 and max of the measurement's skew (the time between its
//! first and last input's requests, as every value carries it) with the bus's measurement
//! groups (after), and with every poll on its own phase as before them (before; the bench-only
//! `Bus::without_measurement_groups`), trials interleaved. The anchor, measured in the same
//! run: one transaction's time, the median of the heads' request-to-reply times. Targets
//! (issue 32): p99 ≤ one transaction + 1 ms on one line, ≤ one transaction + 2 ms on two.
//! Run with `cargo bench -p optobus-bus --bench skew`.

mod common;

use std::path::Path;
use std::time::{Duration, Instant};

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

fn bus_file(layout: Layout) -> BusFile {
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
    let text = format!(
        "lines:
{lines}devices:
  - {{ name: top, line: a, model: p-series, slave: 1, timeout: 100ms, poll: [{{ read: distance_1, every: 20ms }}] }}
  - {{ name: bottom, line: {bottom_line}, model: p-series, slave: 2, timeout: 100ms, poll: [{{ read: distance_1, every: 20ms }}] }}
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
}

async fn trial(layout: Layout, grouped: bool, run: &mut Run) {
    let mut bus = Bus::new(bus_file(layout));
    bus = match layout {
        Layout::OneLine => bus.with_stream("a", line_to(&[1, 2])),
        Layout::TwoLines => bus
            .with_stream("a", line_to(&[1]))
            .with_stream("b", line_to(&[2])),
    };
    if !grouped {
        bus = bus.without_measurement_groups();
    }
    let mut events = bus.subscribe();
    let started = Instant::now();
    let running = bus.start().expect("starts");
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
            Event::Sample(sample) => {
                if let Ok(took) = sample.replied.duration_since(sample.requested) {
                    run.transactions.push(ms(took));
                }
            }
            _ => {}
        }
    }
    drop(running);
}

fn main() {
    let runtime = runtime();
    for (layout, name, allowance) in [
        (Layout::OneLine, "one line", 1.0),
        (Layout::TwoLines, "two lines", 2.0),
    ] {
        let mut before = Run::default();
        let mut after = Run::default();
        for _ in 0..TRIALS {
            runtime.block_on(trial(layout, true, &mut after));
            runtime.block_on(trial(layout, false, &mut before));
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
            println!(
                "  {label:<6}  skew p50 {p50:.3} ms  p99 {p99:.3} ms  max {max:.3} ms  p99 / anchor {:.2}  p99 / target {:.2}  ({} values, {} invalid)",
                p99 / anchor,
                p99 / target,
                run.skews.len(),
                run.invalid
            );
        }
    }
}
