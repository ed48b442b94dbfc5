//! Floods from the broker against a running bus (issue 28, points 2, 3 and 5): the polls'
//! samples per second during each flood over their rate just before it (the anchor, measured
//! in the same run, floods and quiet windows interleaved), and the process's memory after
//! each.
//!
//! A simulated line polls one device every 20 ms; the publisher takes writes and has Home
//! Assistant discovery on. Each round measures, for each flood, a quiet window and then a
//! window that starts with the flood:
//!
//! - 10,000 writes on `/set` (valid values, QoS 1, as fast as a client sends them);
//! - one 262,060-byte and one 1,000,000-byte payload on `/set`;
//! - 20,000 `online` on `homeassistant/status`.
//!
//! Samples are counted twice: as the bus emits them (the polls) and as a subscriber hears
//! them from mosquitto (publishing). Memory is this process's (bus, publisher, the flooding
//! client and the subscriber together) from `/proc/self/status`. `cargo bench -p optobus-mqtt
//! --bench floods`.

#[path = "../tests/common/mod.rs"]
mod common;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::{Broker, Watcher};
use optobus_bus::{Bus, Event};
use optobus_mqtt::{Counts, Publisher};
use rumqttc::{AsyncClient, MqttOptions, QoS};

const WINDOW: Duration = Duration::from_secs(3);
const ROUNDS: usize = 3;
const SAMPLE_TOPIC: &str = "plant/top/distance_1";

fn file(port: u16) -> common::File {
    common::parse(&common::top_alone(
        "poll: [{ read: distance_1, every: 20ms }], writable: [light_power]",
        &format!("broker: 127.0.0.1:{port}, prefix: plant, client_id: hall-2, homeassistant: true"),
    ))
}

/// `VmRSS` and `VmHWM` of this process, in MB.
fn memory() -> (f64, f64) {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        status
            .lines()
            .find_map(|line| line.strip_prefix(name))
            .and_then(|rest| rest.split_whitespace().next()?.parse::<f64>().ok())
            .map_or(f64::NAN, |kb| kb / 1024.0)
    };
    (field("VmRSS:"), field("VmHWM:"))
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Flood {
    Writes,
    LargePayloads,
    Births,
}

impl Flood {
    const ALL: [Self; 3] = [Self::Writes, Self::LargePayloads, Self::Births];

    fn name(self) -> &'static str {
        match self {
            Self::Writes => "10,000 writes on /set",
            Self::LargePayloads => "262 KB and 1 MB payloads on /set",
            Self::Births => "20,000 homeassistant/status",
        }
    }

    async fn send(self, client: &AsyncClient) {
        match self {
            Self::Writes => {
                for n in 0..10_000 {
                    let tenths = 10 + n % 990;
                    let value = format!("{}.{} %", tenths / 10, tenths % 10);
                    let _ = client
                        .publish("plant/top/light_power/set", QoS::AtLeastOnce, false, value)
                        .await;
                }
            }
            Self::LargePayloads => {
                for size in [262_060, 1_000_000] {
                    let _ = client
                        .publish(
                            "plant/top/light_power/set",
                            QoS::AtLeastOnce,
                            false,
                            "9".repeat(size),
                        )
                        .await;
                }
            }
            Self::Births => {
                for _ in 0..20_000 {
                    let _ = client
                        .publish("homeassistant/status", QoS::AtLeastOnce, false, "online")
                        .await;
                }
            }
        }
    }
}

/// Samples counted so far: emitted by the bus, heard from the broker.
struct Tally {
    polled: Arc<AtomicU64>,
    watcher: Watcher,
}

impl Tally {
    fn now(&self) -> (u64, u64) {
        (
            self.polled.load(Ordering::Relaxed),
            self.watcher.on(SAMPLE_TOPIC).len() as u64,
        )
    }

