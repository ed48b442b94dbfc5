//! Seeded network cuts between the publisher and a real mosquitto, through the proxy of
//! `common/proxy.rs`: messages handed to the MQTT client around a broken connection are neither
//! lost nor sent under another message's packet id, and drops are counted exactly.
//!
//! Each case names its seed; the proxy draws every cut from it (where in the byte stream, which
//! way, how long a hang), in the order connections come. The traffic itself is not the same
//! from run to run (it follows the scheduler and the machine), so a seed fixes the faults, not
//! the exact bytes they fall into. `OPTOBUS_MQTT_FAULT_SEED=N` runs every case with seed `N`
//! instead; every assertion message names the seed.
//!
//! What each QoS lets a test assert:
//! - QoS 1: every sample the bus emitted is heard by a subscriber at least once; each payload
//!   heard on a topic is one the bus emitted for that topic; each sample is counted published
//!   exactly once; beyond the queue, `heard + dropped == emitted + both`, where `both` are the
//!   samples the broker took whose acknowledgement the cut kept from the publisher (the proxy
//!   counts them: it reads the packets it passes), which go back to the queue and out of it.
//! - QoS 0: the broker acknowledges nothing, so a sample written into a connection that is then
//!   cut is lost, counted as published (the client wrote it). Asserted: each sample written
//!   once (`published + dropped == emitted`), heard at most once, never heard with another's
//!   payload, no dropped sample heard, and the samples not heard are at most one run of
//!   consecutive ones per cut (a cut loses what was written just before it, nothing else).

mod common;

use std::collections::{HashMap, HashSet};
use std::time::Duration;

use common::proxy::{Connection, Cut, Frames, Passed, Plan, Proxy};
use common::{Broker, Watcher};
use optobus_bus::{rfc3339, Bus, Event};
use optobus_mqtt::{Counts, Publisher};
use tokio::sync::broadcast::{error::RecvError, Receiver};
use tokio::sync::oneshot;
use tokio::task::JoinHandle;

/// Replaces every case's seed.
const SEED_VARIABLE: &str = "OPTOBUS_MQTT_FAULT_SEED";
/// How long the bus runs under cuts.
const RUN: Duration = Duration::from_secs(3);
/// A queue no run here fills.
const LARGE_QUEUE: usize = 100_000;
/// A queue a long outage overflows many times over.
const SMALL_QUEUE: usize = 50;

fn seed(case: u64) -> u64 {
    match std::env::var(SEED_VARIABLE) {
        Ok(text) => text
            .trim()
            .parse()
            .unwrap_or_else(|_| panic!("{SEED_VARIABLE}={text:?} is no seed (a u64)")),
        Err(_) => case,
    }
}

/// Three sensors polled every 5 ms on one simulated line: about a thousand samples a second.
fn bus_file(port: u16, qos: u8, queue: usize) -> common::File {
    let text = format!(
        "
lines:
  - {{ name: rs485, simulated: true, baud: 921600, any_format: true }}
devices:
  - {{ name: a, model: p-series, slave: 1, poll: [{{ read: measurements, every: 5ms }}] }}
  - {{ name: b, model: p-series, slave: 2, poll: [{{ read: measurements, every: 5ms }}] }}
  - {{ name: c, model: p-series, slave: 3, poll: [{{ read: measurements, every: 5ms }}] }}
outputs:
  mqtt: {{ broker: 127.0.0.1:{port}, qos: {qos}, queue: {queue} }}
"
    );
    common::parse(&text)
}

/// A sample as the bus emitted it, with the payload the publisher makes of it.
#[derive(Clone, Debug)]
struct Emitted {
    topic: String,
    time: String,
    payload: String,
}

/// Keeps every sample the bus emits, in order, until told to stop.
struct Recorder {
    task: JoinHandle<(Vec<Emitted>, u64)>,
    stop: oneshot::Sender<()>,
}

