//! A day at full rate with a paused clock: 8 devices of mixed families in memory (no line
//! timing, whose precise waits spin on the real clock), each polling its measurements every
//! 25 ms, about what a 115200 baud line carries (320 polls a second), with a subscriber
//! draining the events. tokio's clock is paused and moves on by itself whenever the line
//! waits for its next tick, so a simulated day takes minutes.
//!
//! Prints the resident set size (`/proc/self/statm`) after the first simulated minute, then
//! every simulated hour, and the first, last and largest, with the polls done (target: flat).
//! `OPTOBUS_BENCH_HOURS` shortens the day. Run with
//! `cargo bench -p optobus-bus --bench memory`.

mod common;

use std::time::{Duration, Instant};

use common::{bus_file, model_name, models, simulators};
use optobus_bus::{Bus, Event};
use tokio::sync::broadcast::error::RecvError;

const EVERY: &str = "25ms";

/// Resident set size in KiB.
fn rss_kib() -> u64 {
    let statm = std::fs::read_to_string("/proc/self/statm").unwrap_or_default();
    let pages: u64 = statm
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    pages * 4
}

async fn run(hours: u64) {
    let devices: Vec<String> = models()
        .iter()
        .enumerate()
        .map(|(i, model)| {
            format!(
                "{{ name: d{}, model: {}, slave: {}, poll: [{{ read: measurements, every: {EVERY} }}] }}",
                i + 1,
                model_name(model),
                i + 1
            )
        })
        .collect();
    let mut file = bus_file("serial: memory, baud: 115200", &devices);
    // In memory: no t3.5 and no transmit time.
    file.lines[0].format = None;
    let (stream, _server) = optobus_simulator::Slaves::new(simulators(&models())).duplex();
    let bus = Bus::new(file).with_stream("bench", stream);
    let mut events = bus.subscribe();
    let running = bus.start().expect("starts");
    let counter = tokio::spawn(async move {
        let (mut samples, mut lost, mut transactions) = (0u64, 0u64, 0u64);
        loop {
            match events.recv().await {
                Ok(Event::Sample(sample)) => {
                    samples += 1;
                    std::hint::black_box(sample);
                }
                Ok(Event::Line(stats)) => transactions = stats.transactions,
                Ok(_) => {}
                Err(RecvError::Lagged(n)) => lost += n,
                Err(RecvError::Closed) => return (samples, lost, transactions),
            }
        }
    });
    let wall = Instant::now();
    let simulated = tokio::time::Instant::now();
    tokio::time::sleep(Duration::from_secs(60)).await;
    let first = rss_kib();
    let mut largest = first;
    let mut last = first;
    println!("after 1 min: RSS {first} KiB");
    for hour in 1..=hours {
        tokio::time::sleep_until(simulated + Duration::from_secs(3600 * hour)).await;
        last = rss_kib();
        largest = largest.max(last);
        println!(
            "after {hour:>2} h: RSS {last} KiB  ({:.0} s of real time, load {})",
            wall.elapsed().as_secs_f64(),
            common::load()
        );
    }
    drop(running);
    let (samples, lost, transactions) = counter.await.unwrap();
    let seconds = simulated.elapsed().as_secs_f64();
    println!(
        "{hours} h simulated in {:.0} s: {transactions} transactions ({:.0}/s simulated), {samples} samples received, {lost} lost by the subscriber",
        wall.elapsed().as_secs_f64(),
        transactions as f64 / seconds,
    );
    println!(
        "RSS first {first} KiB, last {last} KiB, largest {largest} KiB: last / first {:.3}",
        last as f64 / first as f64
    );
}

fn main() {
    let hours = std::env::var("OPTOBUS_BENCH_HOURS")
        .ok()
        .and_then(|h| h.parse().ok())
        .unwrap_or(24);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .start_paused(true)
        .build()
        .unwrap();
    runtime.block_on(run(hours));
}
