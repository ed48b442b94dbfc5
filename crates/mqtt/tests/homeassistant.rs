//! Home Assistant on a real mosquitto, as a plant engineer met it (issue 30, point 3, and the
//! units of point 9): controls get a retained state (read at start, after each write and
//! periodically), a register a command writes is shown as its buttons only, the device block
//! carries the firmware's version and serial number where the spec marks them (`role:`), the
//! state topics Home Assistant reads are rate-limited while the sample topics keep every
//! sample, and units are the spec's ASCII on every topic and Home Assistant's symbols in
//! discovery only.

mod common;

use std::time::{Duration, SystemTime};

use common::{parse, Broker, Heard, Watcher};
use optobus_bus::{Bus, Running};
use optobus_device::DeviceInfo;
use optobus_mqtt::Publisher;
use rumqttc::QoS;
use serde_json::Value as Json;

const P: &DeviceInfo = &optobus_p_series::DEVICE;
const LC: &DeviceInfo = &optobus_lc_rs::DEVICE;
const RANGER: &DeviceInfo = &optobus_rangefinder::DEVICE;

fn json(heard: &Heard) -> Json {
    serde_json::from_str(&heard.payload)
        .unwrap_or_else(|e| panic!("{}: {e}: {}", heard.topic, heard.payload))
}

/// The `text` member of the last message heard on `topic`.
fn last_text(watcher: &Watcher, topic: &str) -> Option<String> {
    let heard = watcher.on(topic);
    let last = heard.last()?;
    json(last)["text"].as_str().map(str::to_owned)
}

async fn wait_for_text(watcher: &Watcher, topic: &str, text: &str) -> bool {
    watcher
        .wait_for(Duration::from_secs(15), |heard| {
            heard
                .iter()
                .rev()
                .find(|h| h.topic == topic)
                .is_some_and(|h| json(h)["text"] == text)
        })
        .await
}