impl Recorder {
    fn start(mut events: Receiver<Event>) -> Self {
        let (stop, mut stopped) = oneshot::channel();
        let task = tokio::spawn(async move {
            let mut emitted = Vec::new();
            let mut missed = 0;
            let keep = |event: Event, emitted: &mut Vec<Emitted>| {
                if let Event::Sample(sample) = event {
                    emitted.push(Emitted {
                        topic: format!("optobus/{}/{}", sample.source.device, sample.register.name),
                        time: rfc3339(sample.replied),
                        payload: optobus_mqtt::sample_json(&sample).to_string(),
                    });
                }
            };
            loop {
                tokio::select! {
                    biased;
                    event = events.recv() => match event {
                        Ok(event) => keep(event, &mut emitted),
                        Err(RecvError::Lagged(n)) => missed += n,
                        Err(RecvError::Closed) => break,
                    },
                    _ = &mut stopped => break,
                }
            }
            loop {
                match events.try_recv() {
                    Ok(event) => keep(event, &mut emitted),
                    Err(tokio::sync::broadcast::error::TryRecvError::Lagged(n)) => missed += n,
                    Err(_) => break,
                }
            }
            (emitted, missed)
        });
        Self { task, stop }
    }

    /// The samples emitted, and how many events it missed.
    async fn finish(self) -> (Vec<Emitted>, u64) {
        let _ = self.stop.send(());
        self.task.await.expect("the recorder runs")
    }
}

/// What a run gave.
struct Outcome {
    context: String,
    emitted: Vec<Emitted>,
    /// Samples heard, (topic, payload), in the order heard.
    heard: Vec<(String, String)>,
    counts: Counts,
    connections: Vec<Connection>,
}

impl Outcome {
    /// Each emitted sample's (topic, time), in the order emitted.
    fn keys(&self) -> Vec<(String, String)> {
        self.emitted
            .iter()
            .map(|e| (e.topic.clone(), e.time.clone()))
            .collect()
    }

    /// How many times each sample was heard, by (topic, time).
    fn heard_times(&self) -> HashMap<(String, String), usize> {
        let mut times = HashMap::new();
        for (topic, payload) in &self.heard {
            let json: serde_json::Value = serde_json::from_str(payload).unwrap_or_else(|e| {
                panic!("{}: {topic} carried no JSON ({e}): {payload}", self.context)
            });
            let time = json["time"].as_str().unwrap_or_default().to_owned();
            *times.entry((topic.clone(), time)).or_insert(0) += 1;
        }
        times
    }

    /// Connections the proxy cut.
    fn cut(&self) -> Vec<&Connection> {
        self.connections
            .iter()
            .filter(|c| c.cut.is_some() && c.ended.as_deref().is_some_and(|e| e.contains("cut")))
            .collect()
    }

    fn summary(&self) -> String {
        let cuts: Vec<String> = self
            .cut()
            .iter()
            .map(|c| {
                format!(
                    "{:?}: {}; passed {} PUBLISH ({} in the hang), {} PUBACK; {} taken, PUBACK withheld",
                    c.cut.unwrap(),
                    c.ended.as_deref().unwrap_or(""),
                    c.published.len(),
                    c.published_in_hang,
                    c.acknowledged.len(),
                    c.unacknowledged().len()
                )
            })
            .collect();
        format!(
            "{}: {} samples emitted, {} heard, {:?}; {} connections ({} refused), {} cut:\n  {}",
            self.context,
            self.emitted.len(),
            self.heard.len(),
            self.counts,
            self.connections.len(),
            self.connections.iter().filter(|c| c.refused).count(),
            cuts.len(),
            cuts.join("\n  ")
        )
    }

    /// Every payload heard on a sample topic is one the bus emitted for that topic, to the
    /// byte: no sample went out with another's payload.
    fn assert_payloads_are_the_bus_own(&self) {
        let emitted: HashSet<(&str, &str)> = self
            .emitted
            .iter()
            .map(|e| (e.topic.as_str(), e.payload.as_str()))
            .collect();
        let foreign: Vec<&(String, String)> = self
            .heard
            .iter()
            .filter(|(topic, payload)| !emitted.contains(&(topic.as_str(), payload.as_str())))
            .collect();
        assert!(
            foreign.is_empty(),
            "{} payloads heard that the bus never emitted on their topic, first {:?}\n{}",
            foreign.len(),
            foreign.first(),
            self.summary()
        );
    }

