//! What the bus adds per transaction over a bare driver core on an `RtuClient`: one P series
//! in memory, its measurements polled as fast as possible, with no line timing on either side
//! (no t3.5 to wait: a wait that both spin through would hide the bus's own work inside it).
//!
//! Three workloads, trials interleaved, each a task of its own while the bench's task sleeps
//! through a warm-up and a measured window: the bare loop (the anchor), the bus with nobody
//! listening to its events, and the bus with a task draining them. Transactions are counted
//! by the simulated device itself (the same counter for all three). Prints the median time per
//! transaction of each and the bus's difference to the anchor (target ≤ 5 µs). Run with
//! `cargo bench -p optobus-bus --bench overhead`.

mod common;

use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use optobus_bus::{Bus, BusFile, Catalogue};
use optobus_driver::{rtu_config, Core};
use optobus_simulator::Simulator;
use optobus_transport::{RtuClient, RtuConfig};

const TRIALS: usize = 7;
const WARM_UP: Duration = Duration::from_millis(200);
const RUN: Duration = Duration::from_millis(1000);

/// A P series at slave 1 counting the requests it answers.
fn simulator(answered: &Arc<AtomicU64>) -> Simulator {
    let counter = Arc::clone(answered);
    Simulator::new(&optobus_p_series::DEVICE)
        .slave(1)
        .sentinel_every(0)
        .observe(move |_| {
            counter.fetch_add(1, Ordering::Relaxed);
        })
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Workload {
    Direct,
    Bus,
    BusListened,
}

/// Seconds per transaction of `workload` over the measured window.
async fn trial(workload: Workload) -> f64 {
    let answered = Arc::new(AtomicU64::new(0));
    let (stream, _server) = simulator(&answered).duplex();
    let mut tasks = Vec::new();
    let running = match workload {
        Workload::Direct => {
            let client = RtuClient::with_config(
                stream,
                RtuConfig {
                    line: None,
                    ..rtu_config(&optobus_p_series::DEVICE)
                },
            );
            let mut core = Core::new(client, 1, &optobus_p_series::DEVICE).unwrap();
            let registers =
                optobus_bus::file::resolve(&optobus_p_series::DEVICE, "measurements").unwrap();
            tasks.push(tokio::spawn(async move {
                loop {
                    core.read_group(&registers).await.unwrap();
                }
            }));
            None
        }
        Workload::Bus | Workload::BusListened => {
            let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
            let mut file = BusFile::parse(
                "bench.yaml",
                "lines: [{ name: memory, serial: memory }]
devices: [{ name: head, model: p-series, slave: 1, poll: [{ read: measurements }] }]",
                Path::new("."),
                &catalogue,
            )
            .unwrap_or_else(|e| panic!("{}", e.render()));
            // In memory, as the bare loop: no line format, so no t3.5 and no transmit time.
            file.lines[0].format = None;
            let bus = Bus::new(file).with_stream("memory", stream);
            if workload == Workload::BusListened {
                let mut events = bus.subscribe();
                tasks.push(tokio::spawn(async move {
                    loop {
                        match events.recv().await {
                            Ok(event) => drop(std::hint::black_box(event)),
                            Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => {}
                            Err(tokio::sync::broadcast::error::RecvError::Closed) => break,
                        }
                    }
                }));
            }
            Some(bus.start().expect("starts"))
        }
    };
    tokio::time::sleep(WARM_UP).await;
    let (from, started) = (answered.load(Ordering::Relaxed), Instant::now());
    tokio::time::sleep(RUN).await;
    let (to, elapsed) = (answered.load(Ordering::Relaxed), started.elapsed());
    drop(running);
    for task in tasks {
        task.abort();
    }
    elapsed.as_secs_f64() / (to - from).max(1) as f64
}

fn main() {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let workloads = [Workload::Direct, Workload::Bus, Workload::BusListened];
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); workloads.len()];
    for _ in 0..TRIALS {
        for (index, &workload) in workloads.iter().enumerate() {
            times[index].push(runtime.block_on(trial(workload)));
        }
    }
    let [direct, bus, listened] = [0, 1, 2].map(|i| common::median(&times[i]));
    let per = |s: f64| s * 1e6;
    println!(
        "direct {:.2} µs/transaction ({:.0}/s)\nbus    {:.2} µs/transaction ({:.0}/s): adds {:.2} µs\nbus, events drained by a subscriber {:.2} µs/transaction ({:.0}/s): adds {:.2} µs",
        per(direct),
        1.0 / direct,
        per(bus),
        1.0 / bus,
        per(bus - direct),
        per(listened),
        1.0 / listened,
        per(listened - direct),
    );
}