/// Starts a bus of `file` with `top`'s light power at 42.0 % (a value no default has: a
/// state must come from the device), a watcher `watcher_id` of its Home Assistant state, and
/// then the publisher, taking writes.
async fn start_at_42_percent(
    file: &common::File,
    port: u16,
    watcher_id: &str,
) -> (Running, Watcher, Publisher) {
    let bus = Bus::new(file.bus.clone());
    let events = bus.subscribe();
    let running = bus.start().unwrap();
    let power = P.register("light_power").unwrap();
    let simulator = running.simulator("top").unwrap();
    simulator.poke(power.table, power.address, &[420]).unwrap();
    let watcher = Watcher::start(port, watcher_id, "optobus/top/light_power/state").await;
    let publisher = Publisher::start(
        file.mqtt.as_ref().unwrap(),
        &file.bus,
        events,
        Some(running.handle()),
    )
    .unwrap();
    (running, watcher, publisher)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn controls_get_a_retained_state_read_at_start_after_each_write_and_periodically() {
    let broker = Broker::start("ha-controls").await;
    let file = parse(&common::top_alone(
        "poll: [{ read: distance_1, every: 50ms }], writable: [light_power]",
        &format!(
            "broker: 127.0.0.1:{}, homeassistant: true, refresh_every: 1s",
            broker.port
        ),
    ));
    let state = "optobus/top/light_power/state";
    let (running, probe, publisher) = start_at_42_percent(&file, broker.port, "ha-probe").await;
    let simulator = running.simulator("top").unwrap();
    let power = P.register("light_power").unwrap();
    // Home Assistant subscribes once the state is out: the broker hands it over, retained.
    assert!(
        probe
            .wait_for(Duration::from_secs(15), |heard| !heard.is_empty())
            .await,
        "no state on {state}: {:?}",
        publisher.counts()
    );
    let late = Watcher::start(broker.port, "ha-late", "optobus/top/light_power/#").await;
    assert!(
        late.hears(Duration::from_secs(10), state, |_| true).await,
        "no state on {state}: {:?}; {:?}",
        late.heard.lock().unwrap(),
        publisher.counts()
    );
    let first = late.on(state).remove(0);
    assert!(first.retain, "the state is retained: {first:?}");
    assert_eq!(json(&first)["text"], "42.0", "{first:?}");
    assert_eq!(json(&first)["unit"], "%");
    let discovery = Watcher::start(broker.port, "ha-config", "homeassistant/#").await;
    let config_topic = "homeassistant/number/optobus_top/light_power/config";
    assert!(
        discovery
            .hears(Duration::from_secs(10), config_topic, |_| true)
            .await
    );
    let config = json(&discovery.on(config_topic)[0]);
    assert_eq!(config["state_topic"], state);
    assert_eq!(config["command_topic"], "optobus/top/light_power/set");

    // A write: the value read back is the state at once.
    let (client, _writer) = common::controller(broker.port, "ha-writer");
    client
        .publish("optobus/top/light_power/set", QoS::AtLeastOnce, false, "55")
        .await
        .unwrap();
    assert!(
        wait_for_text(&late, state, "55.0").await,
        "{:?}",
        late.on(state)
    );
    assert_eq!(simulator.peek(power.table, power.address).unwrap(), [550]);

    // Someone changes it at the device: the next refresh (every 1 s here) shows it.
    simulator.poke(power.table, power.address, &[300]).unwrap();
    assert!(
        wait_for_text(&late, state, "30.0").await,
        "{:?}",
        late.on(state)
    );
    let counts = publisher.counts();
    assert!(counts.state_reads >= 2, "{counts:?}");
    assert_eq!(counts.state_reads_failed, 0, "{counts:?}");
    running.stop();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn a_register_a_command_writes_is_shown_as_its_command_buttons_only() {
    let broker = Broker::start("ha-buttons").await;
    let file = parse(&common::on_a_simulated_line(&format!(
        "
devices:
  - name: c
    model: ccs
    slave: 1
    poll: [{{ read: distance_1, every: 100ms }}]
    writable: all
outputs:
  mqtt: {{ broker: 127.0.0.1:{}, homeassistant: true }}
",
        broker.port
    )));
    let (running, _publisher, _) = common::start_publishing(&file);
    let watcher = Watcher::start(broker.port, "ha-buttons-watch", "homeassistant/#").await;
    let config =
        |component: &str, id: &str| format!("homeassistant/{component}/optobus_c/{id}/config");
    // Buttons come after the controls, in one connection's order.
    let last_button = config("button", "reset_trigger_count");
    assert!(
        watcher
            .hears(Duration::from_secs(10), &last_button, |_| true)
            .await,
        "{:?}",
        watcher.heard.lock().unwrap()
    );
    for command in [
        "zero_position",
        "clear_position_zero",
        "reset_trigger_count",
    ] {
        let heard = watcher.on(&config("button", command));
        assert_eq!(heard.len(), 1, "a button for {command}");
        assert_eq!(
            json(&heard[0])["command_topic"],
            format!("optobus/c/{command}/do")
        );
    }
    for register in ["position_zero", "trigger_count_reset"] {
        for component in ["select", "number", "switch"] {
            assert!(
                watcher.on(&config(component, register)).is_empty(),
                "{register} is shown by its buttons, not as a {component}"
            );
        }
    }
    // A register no command writes keeps its control.
    assert_eq!(watcher.on(&config("select", "exposure_mode")).len(), 1);
    running.stop();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn the_device_block_carries_the_firmware_version_and_serial_number_the_spec_marks() {
    let broker = Broker::start("ha-identity").await;
    let file = parse(&common::on_a_simulated_line(&format!(
        "
devices:
  - name: gauge
    model: lc-rs
    slave: 1
    poll: [{{ read: distance, every: 100ms }}]
  - name: ranger
    model: rangefinder
    slave: 25
    poll: [{{ read: distance, every: 100ms }}]
outputs:
  mqtt: {{ broker: 127.0.0.1:{}, homeassistant: true }}
",
        broker.port
    )));
    let bus = Bus::new(file.bus.clone());
    let events = bus.subscribe();
    let running = bus.start().unwrap();
    // Values no simulator starts with: the device block must come from the devices.
    let poke = |device: &str, info: &'static DeviceInfo, name: &str, words: &[u16]| {
        let register = info.register(name).unwrap();
        running
            .simulator(device)
            .unwrap()
            .poke(register.table, register.address, words)
            .unwrap();
        optobus_inspect::decode_value(register, words).to_string()
    };
    let gauge_version = poke("gauge", LC, "firmware_version", &[0x0002, 0x0713]);
    let ranger_version = poke("ranger", RANGER, "firmware_version", &[102]);
    let ranger_serial = poke("ranger", RANGER, "serial_number", &[0x0001, 0xE240]);
    assert_eq!(
        (
            gauge_version.as_str(),
            ranger_version.as_str(),
            ranger_serial.as_str()
        ),
        ("2.7.19", "102", "123456")
    );
    let _publisher = Publisher::start(
        file.mqtt.as_ref().unwrap(),
        &file.bus,
        events,
        Some(running.handle()),
    )
    .unwrap();
    let watcher = Watcher::start(broker.port, "ha-identity-watch", "homeassistant/#").await;
    // The device block of the last configuration heard for `device`.
    let device_block = |heard: &[Heard], device: &str| {
        let topic = format!("homeassistant/sensor/optobus_{device}/distance/config");
        let last = heard.iter().rev().find(|h| h.topic == topic)?;
        Some(json(last)["device"].clone())
    };
    let identified = |heard: &[Heard]| {
        device_block(heard, "gauge").is_some_and(|d| d["sw_version"] == gauge_version)
            && device_block(heard, "ranger").is_some_and(|d| {
                d["sw_version"] == ranger_version && d["serial_number"] == ranger_serial
            })
    };
    let heard = || watcher.heard.lock().unwrap().clone();
    assert!(
        watcher.wait_for(Duration::from_secs(15), identified).await,
        "{:?} {:?}",
        device_block(&heard(), "gauge"),
        device_block(&heard(), "ranger")
    );
    let gauge = device_block(&heard(), "gauge").unwrap();
    assert_eq!(gauge["model"], LC.title);
    assert!(
        gauge.get("serial_number").is_none(),
        "the LC-RS spec marks no serial number: {gauge}"
    );
    for device in [gauge, device_block(&heard(), "ranger").unwrap()] {
        assert!(
            device.get("manufacturer").is_none(),
            "no spec names a manufacturer: {device}"
        );
    }
    running.stop();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn home_assistant_states_are_rate_limited_and_the_sample_topics_keep_every_sample() {
    let broker = Broker::start("ha-rate").await;
    // The confocal sensor as fast as its line allows (about 145 samples a second).
    let file = parse(&common::on_a_simulated_line(&format!(
        "
devices:
  - name: c
    model: ccs
    slave: 1
    poll: [{{ read: distance_1 }}]
outputs:
  mqtt: {{ broker: 127.0.0.1:{}, homeassistant: true, qos: 0 }}
",
        broker.port
    )));
    let every = file.mqtt.as_ref().unwrap().state_every.of("c");
    assert_eq!(every, Duration::from_secs(1), "the default");
    let watcher = Watcher::start(broker.port, "ha-rate-watch", "optobus/c/#").await;
    let (running, publisher, _) = common::start_publishing(&file);
    let state = "optobus/c/distance_1/state";
    let sample = "optobus/c/distance_1";
    assert!(
        watcher
            .wait_for(Duration::from_secs(30), |heard| heard
                .iter()
                .filter(|h| h.topic == state)
                .count()
                >= 4)
            .await,
        "{:?}",
        publisher.counts()
    );
    running.stop();
    let states = watcher.on(state);
    let samples = watcher.on(sample);
    let seconds =
        |a: SystemTime, b: SystemTime| b.duration_since(a).unwrap_or_default().as_secs_f64();
    let span = seconds(states[0].arrived, states.last().unwrap().arrived);
    let window = seconds(
        samples[0].arrived.min(states[0].arrived),
        samples
            .last()
            .unwrap()
            .arrived
            .max(states.last().unwrap().arrived),
    );
    eprintln!(
        "{} samples and {} states in {window:.2} s ({:.1} and {:.2} a second); {:?}",
        samples.len(),
        states.len(),
        samples.len() as f64 / window,
        states.len() as f64 / window,
        publisher.counts()
    );
    // At most one state a second (one more for the state of the moment the window opened,
    // one for a broker's delivery that bunches two).
    assert!(
        states.len() as f64 <= span / every.as_secs_f64() + 2.0,
        "{} states in {span:.2} s",
        states.len()
    );
    assert!(
        samples.len() >= 5 * states.len(),
        "the sample topic keeps every sample: {} samples, {} states",
        samples.len(),
        states.len()
    );
    let counts = publisher.counts();
    assert!(counts.states_skipped > 0, "{counts:?}");
    // Each state is one of the samples, byte for byte.
    for heard in &states {
        assert!(heard.retain || states[0].arrived <= heard.arrived);
        assert!(
            samples.iter().any(|s| s.payload == heard.payload),
            "a state no sample carried: {}",
            heard.payload
        );
    }
}

#[test]
fn state_every_is_given_for_all_devices_or_per_device() {
    let text = |every: &str| {
        format!(
            "
lines:
  - {{ name: rs485, simulated: true, baud: 115200, any_format: true }}
devices:
  - {{ name: c, model: ccs, slave: 1, poll: [{{ read: distance_1 }}] }}
  - {{ name: top, model: p-series, slave: 2, poll: [{{ read: distance_1, every: 1s }}] }}
outputs:
  mqtt: {{ broker: 127.0.0.1, homeassistant: true, state_every: {every} }}
"
        )
    };
    let file = parse(&text("{ default: 2s, c: 100ms }"));
    let every = &file.mqtt.as_ref().unwrap().state_every;
    assert_eq!(every.of("c"), Duration::from_millis(100));
    assert_eq!(every.of("top"), Duration::from_secs(2));
    let file = parse(&text("0s"));
    assert_eq!(
        file.mqtt.as_ref().unwrap().state_every.of("c"),
        Duration::ZERO
    );
    let rejected = common::try_parse(&text("{ bottom: 1s }"))
        .expect_err("refused")
        .render();
    assert!(
        rejected.contains("`state_every` has no key `bottom`") && rejected.contains("`c`"),
        "{rejected}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn units_are_the_specs_ascii_on_every_topic_and_home_assistants_symbols_in_discovery_only() {
    let broker = Broker::start("ha-units").await;
    let file = parse(&common::on_a_simulated_line(&format!(
        "
devices:
  - name: top
    model: p-series
    slave: 1
    poll: [{{ read: temperature, every: 100ms }}]
  - name: c
    model: ccs
    slave: 2
    poll: [{{ read: exposure_time, every: 100ms }}]
outputs:
  mqtt: {{ broker: 127.0.0.1:{}, homeassistant: true }}
",
        broker.port
    )));
    let watcher = Watcher::start(broker.port, "ha-units-watch", "#").await;
    let (running, _publisher, _) = common::start_publishing(&file);
    let cases = [
        ("top", "temperature", "degC", "°C"),
        // Home Assistant's micro is the Greek mu (U+03BC), as its duration class lists it.
        ("c", "exposure_time", "us", "\u{3bc}s"),
    ];
    for (device, register, ascii, symbol) in cases {
        let sample = format!("optobus/{device}/{register}");
        let state = format!("{sample}/state");
        let config = format!("homeassistant/sensor/optobus_{device}/{register}/config");
        assert!(
            watcher
                .wait_for(Duration::from_secs(15), |heard| [&sample, &state, &config]
                    .iter()
                    .all(|topic| heard.iter().any(|h| &h.topic == *topic)))
                .await,
            "{register}: {:?}",
            watcher
                .heard
                .lock()
                .unwrap()
                .iter()
                .map(|h| &h.topic)
                .collect::<Vec<_>>()
        );
        assert_eq!(json(&watcher.on(&sample)[0])["unit"], ascii);
        assert_eq!(json(&watcher.on(&state)[0])["unit"], ascii);
        assert_eq!(json(&watcher.on(&config)[0])["unit_of_measurement"], symbol);
        assert!(last_text(&watcher, &sample).is_some());
    }
    running.stop();
}

/// The retained state a subscriber that comes now is handed on `topic`, and its `text`.
async fn retained_text(port: u16, id: &str, topic: &str) -> (bool, String) {
    let late = Watcher::start(port, id, topic).await;
    assert!(
        late.wait_for(Duration::from_secs(10), |heard| !heard.is_empty())
            .await,
        "nothing retained on {topic}"
    );
    let first = late.on(topic).remove(0);
    let text = json(&first)["text"].as_str().unwrap_or_default().to_owned();
    (first.retain, text)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn a_console_or_gateway_write_refreshes_the_home_assistant_state_at_once() {
    use optobus_bus::Source;
    use tokio::io::{AsyncReadExt, AsyncWriteExt};

    let broker = Broker::start("ha-written").await;
    // The periodic refresh is an hour away: only the writes can bring the states below.
    let file = parse(
        &common::top_alone(
            "poll: [{ read: distance_1, every: 50ms }], writable: [light_power]",
            &format!(
                "broker: 127.0.0.1:{}, homeassistant: true, refresh_every: 1h",
                broker.port
            ),
        )
        // The same line with a Modbus TCP gateway that takes writes.
        .replace(
            "any_format: true }",
            "any_format: true, gateway: { listen: 127.0.0.1:0, writes: true } }",
        ),
    );
    let state = "optobus/top/light_power/state";
    let (running, watcher, publisher) = start_at_42_percent(&file, broker.port, "ha-watch").await;
    let simulator = running.simulator("top").unwrap();
    let power = P.register("light_power").unwrap();
    // Read at start.
    assert!(
        wait_for_text(&watcher, state, "42.0").await,
        "{:?}; {:?}",
        watcher.on(state),
        publisher.counts()
    );

    // A PLC sets 55.0 % through the gateway: FC06 to holding register `light_power`.
    let mut plc = tokio::net::TcpStream::connect(running.gateway_address("rs485").unwrap())
        .await
        .unwrap();
    let [high, low] = power.address.to_be_bytes();
    let [value_high, value_low] = 550u16.to_be_bytes();
    let pdu = [0x06, high, low, value_high, value_low];
    let mut request = vec![0x00, 0x07, 0x00, 0x00, 0x00, 1 + pdu.len() as u8, 0x01];
    request.extend_from_slice(&pdu);
    plc.write_all(&request).await.unwrap();
    let mut reply = [0u8; 12];
    tokio::time::timeout(Duration::from_secs(10), plc.read_exact(&mut reply))
        .await
        .expect("the gateway answers")
        .unwrap();
    assert_eq!(reply, request.as_slice(), "FC06 is answered with its echo");
    assert_eq!(simulator.peek(power.table, power.address).unwrap(), [550]);
    assert!(
        wait_for_text(&watcher, state, "55.0").await,
        "the gateway's write did not reach the state: {:?}; {:?}",
        watcher.on(state),
        publisher.counts()
    );
    assert_eq!(
        retained_text(broker.port, "ha-late-1", state).await,
        (true, "55.0".to_owned())
    );

    // An operator sets 30 % on the console (its handle's path, as the console's write route).
    let console = running
        .handle()
        .for_source(Source::Console)
        .from_origin("127.0.0.1:50000");
    let back = console
        .set_listed("top", "light_power", "30")
        .await
        .unwrap();
    assert_eq!(back.map(|v| v.to_string()).as_deref(), Some("30.0 %"));
    assert!(
        wait_for_text(&watcher, state, "30.0").await,
        "the console's write did not reach the state: {:?}; {:?}",
        watcher.on(state),
        publisher.counts()
    );
    assert_eq!(
        retained_text(broker.port, "ha-late-2", state).await,
        (true, "30.0".to_owned())
    );

    // The program's own handle writes 25 %.
    running
        .handle()
        .write("top", power, vec![250], false)
        .await
        .unwrap();
    assert!(
        wait_for_text(&watcher, state, "25.0").await,
        "the program's write did not reach the state: {:?}; {:?}",
        watcher.on(state),
        publisher.counts()
    );
    let counts = publisher.counts();
    assert_eq!(counts.state_reads_after_writes, 3, "{counts:?}");
    assert_eq!(counts.state_reads_failed, 0, "{counts:?}");
    running.stop();
}