    /// The emitted samples not heard, as runs of consecutive ones: (first index, length).
    fn runs_not_heard(&self) -> Vec<(usize, usize)> {
        let heard = self.heard_times();
        let mut runs: Vec<(usize, usize)> = Vec::new();
        for (index, key) in self.keys().iter().enumerate() {
            if heard.contains_key(key) {
                continue;
            }
            match runs.last_mut() {
                Some((first, length)) if *first + *length == index => *length += 1,
                _ => runs.push((index, 1)),
            }
        }
        runs
    }
}

/// Runs the bus for [`RUN`] through a proxy cutting as `plan` says, then lets the publisher
/// empty its queue and the subscriber hear what the broker has.
async fn run(name: &str, qos: u8, queue: usize, plan: Plan) -> Outcome {
    let context = format!(
        "{name}: QoS {qos}, queue {queue}, seed {} (rerun: {SEED_VARIABLE}={} cargo test -p optobus-mqtt --test faults {name})",
        plan.seed, plan.seed
    );
    let broker = Broker::start(&format!("faults-{}", name.replace("::", "-"))).await;
    let proxy = Proxy::start(broker.port, &plan).await;
    let watcher = Watcher::start(broker.port, &format!("watcher-{name}"), "optobus/#").await;
    let file = bus_file(proxy.port, qos, queue);
    let bus = Bus::new(file.bus.clone());
    let recorder = Recorder::start(bus.subscribe());
    let publisher = common::publish(&file, &bus);
    let running = bus.start().expect("the bus starts");
    tokio::time::sleep(RUN).await;
    proxy.calm().await;
    running.stop();
    wait_until_idle(&publisher, &context, &proxy).await;
    let (emitted, recorder_missed) = recorder.finish().await;
    assert_eq!(
        recorder_missed, 0,
        "{context}: the test's own record of the bus missed events"
    );
    // The last sample emitted is written last, after the last cut: once the subscriber has
    // heard it, it has heard all the broker took (one connection keeps its order), and the
    // publisher has taken in every sample.
    let last = emitted.last().expect("the bus emitted samples").clone();
    watcher
        .wait_for(Duration::from_secs(15), |heard| {
            heard
                .iter()
                .any(|h| h.topic == last.topic && h.payload == last.payload)
        })
        .await;
    wait_until_idle(&publisher, &context, &proxy).await;
    let counts = publisher.counts();
    let heard = watcher
        .heard
        .lock()
        .unwrap()
        .iter()
        .filter(|h| is_sample(&h.topic))
        .map(|h| (h.topic.clone(), h.payload.clone()))
        .collect();
    let outcome = Outcome {
        context,
        emitted,
        heard,
        counts,
        connections: proxy.connections(),
    };
    println!("{}", outcome.summary());
    assert_eq!(
        outcome.counts.missed_events,
        0,
        "the publisher missed bus events\n{}",
        outcome.summary()
    );
    assert!(
        !outcome.cut().is_empty(),
        "no connection was cut: the case tests nothing\n{}",
        outcome.summary()
    );
    outcome
}

fn is_sample(topic: &str) -> bool {
    topic != "optobus/status" && !topic.ends_with("/availability")
}

