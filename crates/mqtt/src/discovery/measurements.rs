//! The bus file's measurements in Home Assistant: one device for the bus, a `sensor` per
//! measurement for its value and, where it has limits, an enum `sensor` for its judgement.
//!
//! Both read the measurement's own topic, `<prefix>/measurements/<name>`, through a
//! `value_template` on its JSON (an invalid value renders `None`: Home Assistant shows it as
//! unknown). Their availability is the process's (`<prefix>/status`): a measurement is
//! computed by the bus, not by one device, and an invalid value says itself why.

use optobus_bus::BusFile;
use serde_json::{json, Value as Json};

use super::{home_assistant_unit, object, object_id};
use crate::topics::Topics;

/// The judgements, lowest first, as the JSON names them: the judgement sensor's options.
pub const JUDGEMENTS: [&str; 5] = ["ll", "lo", "go", "hi", "hh"];

/// The node id of the bus's measurements in discovery topics, for a publisher with
/// `client_id`: `<discovery prefix>/sensor/<node>/<measurement>[_judgement]/config`.
pub fn node(client_id: &str) -> String {
    object_id(&format!("{client_id}_measurements"))
}

/// The discovery configurations of `file`'s measurements, as (topic, payload), for a
/// publisher with `client_id` and topic `prefix`; none for a file without measurements.
pub fn configurations(
    file: &BusFile,
    discovery_prefix: &str,
    client_id: &str,
    prefix: &str,
) -> Vec<(String, Json)> {
    let topics = Topics::new(prefix);
    let node = node(client_id);
    let plan = &file.measurements.plan;
    if plan.formulas.is_empty() {
        return Vec::new();
    }
    // One Home Assistant device for the bus, named after its topic prefix.
    let block = json!({
        "identifiers": [object_id(&format!("optobus_{client_id}_{prefix}_measurements"))],
        "name": format!("{prefix} measurements"),
        "model": "optobus bus",
    });
    let mut configurations = Vec::new();
    for (formula, settings) in plan.formulas.iter().zip(&file.measurements.settings) {
        let name = &formula.name;
        let id = object_id(name);
        let mut value = object(json!({
            "name": name,
            "value_template": "{{ value_json.value.value if value_json.value else 'None' }}",
            "state_class": "measurement",
        }));
        if !formula.unit.name.is_empty() {
            let (symbol, class) = home_assistant_unit(&formula.unit.name);
            value.insert("unit_of_measurement".into(), symbol.into());
            if let Some(class) = class {
                value.insert("device_class".into(), class.into());
            }
        }
        let mut entities = vec![(id.clone(), value)];
        if settings.limits.is_some() {
            entities.push((
                format!("{id}_judgement"),
                object(json!({
                    "name": format!("{name} judgement"),
                    "value_template":
                        "{{ value_json.judgement if value_json.judgement else 'None' }}",
                    "device_class": "enum",
                    "options": JUDGEMENTS,
                })),
            ));
        }
        for (object_id, mut config) in entities {
            config.insert(
                "unique_id".into(),
                format!("{node}_{object_id}_sensor").into(),
            );
            config.insert("state_topic".into(), topics.measurement(name).into());
            config.insert("availability".into(), json!([{ "topic": topics.status() }]));
            config.insert("device".into(), block.clone());
            config.insert(
                "origin".into(),
                json!({ "name": "optobus", "sw_version": env!("CARGO_PKG_VERSION") }),
            );
            configurations.push((
                format!("{discovery_prefix}/sensor/{node}/{object_id}/config"),
                Json::Object(config),
            ));
        }
    }
    configurations
}

/// The filter of this publisher's measurement configurations, subscribed to so that those a
/// former run left retained and this run has not are found and removed.
pub fn filter(discovery_prefix: &str, client_id: &str) -> String {
    format!("{discovery_prefix}/sensor/{}/+/config", node(client_id))
}

/// Whether `topic` is a configuration of this publisher's measurements (one [`filter`]
/// matches) that `current` (this run's configuration topics) has not: a measurement gone
/// from the bus file, whose retained configuration is to be removed.
pub fn is_stale(topic: &str, discovery_prefix: &str, client_id: &str, current: &[String]) -> bool {
    let start = format!("{discovery_prefix}/sensor/{}/", node(client_id));
    let Some(object) = topic
        .strip_prefix(&start)
        .and_then(|rest| rest.strip_suffix("/config"))
    else {
        return false;
    };
    !object.is_empty() && !object.contains('/') && !current.iter().any(|c| c == topic)
}
