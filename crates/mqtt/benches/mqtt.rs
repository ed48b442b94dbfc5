//! The figures of the MQTT output, against anchors measured in the same run on the same local
//! mosquitto (trials interleaved):
//!
//! - samples per second through the publisher at QoS 0 and QoS 1, over a minimal publisher
//!   with the same client crate: the same samples, each made into the same payload
//!   (`sample_json`) and published in a loop (one topic per register); also over the same
//!   loop with every payload made before the clock starts, the client's bare speed;
//! - reply-to-delivery latency at 1,000 samples a second (from a sample's reply time to its
//!   arrival at a subscriber in this process: publisher, broker and subscriber together);
//! - the broker stopped for 10 s and restarted during a run, with a queue that holds the
//!   outage and with one that does not: samples lost, drops counted, availability again.
//!
//! Samples are bus events made here (no line in the way): `cargo bench -p optobus-mqtt`.

#[path = "../tests/common/mod.rs"]
mod common;

use std::collections::HashSet;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime};

use common::{Broker, Watcher};
use optobus_bus::{rfc3339, BusFile, Catalogue, DeviceId, Event, Sample};
use optobus_codec::value::{Fixed, Scale};
use optobus_device::RegisterInfo;
use optobus_inspect::Value;
use optobus_mqtt::{MqttConfig, Publisher};
use rumqttc::{AsyncClient, Event as MqttEvent, MqttOptions, Outgoing, Packet, QoS};
use tokio::sync::broadcast;

const P: &optobus_device::DeviceInfo = &optobus_p_series::DEVICE;
const SAMPLES: usize = 50_000;
const TRIALS: usize = 7;

/// The bench's bus file and its `mqtt` settings.
fn file(port: u16, qos: u8, queue: usize) -> (BusFile, MqttConfig) {
    let text = format!(
        "lines: [{{ name: rs485, simulated: true }}]\n\
         devices: [{{ name: top, model: p-series, slave: 1 }}]\n\
         outputs: {{ mqtt: {{ broker: 127.0.0.1:{port}, qos: {qos}, queue: {queue} }} }}\n"
    );
    let mut mqtt = None;
    let file = BusFile::parse_with(
        "bench.yaml",
        &text,
        Path::new("."),
        &Catalogue::new([P]),
        &mut mqtt,
    )
    .unwrap_or_else(|e| panic!("{}", e.render()));
    (file, mqtt.expect("the file has `mqtt`"))
}

fn registers() -> Vec<&'static RegisterInfo> {
    [
        "distance_1",
        "distance_2",
        "thickness",
        "statistic_1",
        "statistic_2",
    ]
    .iter()
    .map(|name| P.register(name).expect("a P series register"))
    .collect()
}

fn source() -> Arc<DeviceId> {
    Arc::new(DeviceId {
        device: "top".into(),
        model: P.model_name().to_string().into(),
        line: "rs485".into(),
        slave: 1,
    })
}

fn sample(source: &Arc<DeviceId>, register: &'static RegisterInfo, n: usize) -> Event {
    let now = SystemTime::now();
    Event::Sample(Arc::new(Sample {
        source: Arc::clone(source),
        register,
        value: Value::Quantity(
            Fixed::new(4_969_234 + n as i64, Scale::Decimal { exponent: -6 }),
            Some("mm"),
        ),
        requested: now,
        replied: now,
    }))
}