async fn wait_until_idle(publisher: &Publisher, context: &str, proxy: &Proxy) {
    for _ in 0..1000 {
        let counts = publisher.counts();
        if counts.queued == 0 && counts.in_flight == 0 && counts.connected {
            return;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let cuts: Vec<String> = proxy
        .connections()
        .iter()
        .filter_map(|c| Some(format!("{:?}: {}", c.cut?, c.ended.as_deref()?)))
        .collect();
    panic!(
        "{context}: the publisher did not empty its queue in 20 s: {:?}\ncuts:\n  {}",
        publisher.counts(),
        cuts.join("\n  ")
    );
}

/// Many short cuts, each followed at once by the reconnection; the queue never fills.
fn many_cuts(seed: u64, qos: u8) -> Plan {
    Plan {
        seed,
        cuts: 16,
        // QoS 0 has no PUBACK to cut into.
        weights: if qos == 1 { [2, 1, 1] } else { [3, 0, 1] },
        to_broker: 2_000..60_000,
        to_client: 8..600,
        hold_ms: 150..400,
        outage: Duration::ZERO,
    }
}

/// At QoS 1 through many cuts: every sample arrives, none with another's payload, none
/// dropped, each counted published once.
async fn qos1_through_cuts(name: &str, case_seed: u64) {
    let plan = many_cuts(seed(case_seed), 1);
    let outcome = run(name, 1, LARGE_QUEUE, plan).await;
    outcome.assert_payloads_are_the_bus_own();
    let heard = outcome.heard_times();
    let lost: Vec<(String, String)> = outcome
        .keys()
        .into_iter()
        .filter(|key| !heard.contains_key(key))
        .collect();
    assert!(
        lost.is_empty(),
        "{} of {} samples never heard, first {:?}; runs not heard (index, length) {:?}\n{}",
        lost.len(),
        outcome.emitted.len(),
        lost.first(),
        outcome.runs_not_heard(),
        outcome.summary()
    );
    assert_eq!(outcome.counts.dropped, 0, "{}", outcome.summary());
    assert_eq!(
        outcome.counts.published,
        outcome.emitted.len() as u64,
        "each sample acknowledged and counted once\n{}",
        outcome.summary()
    );
}

/// At QoS 0 through many cuts: each sample written once, heard at most once and with its own
/// payload; what is lost was written into a connection just before its cut.
async fn qos0_through_cuts(name: &str, case_seed: u64) {
    let plan = many_cuts(seed(case_seed), 0);
    let outcome = run(name, 0, LARGE_QUEUE, plan).await;
    outcome.assert_payloads_are_the_bus_own();
    assert_eq!(outcome.counts.dropped, 0, "{}", outcome.summary());
    assert_eq!(
        outcome.counts.published,
        outcome.emitted.len() as u64,
        "each sample written once\n{}",
        outcome.summary()
    );
    let twice: Vec<_> = outcome
        .heard_times()
        .into_iter()
        .filter(|(_, times)| *times > 1)
        .collect();
    assert!(
        twice.is_empty(),
        "{} samples heard more than once at QoS 0, first {:?}\n{}",
        twice.len(),
        twice.first(),
        outcome.summary()
    );
    let runs = outcome.runs_not_heard();
    assert!(
        runs.len() <= outcome.cut().len(),
        "samples not heard in {} runs (index, length) {runs:?}, more than the {} cuts\n{}",
        runs.len(),
        outcome.cut().len(),
        outcome.summary()
    );
    let lost: usize = runs.iter().map(|(_, length)| length).sum();
    println!("QoS 0: {lost} samples lost in {} runs at cuts", runs.len());
}

/// One hang then cut, then the broker unreachable for a second while the bus polls on: the
/// queue overflows, and every sample is heard or counted dropped.
async fn beyond_the_queue(name: &str, case_seed: u64, qos: u8) {
    let plan = Plan {
        seed: seed(case_seed),
        cuts: 1,
        weights: [0, 0, 1],
        to_broker: 20_000..80_000,
        to_client: 8..600,
        hold_ms: 200..300,
        outage: Duration::from_secs(1),
    };
    let outcome = run(name, qos, SMALL_QUEUE, plan).await;
    outcome.assert_payloads_are_the_bus_own();
    let heard = outcome.heard_times();
    let emitted = outcome.emitted.len() as u64;
    let dropped = outcome.counts.dropped;
    let cut = outcome.cut();
    assert!(dropped > 0, "the queue overflowed\n{}", outcome.summary());
    // Taken by the broker, its acknowledgement held back: sent again after the reconnection,
    // or (here, the queue overflowing) dropped from the front of the queue though heard.
    let both: u64 = cut.iter().map(|c| c.unacknowledged().len() as u64).sum();
    if qos == 1 {
        assert_eq!(
            heard.len() as u64 + dropped,
            emitted + both,
            "heard (distinct) + dropped == emitted + taken but not acknowledged ({both})\n{}",
            outcome.summary()
        );
        assert_eq!(
            outcome.counts.published + dropped,
            emitted,
            "each sample counted published or dropped, once\n{}",
            outcome.summary()
        );
    } else {
        assert_eq!(
            both,
            0,
            "no acknowledgement at QoS 0\n{}",
            outcome.summary()
        );
        assert_eq!(
            outcome.counts.published + dropped,
            emitted,
            "each sample written or dropped, once\n{}",
            outcome.summary()
        );
        assert!(
            heard.values().all(|times| *times == 1),
            "a sample heard twice at QoS 0\n{}",
            outcome.summary()
        );
        // A dropped sample was never written: none of them is heard.
        assert!(
            heard.len() as u64 + dropped <= emitted,
            "heard (distinct) {} + dropped {dropped} > emitted {emitted}: a dropped sample was heard\n{}",
            heard.len(),
            outcome.summary()
        );
        println!(
            "QoS 0: {} samples written into the cut connection and lost",
            emitted - heard.len() as u64 - dropped
        );
    }
    // Drop-oldest: what is not heard is one run of consecutive samples.
    let runs = outcome.runs_not_heard();
    assert_eq!(
        runs.len(),
        1,
        "samples not heard (index, length): {runs:?}\n{}",
        outcome.summary()
    );
}

mod qos1_through_cuts {
    macro_rules! seeds {
        ($($name:ident: $seed:literal,)*) => {$(
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            #[cfg_attr(not(peer_mosquitto), ignore = "mosquitto is not installed (Debian package mosquitto)")]
            async fn $name() {
                super::qos1_through_cuts(concat!("qos1_through_cuts::", stringify!($name)), $seed).await;
            }
        )*};
    }
    seeds! {
        seed_1: 1,
        seed_7: 7,
        seed_42: 42,
        seed_1009: 1009,
    }
}

mod qos0_through_cuts {
    macro_rules! seeds {
        ($($name:ident: $seed:literal,)*) => {$(
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            #[cfg_attr(not(peer_mosquitto), ignore = "mosquitto is not installed (Debian package mosquitto)")]
            async fn $name() {
                super::qos0_through_cuts(concat!("qos0_through_cuts::", stringify!($name)), $seed).await;
            }
        )*};
    }
    seeds! {
        seed_2: 2,
        seed_11: 11,
        seed_99: 99,
        seed_2024: 2024,
    }
}

mod beyond_the_queue {
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    #[cfg_attr(
        not(peer_mosquitto),
        ignore = "mosquitto is not installed (Debian package mosquitto)"
    )]
    async fn qos1_seed_5() {
        super::beyond_the_queue("beyond_the_queue::qos1_seed_5", 5, 1).await;
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    #[cfg_attr(
        not(peer_mosquitto),
        ignore = "mosquitto is not installed (Debian package mosquitto)"
    )]
    async fn qos0_seed_6() {
        super::beyond_the_queue("beyond_the_queue::qos0_seed_6", 6, 0).await;
    }
}

