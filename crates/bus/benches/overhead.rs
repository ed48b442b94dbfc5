//! What the bus adds per transaction over a bare driver core on an `RtuClient`: one P series
//! in memory (no line timing), its measurements polled as fast as possible, for the bus and
//! for a bare loop (the anchor), trials interleaved. Prints transactions per second of each
//! and the difference of their median times per transaction (target ≤ 5 µs). Run with
//! `cargo bench -p optobus-bus --bench overhead`.

use std::path::Path;
use std::time::{Duration, Instant};

use optobus_bus::{Bus, BusFile, Catalogue, Event};
use optobus_driver::{rtu_config, Core};
use optobus_simulator::Simulator;
use optobus_transport::{RtuClient, RtuConfig};

const TRIALS: usize = 5;
const RUN: Duration = Duration::from_millis(1500);

fn simulator() -> Simulator {
    Simulator::new(&optobus_p_series::DEVICE)
        .slave(1)
        .sentinel_every(0)
}

/// Seconds per transaction of the bus.
async fn bus_run() -> f64 {
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
    let file = BusFile::parse(
        "bench.yaml",
        "lines: [{ name: memory, serial: memory }]
devices: [{ name: head, model: p-series, slave: 1, poll: [{ read: measurements }] }]",
        Path::new("."),
        &catalogue,
    )
    .unwrap_or_else(|e| panic!("{}", e.render()));
    let (stream, _server) = simulator().duplex();
    // In memory there is no line to time: the bus keeps t3.5 of a line of 4 Mbaud (9 µs).
    let mut file = file;
    file.lines[0].format = Some(optobus_codec::LineFormat::new(4_000_000));
    let bus = Bus::new(file).with_stream("memory", stream);
    let mut events = bus.subscribe();
    let running = bus.start().expect("starts");
    let started = Instant::now();
    let mut last = None;
    while started.elapsed() < RUN {
        if let Ok(Ok(Event::Line(stats))) =
            tokio::time::timeout(Duration::from_millis(50), events.recv()).await
        {
            last = Some((stats.transactions, stats.elapsed));
        }
    }
    drop(running);
    let (transactions, elapsed) = last.expect("a line statistic each second");
    elapsed.as_secs_f64() / transactions as f64
}

/// Seconds per transaction of a bare core on the same kind of client.
async fn direct_run() -> f64 {
    let (stream, _server) = simulator().duplex();
    let client = RtuClient::with_config(
        stream,
        RtuConfig {
            line: Some(optobus_codec::LineFormat::new(4_000_000)),
            ..rtu_config(&optobus_p_series::DEVICE)
        },
    );
    let mut core = Core::new(client, 1, &optobus_p_series::DEVICE).unwrap();
    let registers = optobus_bus::file::resolve(&optobus_p_series::DEVICE, "measurements").unwrap();
    // A task of its own, as the bus's line is: the runtime polls both alike.
    tokio::spawn(async move {
        let started = Instant::now();
        let mut transactions = 0u64;
        while started.elapsed() < RUN {
            core.read_group(&registers).await.unwrap();
            transactions += 1;
        }
        started.elapsed().as_secs_f64() / transactions as f64
    })
    .await
    .unwrap()
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

fn main() {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let mut bus = Vec::new();
    let mut direct = Vec::new();
    for _ in 0..TRIALS {
        bus.push(runtime.block_on(bus_run()));
        direct.push(runtime.block_on(direct_run()));
    }
    let (bus, direct) = (median(bus), median(direct));
    println!(
        "bus {:.0} transactions/s, direct {:.0}/s: the bus adds {:.2} µs per transaction",
        1.0 / bus,
        1.0 / direct,
        (bus - direct) * 1e6
    );
}