/// Samples per second through the publisher: all handed over, then until all are taken.
async fn through_publisher(port: u16, qos: u8) -> f64 {
    let (file, mqtt) = file(port, qos, SAMPLES * 2);
    let (events, receiver) = broadcast::channel(SAMPLES + 16);
    let publisher = Publisher::start(&mqtt, &file, receiver, None).expect("starts");
    while !publisher.counts().connected {
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    let source = source();
    let registers = registers();
    let start = Instant::now();
    for n in 0..SAMPLES {
        let _ = events.send(sample(&source, registers[n % registers.len()], n));
    }
    while publisher.counts().published < SAMPLES as u64 {
        tokio::time::sleep(Duration::from_micros(200)).await;
    }
    let rate = SAMPLES as f64 / start.elapsed().as_secs_f64();
    publisher.stop(Duration::from_secs(1)).await;
    rate
}

/// Samples per second of a minimal rumqttc publisher: the same samples, topics and payloads,
/// published in a loop, until the broker took them all.
async fn minimal(port: u16, qos: QoS, made: Payloads) -> f64 {
    let mut options = MqttOptions::new("bench-minimal", "127.0.0.1", port);
    options.set_inflight(100);
    let (client, mut eventloop) = AsyncClient::new(options, 64);
    let source = source();
    let registers = registers();
    let events: Vec<Event> = (0..SAMPLES)
        .map(|n| sample(&source, registers[n % registers.len()], n))
        .collect();
    let message = |event: &Event| {
        let Event::Sample(sample) = event else {
            unreachable!()
        };
        (
            format!("optobus/top/{}", sample.register.name),
            optobus_mqtt::sample_json(sample).to_string().into_bytes(),
        )
    };
    let beforehand: Vec<(String, Vec<u8>)> = match made {
        Payloads::Beforehand => events.iter().map(message).collect(),
        Payloads::InTheLoop => Vec::new(),
    };
    loop {
        if let Ok(MqttEvent::Incoming(Packet::ConnAck(_))) = eventloop.poll().await {
            break;
        }
    }
    let start = Instant::now();
    let sender = tokio::spawn(async move {
        if beforehand.is_empty() {
            for event in &events {
                let (topic, payload) = message(event);
                client.publish(topic, qos, false, payload).await.unwrap();
            }
        } else {
            for (topic, payload) in beforehand {
                client.publish(topic, qos, false, payload).await.unwrap();
            }
        }
        client
    });
    let mut taken = 0;
    while taken < SAMPLES {
        match eventloop.poll().await {
            Ok(MqttEvent::Incoming(Packet::PubAck(_))) if qos == QoS::AtLeastOnce => taken += 1,
            Ok(MqttEvent::Outgoing(Outgoing::Publish(_))) if qos == QoS::AtMostOnce => taken += 1,
            Ok(_) => {}
            Err(error) => panic!("minimal publisher: {error}"),
        }
    }
    let rate = SAMPLES as f64 / start.elapsed().as_secs_f64();
    let client = sender.await.unwrap();
    let _ = client.disconnect().await;
    let _ = tokio::time::timeout(Duration::from_millis(200), eventloop.poll()).await;
    rate
}

/// When the minimal publisher makes its payloads: in the loop, one per sample as the publisher
/// does (the anchor of the goal), or all before the clock starts (a bare client's speed).
#[derive(Clone, Copy)]
enum Payloads {
    InTheLoop,
    Beforehand,
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(|a, b| a.total_cmp(b));
    values[values.len() / 2]
}

async fn throughput(port: u16) {
    for (qos, name) in [(0u8, "QoS 0"), (1, "QoS 1")] {
        let mut ours = Vec::new();
        let mut anchor = Vec::new();
        let mut bare = Vec::new();
        let level = if qos == 0 {
            QoS::AtMostOnce
        } else {
            QoS::AtLeastOnce
        };
        for _ in 0..TRIALS {
            anchor.push(minimal(port, level, Payloads::InTheLoop).await);
            ours.push(through_publisher(port, qos).await);
            bare.push(minimal(port, level, Payloads::Beforehand).await);
        }
        let (ours, anchor, bare) = (median(&mut ours), median(&mut anchor), median(&mut bare));
        println!(
            "{name}: publisher {ours:>9.0} samples/s, minimal rumqttc publisher {anchor:>9.0}/s, \
             ratio {:.2}; with its payloads made beforehand {bare:>9.0}/s, ratio {:.2} \
             (median of {TRIALS} interleaved trials of {SAMPLES})",
            ours / anchor,
            ours / bare
        );
    }
}

/// Reply-to-delivery latency at 1,000 samples a second for 5 s, at QoS 1.
async fn latency(port: u16) {
    let watcher = Watcher::start(port, "bench-latency", "optobus/top/+").await;
    let (file, mqtt) = file(port, 1, 100_000);
    let (events, receiver) = broadcast::channel(4096);
    let publisher = Publisher::start(&mqtt, &file, receiver, None).unwrap();
    while !publisher.counts().connected {
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    let source = source();
    let registers = registers();
    let count = 5_000;
    let mut tick = tokio::time::interval(Duration::from_millis(1));
    for n in 0..count {
        tick.tick().await;
        let _ = events.send(sample(&source, registers[n % registers.len()], n));
    }
    watcher
        .wait_for(Duration::from_secs(20), |heard| {
            heard.iter().filter(|h| h.payload.starts_with('{')).count() >= count
        })
        .await;
    // Arrival is stamped as the watcher's task stores the message; the payload's time is the
    // sample's reply time.
    let heard = watcher.heard.lock().unwrap().clone();
    let mut latencies: Vec<f64> = heard
        .iter()
        .filter_map(|h| {
            let json: serde_json::Value = serde_json::from_str(&h.payload).ok()?;
            let sent: jiff::Timestamp = json["time"].as_str()?.parse().ok()?;
            let arrived: jiff::Timestamp = h.arrived.try_into().ok()?;
            Some((arrived - sent).as_secs_f64() * 1000.0)
        })
        .collect();
    latencies.sort_by(|a, b| a.total_cmp(b));
    let at = |q: f64| latencies[((latencies.len() - 1) as f64 * q) as usize];
    println!(
        "latency at 1000 samples/s, QoS 1, reply to a subscriber's receipt: p50 {:.3} ms, \
         p99 {:.3} ms, max {:.3} ms ({} of {count} heard)",
        at(0.5),
        at(0.99),
        at(1.0),
        latencies.len()
    );
    publisher.stop(Duration::from_secs(1)).await;
}

/// The broker stopped for 10 s and restarted while samples come at 500 a second.
async fn outage(queue: usize) {
    let mut broker = Broker::start("bench-outage").await;
    let watcher = Watcher::start(broker.port, "bench-outage", "optobus/#").await;
    let (file, mqtt) = file(broker.port, 1, queue);
    let (events, receiver) = broadcast::channel(4096);
    let publisher = Publisher::start(&mqtt, &file, receiver, None).unwrap();
    let source = source();
    let registers = registers();
    let mut sent = Vec::new();
    let mut tick = tokio::time::interval(Duration::from_millis(2));
    let started = Instant::now();
    let mut stopped = false;
    let mut restarted = false;
    let mut n = 0;
    while started.elapsed() < Duration::from_secs(14) {
        tick.tick().await;
        let event = sample(&source, registers[n % registers.len()], n);
        if let Event::Sample(s) = &event {
            sent.push(rfc3339(s.replied));
        }
        let _ = events.send(event);
        n += 1;
        if !stopped && started.elapsed() > Duration::from_secs(2) {
            broker.stop();
            stopped = true;
        }
        if !restarted && started.elapsed() > Duration::from_secs(12) {
            broker.run().await;
            restarted = true;
        }
    }
    let deadline = Instant::now() + Duration::from_secs(60);
    while Instant::now() < deadline {
        let counts = publisher.counts();
        if counts.connected && counts.queued == 0 && counts.in_flight == 0 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    tokio::time::sleep(Duration::from_secs(2)).await;
    let heard: HashSet<String> = watcher
        .heard
        .lock()
        .unwrap()
        .iter()
        .filter(|h| h.topic.starts_with("optobus/top/") && !h.topic.ends_with("availability"))
        .filter_map(|h| {
            let json: serde_json::Value = serde_json::from_str(&h.payload).ok()?;
            Some(json["time"].as_str()?.to_owned())
        })
        .collect();
    let missing = sent.iter().filter(|t| !heard.contains(*t)).count();
    let counts = publisher.counts();
    let online = watcher
        .on("optobus/status")
        .iter()
        .filter(|h| h.payload == "online")
        .count();
    println!(
        "broker away 10 s, queue {queue}: {} samples sent, {missing} not heard, {} dropped \
         (counted), {} requeued, {} connections, status online published {online} times",
        sent.len(),
        counts.dropped,
        counts.requeued,
        counts.connections
    );
    publisher.stop(Duration::from_secs(1)).await;
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() {
    println!("load average at start: {}", optobus_testkit::load_average());
    let broker = Broker::start("bench").await;
    throughput(broker.port).await;
    latency(broker.port).await;
    drop(broker);
    outage(10_000).await;
    outage(1_000).await;
    println!("load average at end: {}", optobus_testkit::load_average());
}