#[test]
fn the_proxy_reads_packets_wherever_the_bytes_break() {
    // PUBLISH QoS 1 "a/b" id 7 payload "xy", then a PUBACK of 7.
    let bytes = [
        0x32, 9, 0, 3, b'a', b'/', b'b', 0, 7, b'x', b'y', 0x40, 2, 0, 7,
    ];
    for split in 0..bytes.len() {
        let mut frames = Frames::default();
        let mut packets = frames.push(&bytes[..split]);
        assert_eq!(frames.begun().is_some(), split > 0 && split != 11);
        packets.extend(frames.push(&bytes[split..]));
        assert_eq!(packets.len(), 2, "split at {split}");
        assert_eq!(
            packets[0].publish(),
            Some(Passed {
                topic: "a/b".into(),
                payload: "xy".into(),
                qos: 1,
                pkid: 7
            })
        );
        assert_eq!(packets[1].pkid(), Some(7));
        assert_eq!(frames.begun(), None);
    }
}

#[test]
fn the_same_seed_plans_the_same_cuts() {
    let plan = many_cuts(3, 1);
    assert_eq!(plan.cuts(), plan.cuts());
    assert_ne!(plan.cuts(), many_cuts(4, 1).cuts());
    assert!(plan.cuts().iter().all(|cut| match cut {
        Cut::ToBroker(bytes) => (2_000..60_000).contains(bytes),
        Cut::ToClient(bytes) => (8..600).contains(bytes),
        Cut::Hang(bytes, hold) =>
            (2_000..60_000).contains(bytes) && *hold >= Duration::from_millis(150),
    }));
}