    /// Samples per second polled and heard over `WINDOW`, `flood` sent at its start.
    async fn window(&self, flood: Option<(Flood, &AsyncClient)>) -> (f64, f64) {
        let (polled, heard) = self.now();
        let start = Instant::now();
        if let Some((flood, client)) = flood {
            flood.send(client).await;
        }
        tokio::time::sleep(WINDOW.saturating_sub(start.elapsed())).await;
        let (polled_after, heard_after) = self.now();
        let seconds = start.elapsed().as_secs_f64();
        (
            (polled_after - polled) as f64 / seconds,
            (heard_after - heard) as f64 / seconds,
        )
    }
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// Waits until the publisher has nothing of a flood left to do (its write and control
/// counts stand still and nothing control waits; samples go on being published meanwhile).
async fn settled(publisher: &Publisher) -> Counts {
    let flood = |c: &Counts| {
        (
            c.writes_taken + c.writes_busy + c.writes_too_large,
            c.homeassistant_births,
            c.control_queued,
        )
    };
    let mut last = flood(&publisher.counts());
    loop {
        tokio::time::sleep(Duration::from_millis(300)).await;
        let counts = publisher.counts();
        if counts.control_queued == 0 && flood(&counts) == last {
            return counts;
        }
        last = flood(&counts);
    }
}

fn main() {
    if !common::mosquitto_installed() {
        return;
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("a runtime");
    runtime.block_on(async {
        println!("load average at start: {}", optobus_testkit::load_average());
        let broker = Broker::start("bench-floods").await;
        let file = file(broker.port);
        let bus = Bus::new(file.bus.clone());
        let mut events = bus.subscribe();
        let (running, publisher) = common::start_taking_writes(bus, &file);
        let polled = Arc::new(AtomicU64::new(0));
        {
            let polled = Arc::clone(&polled);
            tokio::spawn(async move {
                loop {
                    match events.recv().await {
                        Ok(Event::Sample(_)) => {
                            polled.fetch_add(1, Ordering::Relaxed);
                        }
                        Ok(_) | Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => {}
                        Err(_) => return,
                    }
                }
            });
        }
        let tally = Tally {
            polled,
            watcher: Watcher::start(broker.port, "bench-floods-watcher", SAMPLE_TOPIC).await,
        };
        while !publisher.counts().connected {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        tokio::time::sleep(Duration::from_secs(1)).await;
        let mut options = MqttOptions::new("bench-floods-controller", "127.0.0.1", broker.port);
        options.set_max_packet_size(2 << 20, 2 << 20);
        let (client, mut eventloop) = AsyncClient::new(options, 1000);
        tokio::spawn(async move {
            loop {
                if eventloop.poll().await.is_err() {
                    tokio::time::sleep(Duration::from_millis(50)).await;
                }
            }
        });
        let (rss, hwm) = memory();
        println!("memory before the floods: VmRSS {rss:.1} MB, VmHWM {hwm:.1} MB");

        let mut ratios: Vec<(Vec<f64>, Vec<f64>)> = vec![(Vec::new(), Vec::new()); 3];
        for round in 1..=ROUNDS {
            for (index, flood) in Flood::ALL.into_iter().enumerate() {
                let (quiet_polled, quiet_heard) = tally.window(None).await;
                let (flood_polled, flood_heard) = tally.window(Some((flood, &client))).await;
                let counts = settled(&publisher).await;
                let (rss, hwm) = memory();
                let polled_ratio = flood_polled / quiet_polled;
                let heard_ratio = flood_heard / quiet_heard;
                ratios[index].0.push(polled_ratio);
                ratios[index].1.push(heard_ratio);
                println!(
                    "round {round}, {}: polled {flood_polled:.1}/s over {quiet_polled:.1}/s \
                     quiet = {polled_ratio:.2}; heard {flood_heard:.1}/s over \
                     {quiet_heard:.1}/s = {heard_ratio:.2}; VmRSS {rss:.1} MB, VmHWM {hwm:.1} MB",
                    flood.name()
                );
                println!("  {counts:?}");
            }
        }
        println!(
            "\nmedians of {ROUNDS} rounds (window {WINDOW:?}, load at end {}):",
            optobus_testkit::load_average()
        );
        for (flood, (polled, heard)) in Flood::ALL.into_iter().zip(&mut ratios) {
            println!(
                "  {}: polls kept {:.2} of their rate, samples heard {:.2}",
                flood.name(),
                median(polled),
                median(heard)
            );
        }
        let (rss, hwm) = memory();
        println!("memory at the end: VmRSS {rss:.1} MB, VmHWM {hwm:.1} MB");
        let counts = publisher.counts();
        println!("{counts:?}");
        publisher.stop(Duration::from_secs(1)).await;
        running.stop();
    });
}
