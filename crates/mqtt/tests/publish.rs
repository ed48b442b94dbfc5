//! Samples, availability and the last will on a real mosquitto.

mod common;

use std::time::Duration;

use common::{parse as file, Broker, Watcher};
use optobus_bus::{rfc3339, Bus, Event};
use optobus_mqtt::Publisher;
use serde_json::Value as Json;

fn bus_text(port: u16) -> String {
    format!(
        "
lines:
  - {{ name: rs485, simulated: true, baud: 115200, any_format: true }}
devices:
  - {{ name: top, model: p-series, slave: 1, timeout: 100ms, poll: [{{ read: [light_power, measurements], every: 50ms }}] }}
  - {{ name: dead, model: ccs, slave: 3, timeout: 20ms, faults: \"drop=1,seed=1\", poll: [{{ read: measurements, every: 50ms }}] }}
outputs:
  mqtt: {{ broker: 127.0.0.1:{port}, prefix: plant/hall }}
"
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn samples_are_published_as_json_with_number_exact_text_unit_and_time() {
    let broker = Broker::start("samples").await;
    let watcher = Watcher::start(broker.port, "watcher-samples", "plant/#").await;
    let file = file(&bus_text(broker.port));
    let (running, publisher, mut events) = common::start_publishing(&file);
    running
        .simulator("top")
        .unwrap()
        .set("light_power", &[425])
        .unwrap();
    // The bus's own samples of distance_1, by their reply time.
    let mut distances = std::collections::HashMap::new();
    while distances.len() < 5 {
        if let Ok(Ok(Event::Sample(sample))) =
            tokio::time::timeout(Duration::from_secs(10), events.recv()).await
        {
            if sample.register.name == "distance_1" {
                distances.insert(rfc3339(sample.replied), sample.value.to_string());
            }
        }
    }
    assert!(
        watcher
            .wait_for(Duration::from_secs(10), |heard| {
                heard
                    .iter()
                    .filter(|h| h.topic == "plant/hall/top/distance_1")
                    .count()
                    >= 5
                    && heard.iter().any(|h| {
                        h.topic == "plant/hall/top/light_power" && h.payload.contains("42.5")
                    })
            })
            .await,
        "{:?}",
        watcher.heard.lock().unwrap()
    );
    // A distance: the number for consumers, the exact text and unit the bus decoded, the
    // reply's time; the same sample as the bus's own event.
    let mut matched = 0;
    for heard in watcher.on("plant/hall/top/distance_1") {
        let json: Json = serde_json::from_str(&heard.payload).expect("JSON");
        let text = json["text"].as_str().expect("text");
        assert_eq!(json["unit"], "mm");
        assert_eq!(json["value"].as_f64(), Some(text.parse::<f64>().unwrap()));
        assert!(!heard.retain, "samples are not retained");
        let time = json["time"].as_str().expect("time");
        assert!(time.parse::<jiff::Timestamp>().is_ok(), "RFC 3339: {time}");
        if let Some(shown) = distances.get(time) {
            assert_eq!(shown, &format!("{text} mm"));
            matched += 1;
        }
    }
    assert!(matched > 0, "no published sample matched the bus's own");
    // The first samples may predate the simulator's new power.
    let powers = watcher.on("plant/hall/top/light_power");
    let set = powers.iter().find(|h| h.payload.contains("42.5")).unwrap();
    let power: Json = serde_json::from_str(&set.payload).unwrap();
    assert_eq!(power["value"].as_f64(), Some(42.5));
    assert_eq!(power["text"], "42.5");
    assert_eq!(power["unit"], "%");
    assert!(publisher.counts().published > 0);
    running.stop();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn availability_follows_health_and_the_last_will_says_offline() {
    let broker = Broker::start("availability").await;
    let file = file(&bus_text(broker.port));
    let (running, publisher, _) = common::start_publishing(&file);
    // Retained: a subscriber that comes later still learns the state.
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let watcher = Watcher::start(broker.port, "watcher-availability", "plant/#").await;
    let last = |topic: &str| {
        watcher
            .on(topic)
            .last()
            .map(|h| (h.payload.clone(), h.retain))
    };
    assert!(
        watcher
            .wait_for(Duration::from_secs(10), |heard| {
                let has = |topic: &str, payload: &str| {
                    heard
                        .iter()
                        .any(|h| h.topic == topic && h.payload == payload)
                };
                has("plant/hall/status", "online")
                    && has("plant/hall/top/availability", "online")
                    && has("plant/hall/dead/availability", "offline")
            })
            .await,
        "{:?}",
        watcher.heard.lock().unwrap()
    );
    assert_eq!(last("plant/hall/status"), Some(("online".into(), true)));
    assert_eq!(
        last("plant/hall/dead/availability"),
        Some(("offline".into(), true)),
        "a device that never answers goes offline"
    );
    // The process goes away without a word: the broker publishes its will.
    drop(publisher);
    assert!(
        watcher
            .wait_for(Duration::from_secs(15), |heard| {
                heard
                    .iter()
                    .any(|h| h.topic == "plant/hall/status" && h.payload == "offline")
            })
            .await,
        "no last will: {:?}",
        watcher.on("plant/hall/status")
    );
    running.stop();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn a_clean_stop_says_every_device_is_offline() {
    let broker = Broker::start("clean-stop").await;
    let file = file(&bus_text(broker.port));
    let (running, publisher, _) = common::start_publishing(&file);
    let watcher = Watcher::start(broker.port, "watcher-running", "plant/hall/+/availability").await;
    assert!(
        watcher
            .hears(
                Duration::from_secs(10),
                "plant/hall/top/availability",
                |h| h.payload == "online"
            )
            .await,
        "{:?}",
        watcher.heard.lock().unwrap()
    );
    // The bus still polls while the publisher stops: no later sample says `online` again.
    publisher.stop(Duration::from_secs(5)).await;
    let after = Watcher::start(broker.port, "watcher-after", "plant/hall/#").await;
    let retained = ["status", "top/availability", "dead/availability"]
        .map(|topic| format!("plant/hall/{topic}"));
    assert!(
        after
            .wait_for(Duration::from_secs(10), |heard| retained
                .iter()
                .all(|topic| heard.iter().any(|h| h.topic == *topic)))
            .await,
        "{:?}",
        after.heard.lock().unwrap()
    );
    for topic in &retained {
        let heard: Vec<(String, bool)> = after
            .on(topic)
            .into_iter()
            .map(|h| (h.payload, h.retain))
            .collect();
        assert_eq!(heard, [("offline".to_owned(), true)], "{topic}");
    }
    running.stop();
}

#[tokio::test]
async fn secrets_are_never_in_debug_output() {
    std::env::set_var("OPTOBUS_TEST_MQTT_PASSWORD", "hunter2");
    let secret = optobus_mqtt::Secret::read(&optobus_mqtt::SecretSource::Env(
        "OPTOBUS_TEST_MQTT_PASSWORD".into(),
    ))
    .expect("set");
    assert_eq!(format!("{secret:?}"), "Secret(..)");
    let file = file(
        "
lines: [{ name: rs485, simulated: true }]
devices: [{ name: top, model: p-series, slave: 1 }]
outputs:
  mqtt:
    broker: 127.0.0.1:1
    username: gateway
    password: { env: OPTOBUS_TEST_MQTT_PASSWORD }
",
    );
    let config = file.mqtt.as_ref().unwrap();
    let bus = Bus::new(file.bus.clone());
    let publisher = Publisher::start(config, &file.bus, bus.subscribe(), None).expect("starts");
    for shown in [
        format!("{publisher:?}"),
        format!("{config:?}"),
        format!("{file:?}"),
    ] {
        assert!(!shown.contains("hunter2"), "{shown}");
    }
    let missing = optobus_mqtt::Secret::read(&optobus_mqtt::SecretSource::Env(
        "OPTOBUS_TEST_NO_SUCH_VARIABLE".into(),
    ))
    .expect_err("not set");
    assert_eq!(
        missing.to_string(),
        "the environment variable OPTOBUS_TEST_NO_SUCH_VARIABLE is not set"
    );
}

#[tokio::test]
async fn a_ca_file_without_a_certificate_is_refused_before_connecting() {
    let dir = std::env::temp_dir().join(format!("optobus-mqtt-ca-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("ca.pem"), "not a certificate\n").unwrap();
    let file = file(&format!(
        "
lines: [{{ name: rs485, simulated: true }}]
devices: [{{ name: top, model: p-series, slave: 1 }}]
outputs:
  mqtt: {{ broker: 127.0.0.1:1, ca: {} }}
",
        dir.join("ca.pem").display()
    ));
    let refused = Publisher::start(
        file.mqtt.as_ref().unwrap(),
        &file.bus,
        Bus::new(file.bus.clone()).subscribe(),
        None,
    )
    .expect_err("no certificate to trust");
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        refused.to_string().starts_with("MQTT TLS: ")
            && refused.to_string().contains("holds no PEM certificate"),
        "{refused}"
    );
}
