//! Home Assistant discovery on a real mosquitto: a device per sensor, an entity per polled
//! register with the unit, class and precision its spec gives, published again when Home
//! Assistant announces itself.

mod common;

use std::time::Duration;

use common::{Broker, Watcher};
use optobus_codec::value::Scale;
use rumqttc::QoS;
use serde_json::{json, Value as Json};

const P: &optobus_device::DeviceInfo = &optobus_p_series::DEVICE;

fn file(port: u16) -> common::File {
    let text = format!(
        "
lines:
  - {{ name: rs485, simulated: true, baud: 115200, any_format: true }}
devices:
  - name: top
    model: p-series
    slave: 7
    poll: [{{ read: [measurements, temperature, laser_enabled, median_filter_width], every: 100ms }}]
    writable: [light_power, median_filter_width, zero_position_1]
outputs:
  mqtt: {{ broker: 127.0.0.1:{port}, client_id: hall-2, homeassistant: true }}
"
    );
    common::parse(&text)
}

fn config(watcher: &Watcher, topic: &str) -> Json {
    let heard = watcher.on(topic);
    let last = heard
        .last()
        .unwrap_or_else(|| panic!("no {topic}: {:?}", watcher.heard.lock().unwrap()));
    serde_json::from_str(&last.payload).expect("JSON")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn home_assistant_gets_a_device_and_an_entity_per_polled_register() {
    let broker = Broker::start("discovery").await;
    let file = file(broker.port);
    let (running, _publisher, _) = common::start_publishing(&file);
    let watcher = Watcher::start(broker.port, "watcher-discovery", "homeassistant/#").await;
    let distance_topic = "homeassistant/sensor/hall-2_top/distance_1/config";
    assert!(
        watcher
            .hears(Duration::from_secs(10), distance_topic, |_| true)
            .await,
        "{:?}",
        watcher.heard.lock().unwrap()
    );
    let distance = config(&watcher, distance_topic);
    let register = P.register("distance_1").unwrap();
    let decimals = match register.scale {
        Some(Scale::Decimal { exponent }) => u64::from(exponent.unsigned_abs()),
        other => panic!("distance_1 has a decimal step: {other:?}"),
    };
    assert_eq!(distance["unit_of_measurement"], "mm");
    assert_eq!(distance["device_class"], "distance");
    assert_eq!(distance["state_class"], "measurement");
    assert_eq!(distance["suggested_display_precision"], decimals);
    assert_eq!(distance["state_topic"], "optobus/top/distance_1/state");
    assert_eq!(distance["value_template"], "{{ value_json.value }}");
    assert_eq!(distance["unique_id"], "hall-2_top_distance_1_sensor");
    assert_eq!(
        distance["availability"],
        json!([{ "topic": "optobus/status" }, { "topic": "optobus/top/availability" }])
    );
    assert_eq!(distance["availability_mode"], "all");
    assert_eq!(
        distance["device"],
        json!({ "identifiers": ["optobus_hall-2_rs485_7"], "name": "top", "model": P.title })
    );
    let temperature = config(
        &watcher,
        "homeassistant/sensor/hall-2_top/temperature/config",
    );
    assert_eq!(temperature["unit_of_measurement"], "°C");
    assert_eq!(temperature["device_class"], "temperature");
    let laser = config(
        &watcher,
        "homeassistant/binary_sensor/hall-2_top/laser_enabled/config",
    );
    assert_eq!(
        laser["value_template"],
        "{{ 'ON' if value_json.value else 'OFF' }}"
    );
    // An enumerated register: its code names are the options.
    let median = config(
        &watcher,
        "homeassistant/sensor/hall-2_top/median_filter_width/config",
    );
    let codes: Vec<&str> = P
        .register("median_filter_width")
        .unwrap()
        .codes
        .iter()
        .map(|c| c.name)
        .collect();
    assert_eq!(median["device_class"], "enum");
    assert_eq!(median["options"], json!(codes));
    assert_eq!(median["value_template"], "{{ value_json.name }}");

    // What the file lets MQTT write: a number in the register's range and steps, a select of
    // its codes, a button per command.
    let power = config(
        &watcher,
        "homeassistant/number/hall-2_top/light_power/config",
    );
    let register = P.register("light_power").unwrap();
    let (low, high) = register.range.expect("light_power has a range");
    let scale = register.scale.unwrap();
    let value = |raw: i64| optobus_codec::value::Fixed::new(raw, scale).to_f64();
    assert_eq!(power["min"].as_f64(), Some(value(low)));
    assert_eq!(power["max"].as_f64(), Some(value(high)));
    assert_eq!(power["step"].as_f64(), Some(value(1)));
    assert_eq!(power["unit_of_measurement"], "%");
    assert_eq!(power["command_topic"], "optobus/top/light_power/set");
    assert_eq!(power["state_topic"], "optobus/top/light_power/state");
    let select = config(
        &watcher,
        "homeassistant/select/hall-2_top/median_filter_width/config",
    );
    assert_eq!(select["options"], json!(codes));
    assert_eq!(
        select["command_topic"],
        "optobus/top/median_filter_width/set"
    );
    let button = config(
        &watcher,
        "homeassistant/button/hall-2_top/zero_position_1/config",
    );
    assert_eq!(button["command_topic"], "optobus/top/zero_position_1/do");
    assert!(
        watcher
            .on("homeassistant/button/hall-2_top/reboot/config")
            .is_empty(),
        "a command not listed has no button"
    );

    // Retained: a Home Assistant that connects later still finds the entities.
    let late = Watcher::start(broker.port, "watcher-late", "homeassistant/#").await;
    assert!(
        late.hears(Duration::from_secs(10), distance_topic, |h| h.retain)
            .await
    );

    // Home Assistant restarts and says so: the configurations come again.
    let before = watcher.on(distance_topic).len();
    let (client, _home_assistant) = common::controller(broker.port, "home-assistant");
    client
        .publish("homeassistant/status", QoS::AtLeastOnce, false, "online")
        .await
        .unwrap();
    assert!(
        watcher
            .wait_for(Duration::from_secs(10), |heard| heard
                .iter()
                .filter(|h| h.topic == distance_topic)
                .count()
                > before)
            .await,
        "discovery not published again"
    );
    running.stop();
}
