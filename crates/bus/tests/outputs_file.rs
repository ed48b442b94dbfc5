//! The `outputs` of a bus file: MQTT and metrics read into plain settings, and every problem
//! of them reported with the rest of the file, located.

use std::net::SocketAddr;
use std::path::Path;
use std::time::Duration;

use optobus_bus::{BusFile, Catalogue, SecretSource};

fn parse(text: &str) -> Result<BusFile, String> {
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
    BusFile::parse("bus.yaml", text, Path::new("/etc/optobus"), &catalogue).map_err(|e| e.render())
}

const BUS: &str = "
lines:
  - { name: rs485, simulated: true }
devices:
  - { name: top, model: p-series, slave: 1 }
";

#[test]
fn mqtt_and_metrics_outputs_read_into_their_settings() {
    let bus = parse(&format!(
        "{BUS}outputs:
  mqtt:
    broker: broker.plant:1884
    client_id: hall-2
    prefix: plant/hall-2
    username: gateway
    password: {{ env: MQTT_PASSWORD }}
    ca: certs/ca.pem
    qos: 0
    queue: 500
    keep_alive: 10s
    homeassistant: true
  metrics: 9464
"
    ))
    .expect("the file passes");
    let mqtt = bus.outputs.mqtt.expect("mqtt is given");
    assert_eq!((mqtt.host.as_str(), mqtt.port), ("broker.plant", 1884));
    assert_eq!(mqtt.client_id, "hall-2");
    assert_eq!(mqtt.prefix, "plant/hall-2");
    assert_eq!(mqtt.username, Some(SecretSource::Text("gateway".into())));
    assert_eq!(
        mqtt.password,
        Some(SecretSource::Env("MQTT_PASSWORD".into()))
    );
    assert_eq!(
        mqtt.ca.as_deref(),
        Some(Path::new("/etc/optobus/certs/ca.pem")),
        "relative to the bus file"
    );
    assert_eq!((mqtt.qos, mqtt.queue), (0, 500));
    assert_eq!(mqtt.keep_alive, Duration::from_secs(10));
    assert_eq!(mqtt.homeassistant.as_deref(), Some("homeassistant"));
    let metrics = bus.outputs.metrics.expect("metrics are given");
    assert_eq!(
        metrics.listen,
        "127.0.0.1:9464".parse::<SocketAddr>().unwrap(),
        "a port alone listens on loopback"
    );
}

#[test]
fn mqtt_defaults_are_plain_tcp_qos_1_and_no_discovery() {
    let bus = parse(&format!("{BUS}outputs:\n  mqtt: {{ broker: localhost }}\n"))
        .expect("the file passes");
    let mqtt = bus.outputs.mqtt.expect("mqtt is given");
    assert_eq!((mqtt.host.as_str(), mqtt.port), ("localhost", 1883));
    assert_eq!(
        (mqtt.client_id.as_str(), mqtt.prefix.as_str()),
        ("optobus", "optobus")
    );
    assert_eq!(
        (mqtt.qos, mqtt.queue),
        (1, optobus_bus::file::outputs::DEFAULT_MQTT_QUEUE)
    );
    assert_eq!(
        (mqtt.ca, mqtt.username, mqtt.homeassistant),
        (None, None, None)
    );
    assert!(bus.outputs.metrics.is_none());
    let tls = parse(&format!(
        "{BUS}outputs:\n  mqtt: {{ broker: localhost, ca: ca.pem }}\n"
    ))
    .expect("the file passes");
    assert_eq!(tls.outputs.mqtt.unwrap().port, 8883, "MQTT over TLS");
}

#[test]
fn every_outputs_problem_is_reported_at_once_with_its_place() {
    let rendered = parse(
        "
lines:
  - { name: rs485, simulated: true }
devices:
  - { name: top/left, model: p-series, slave: 1 }
outputs:
  mqtt:
    broker: 'no such:host:x'
    prefix: plant/+/x
    qos: 2
    queue: 0
    keep_alive: 1s
    homeassistant: $SYS
    password: { env: PASS }
    retain: true
  metrics: { listen: everywhere }
  console: true
",
    )
    .expect_err("the outputs have problems");
    for expected in [
        "`no such:host:x` is no broker address",
        "`prefix` `plant/+/x` is no topic prefix",
        "`qos` must be a whole number from 0 to 1, not `2`",
        "`queue` must be a whole number from 1 to 1000000, not `0`",
        "`keep_alive` must be more than",
        "is no topic prefix",
        "a `password` without a `username`",
        "`mqtt` has no key `retain`",
        "`everywhere` is no address to listen on",
        "`outputs` has no key `console`",
        "device `top/left` cannot be an MQTT topic level",
        "bus.yaml:8:13",
    ] {
        assert!(
            rendered.contains(expected),
            "missing {expected:?} in:\n{rendered}"
        );
    }
}

#[test]
fn a_password_written_in_the_file_is_refused_without_being_shown() {
    let rendered = parse(&format!(
        "{BUS}outputs:\n  mqtt:\n    broker: localhost\n    username: gateway\n    password: hunter2\n"
    ))
    .expect_err("a password is never written in the file");
    assert!(
        rendered.contains("`password` is never written in the bus file"),
        "{rendered}"
    );
    assert!(
        !rendered.contains("hunter2"),
        "the password is shown:\n{rendered}"
    );
}

#[test]
fn secret_sources_do_not_show_a_written_user_name_in_debug() {
    let shown = format!("{:?}", SecretSource::Text("gateway".into()));
    assert!(!shown.contains("gateway"), "{shown}");
    assert_eq!(
        format!("{:?}", SecretSource::Env("MQTT_PASSWORD".into())),
        "Env(\"MQTT_PASSWORD\")"
    );
}

#[test]
fn homeassistant_yes_is_refused_rather_than_taken_for_a_prefix() {
    // Found in the README walk: `yes` passed `bus check` and became the discovery prefix
    // `yes`, so Home Assistant saw no entity.
    for word in ["yes", "no", "on", "Off"] {
        let rendered = parse(&format!(
            "{BUS}outputs:\n  mqtt:\n    broker: localhost\n    homeassistant: {word}\n"
        ))
        .expect_err("a YAML 1.1 boolean is no prefix");
        assert!(
            rendered.contains(&format!(
                "`homeassistant: {word}` reads as a discovery prefix `{word}`"
            )) && rendered.contains("write `true`"),
            "{rendered}"
        );
    }
    let file = parse(&format!(
        "{BUS}outputs:\n  mqtt:\n    broker: localhost\n    homeassistant: ha\n"
    ))
    .unwrap();
    let mqtt = file.outputs.mqtt.unwrap();
    assert_eq!(mqtt.homeassistant.as_deref(), Some("ha"));
}
