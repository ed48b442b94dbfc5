//! `outputs: mqtt:` read into [`MqttConfig`](optobus_mqtt::MqttConfig) as the bus file is
//! read: secrets never written in the file nor shown, YAML 1.1 booleans refused as a
//! discovery prefix. (Moved from the bus crate's tests with the settings.)

use std::path::Path;

use optobus_bus::{BusFile, Catalogue};
use optobus_mqtt::{MqttConfig, SecretSource};

/// The file with its `mqtt` settings, or every problem of it rendered.
fn parse(text: &str) -> Result<Option<MqttConfig>, String> {
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
    let mut mqtt = None;
    BusFile::parse_with(
        "bus.yaml",
        text,
        Path::new("/etc/optobus"),
        &catalogue,
        &mut mqtt,
    )
    .map_err(|e| e.render())?;
    Ok(mqtt)
}

use optobus_testkit::bus_files::ONE_HEAD as BUS;

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
    let mqtt = parse(&format!(
        "{BUS}outputs:\n  mqtt:\n    broker: localhost\n    homeassistant: ha\n"
    ))
    .unwrap()
    .unwrap();
    assert_eq!(mqtt.homeassistant.as_deref(), Some("ha"));
}
