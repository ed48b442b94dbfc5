//! Issue 32 on MQTT: each value of a bus file's measurement published on
//! `<prefix>/measurements/<name>` as its JSON contract, on a real mosquitto.

mod common;

use std::time::Duration;

use common::{Broker, Watcher};
use optobus_bus::Bus;
use optobus_codec::value::Fixed;
use optobus_testkit::bus_files::{two_heads_gap, TwoHeadsGap};
use serde_json::Value as Json;

/// The measurement line of the tests (`optobus_testkit::bus_files`), polled every 50 ms, the
/// gap's statistics over 100 values.
fn gap_file() -> TwoHeadsGap {
    two_heads_gap().every("50ms").stats(100)
}

fn file(port: u16) -> common::File {
    let text = gap_file()
        .outputs(&format!(
            "{{ mqtt: {{ broker: 127.0.0.1:{port}, prefix: plant }} }}"
        ))
        .text();
    common::parse(&text)
}

/// An exact decimal of the JSON.
fn exact(json: &Json) -> Fixed {
    json["value"]
        .as_str()
        .expect("exact text")
        .parse()
        .expect("a decimal")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn a_measurement_is_published_as_its_json_with_the_inputs_it_was_made_of() {
    let broker = Broker::start("measurements").await;
    let watcher = Watcher::start(broker.port, "watcher-measurements", "plant/measurements/#").await;
    let file = file(broker.port);
    let bus = Bus::new(file.bus.clone());
    let _publisher = common::publish(&file, &bus);
    let _running = bus.start().expect("starts");
    assert!(
        watcher
            .wait_for(Duration::from_secs(15), |heard| heard.len() >= 5)
            .await,
        "no measurement on plant/measurements/gap"
    );
    for heard in watcher.on("plant/measurements/gap") {
        let json: Json = serde_json::from_str(&heard.payload).expect("JSON");
        assert!(!heard.retain);
        assert_eq!(json["measurement"], "gap");
        assert_eq!(json["value"]["unit"], "mm");
        // The value is the exact arithmetic of the inputs it carries.
        let (top, bottom) = (
            exact(&json["inputs"]["top.distance_1"]),
            exact(&json["inputs"]["bottom.distance_1"]),
        );
        let gap = exact(&json["value"]);
        let scale = gap.scale();
        let expected =
            20_000_000 - top.to_scale(scale).unwrap().raw() - bottom.to_scale(scale).unwrap().raw();
        assert_eq!(gap.raw(), expected, "{json}");
        assert!(["ll", "lo", "go", "hi", "hh"].contains(&json["judgement"].as_str().unwrap()));
        assert!(json["stats"]["count"].as_u64().unwrap() >= 1);
        assert!(json["skew_us"].is_u64());
    }
}

/// `template` rendered by Jinja2 (the engine Home Assistant renders it with) with `payload`
/// as `value_json`.
fn render(template: &str, payload: &str) -> String {
    use std::io::Write;
    use std::process::{Command, Stdio};
    let mut python = Command::new("python3")
        .args([
            "-c",
            "import jinja2, json, sys\n\
             given = json.load(sys.stdin)\n\
             template = jinja2.Environment().from_string(given['template'])\n\
             sys.stdout.write(template.render(value_json=json.loads(given['payload'])))",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("python3 runs");
    let given = serde_json::json!({ "template": template, "payload": payload });
    python
        .stdin
        .take()
        .unwrap()
        .write_all(given.to_string().as_bytes())
        .unwrap();
    let output = python.wait_with_output().unwrap();
    assert!(output.status.success(), "Jinja2 renders {template}");
    String::from_utf8(output.stdout).unwrap()
}

/// Publishes `payload` retained on `topic` and waits for the broker's acknowledgement.
async fn retain(port: u16, topic: &str, payload: &str) {
    use rumqttc::{AsyncClient, Event, MqttOptions, Packet, QoS};
    let (client, mut eventloop) =
        AsyncClient::new(MqttOptions::new("former-run", "127.0.0.1", port), 10);
    client
        .publish(topic, QoS::AtLeastOnce, true, payload.as_bytes().to_vec())
        .await
        .unwrap();
    let acknowledged = async {
        loop {
            if let Event::Incoming(Packet::PubAck(_)) = eventloop.poll().await.expect("connects") {
                return;
            }
        }
    };
    tokio::time::timeout(Duration::from_secs(10), acknowledged)
        .await
        .expect("the broker takes the retained message");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(all(peer_mosquitto, peer_jinja2)),
    ignore = "needs mosquitto (Debian package mosquitto) and Jinja2 (pip install jinja2)"
)]
async fn home_assistant_has_a_sensor_per_measurement_and_its_judgement_on_a_device_for_the_bus() {
    let broker = Broker::start("measurements-ha").await;
    // A former run's measurement, gone from the file since.
    let gone = "homeassistant/sensor/optobus_measurements/thickness/config";
    retain(broker.port, gone, r#"{"name": "thickness"}"#).await;
    let discovery = Watcher::start(broker.port, "ha-measurements", "homeassistant/#").await;
    let values = Watcher::start(broker.port, "ha-values", "plant/measurements/#").await;
    let text = gap_file()
        .measurement("ratio", "top.distance_1 / bottom.distance_1")
        .outputs(&format!(
            "{{ mqtt: {{ broker: 127.0.0.1:{}, prefix: plant, homeassistant: true }} }}",
            broker.port
        ))
        .text();
    let file = common::parse(&text);
    let bus = Bus::new(file.bus.clone());
    let _publisher = common::publish(&file, &bus);
    let _running = bus.start().expect("starts");

    let value_topic = "homeassistant/sensor/optobus_measurements/gap/config";
    let judgement_topic = "homeassistant/sensor/optobus_measurements/gap_judgement/config";
    let ratio_topic = "homeassistant/sensor/optobus_measurements/ratio/config";
    assert!(
        discovery
            .wait_for(Duration::from_secs(15), |heard| {
                [value_topic, judgement_topic, ratio_topic]
                    .iter()
                    .all(|t| heard.iter().any(|h| h.topic == *t))
                    && heard
                        .iter()
                        .any(|h| h.topic == gone && h.payload.is_empty())
            })
            .await,
        "no discovery of the measurements, or the former one not removed: {:?}",
        discovery.heard.lock().unwrap()
    );
    // What Home Assistant finds when it subscribes later: the retained configurations, and
    // none left of the former measurement.
    let late = Watcher::start(
        broker.port,
        "ha-late",
        "homeassistant/sensor/optobus_measurements/#",
    )
    .await;
    assert!(
        late.wait_for(Duration::from_secs(10), |heard| heard.len() >= 3)
            .await
    );
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert!(late.on(gone).is_empty(), "{:?}", late.on(gone));
    let config = |topic: &str| -> Json {
        let heard = late.on(topic);
        assert_eq!(heard.len(), 1, "{topic}: {heard:?}");
        assert!(heard[0].retain, "{topic} is retained");
        serde_json::from_str(&heard[0].payload).expect("JSON")
    };
    let (value, judgement, ratio) = (
        config(value_topic),
        config(judgement_topic),
        config(ratio_topic),
    );
    assert_eq!(value["unit_of_measurement"], "mm");
    assert_eq!(value["device_class"], "distance");
    assert_eq!(value["state_class"], "measurement");
    assert_eq!(value["state_topic"], "plant/measurements/gap");
    assert_eq!(judgement["device_class"], "enum");
    assert_eq!(
        judgement["options"],
        serde_json::json!(["ll", "lo", "go", "hi", "hh"])
    );
    assert_eq!(judgement["state_topic"], "plant/measurements/gap");
    // A plain number: no unit, no class; no limits: no judgement sensor.
    assert!(ratio.get("unit_of_measurement").is_none(), "{ratio}");
    assert!(ratio.get("device_class").is_none(), "{ratio}");
    assert!(discovery
        .on("homeassistant/sensor/optobus_measurements/ratio_judgement/config")
        .is_empty());
    // One device for the bus, available with the process.
    for config in [&value, &judgement, &ratio] {
        assert_eq!(config["device"], value["device"]);
        assert_eq!(
            config["availability"],
            serde_json::json!([{ "topic": "plant/status" }])
        );
    }
    assert_ne!(value["unique_id"], judgement["unique_id"]);

    // The state topic's JSON through the templates gives the value and the judgement.
    // A value (the simulated heads now and then read invalid).
    let valid = |heard: &common::Heard| {
        heard.topic == "plant/measurements/gap" && heard.payload.contains("\"judgement\":\"")
    };
    assert!(
        values
            .wait_for(Duration::from_secs(15), |heard| heard.iter().any(valid))
            .await
    );
    let heard = values.on("plant/measurements/gap");
    let payload = &heard.iter().find(|h| valid(h)).unwrap().payload;
    let json: Json = serde_json::from_str(payload).unwrap();
    let template = |config: &Json| config["value_template"].as_str().unwrap().to_owned();
    assert_eq!(
        render(&template(&value), payload),
        json["value"]["value"].as_str().unwrap()
    );
    assert_eq!(
        render(&template(&judgement), payload),
        json["judgement"].as_str().unwrap()
    );
    // An invalid value: Home Assistant's `None`, shown as unknown.
    let invalid =
        r#"{"measurement": "gap", "value": null, "reason": "top offline", "judgement": null}"#;
    assert_eq!(render(&template(&value), invalid), "None");
    assert_eq!(render(&template(&judgement), invalid), "None");
}
