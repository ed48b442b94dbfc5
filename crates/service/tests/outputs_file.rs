//! The `outputs` of a bus file as a service reads them: each output's section read into its
//! settings by the output's crate, and every problem of them reported with the rest of the
//! file, located. (Moved from the bus crate's tests with the settings.)

use std::net::SocketAddr;
use std::path::Path;
use std::time::Duration;

use optobus_bus::Catalogue;
use optobus_mqtt::SecretSource;
use optobus_service::{ServiceFile, SECTIONS};

fn parse_in(base: &str, text: &str) -> Result<ServiceFile, String> {
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
    ServiceFile::parse("bus.yaml", text, Path::new(base), &catalogue).map_err(|e| e.render())
}

fn parse(text: &str) -> Result<ServiceFile, String> {
    parse_in("/etc/optobus", text)
}

use optobus_testkit::bus_files::ONE_HEAD as BUS;

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
        (1, optobus_mqtt::settings::DEFAULT_MQTT_QUEUE)
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
fn a_bad_console_address_key_or_origin_is_located() {
    let rendered = parse_in(
        ".",
        "
lines: [{ name: a, simulated: true }]
devices: [{ name: head, model: p-series }]
outputs:
  http: { listen: nowhere, tokens: x, origins: [\"javascript:alert(1)\"] }
  ftp: 21
",
    )
    .expect_err("bad outputs");
    for expected in [
        "`http` has no key `tokens`",
        "`nowhere` is no address to listen on",
        "`javascript:alert(1)` is no origin",
        "`outputs` has no key `ftp`",
        "bus.yaml:5:19",
    ] {
        assert!(rendered.contains(expected), "{expected}: {rendered}");
    }
}

/// The schema `optobus bus schema` prints names every section of `outputs` and every key of
/// each (each output's crate gives its own), as the bus crate checks for its own keys.
#[test]
fn the_schema_names_every_output_and_every_key_of_each() {
    let keys = [
        &SECTIONS[..],
        optobus_mqtt::settings::KEYS,
        optobus_metrics::settings::KEYS,
        optobus_console::settings::KEYS,
    ];
    let schema = optobus_bus::file::SCHEMA;
    let missing: Vec<&str> = keys
        .into_iter()
        .flatten()
        .filter(|key| !schema.contains(&format!("{key}:")))
        .copied()
        .collect();
    assert!(missing.is_empty(), "the schema lacks {missing:?}");
}

/// The README walk: `optobus bus schema`'s example passes its own check, its outputs too.
#[test]
fn the_schemas_example_passes_with_its_outputs() {
    let file = parse_in(".", optobus_bus::file::SCHEMA).unwrap_or_else(|e| panic!("{e}"));
    assert!(file.outputs.mqtt.is_some() && file.outputs.http.is_some());
}
