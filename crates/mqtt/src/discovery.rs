//! Home Assistant MQTT discovery: a Home Assistant device per sensor of the bus, a `sensor`
//! (or `binary_sensor`) per polled register, a `number`, `select` or `switch` per register the
//! bus file lets MQTT write and a `button` per command it lets MQTT run, each tied to the
//! process's and the device's availability.
//!
//! Topics follow Home Assistant's MQTT discovery documentation:
//! `<discovery prefix>/<component>/<node id>/<object id>/config`, the node id made of the
//! client id and the device's name, the object id of the register's (characters other than
//! letters, digits, `_` and `-` become `_`). A reading with a unit gets the `device_class` its
//! unit says (a length is a `distance`, °C a `temperature`, …) only where Home Assistant
//! accepts that unit for that class; a unit it would refuse gets no class, since an entity
//! whose unit its class does not accept fails to load.

use optobus_bus::BusFile;
use optobus_codec::value::{Fixed, Scale};
use optobus_device::{RegisterInfo, Scalar, ValueKind};
use serde_json::{json, Map, Value as Json};

use crate::topics::Topics;

/// The discovery configurations of every polled register of every device of `file`, as
/// (topic, payload), for a publisher with `client_id` and topic `prefix`.
pub fn configurations(
    file: &BusFile,
    discovery_prefix: &str,
    client_id: &str,
    prefix: &str,
) -> Vec<(String, Json)> {
    let topics = Topics::new(prefix);
    let mut configurations = Vec::new();
    for device in &file.devices {
        let line = &file.lines[device.line].name;
        let node = object_id(&format!("{client_id}_{}", device.name));
        // The spec names no manufacturer, so none is claimed.
        let block = json!({
            "identifiers": [object_id(&format!("optobus_{client_id}_{line}_{}", device.slave))],
            "name": device.name,
            "model": device.device.title,
        });
        let mut registers: Vec<&'static RegisterInfo> = device
            .polls
            .iter()
            .flat_map(|poll| poll.registers.iter().copied())
            .collect();
        registers.sort_by_key(|r| (r.table, r.address));
        registers.dedup_by_key(|r| (r.table, r.address, r.name));
        let mut all: Vec<Entity> = registers.into_iter().flat_map(entities).collect();
        for register in &device.writable.registers {
            all.extend(control(
                register,
                &topics.sample(&device.name, register.name),
            ));
        }
        for command in &device.writable.commands {
            all.push(Entity {
                component: "button",
                id: command.name.to_owned(),
                state: None,
                config: object(json!({
                    "command_topic": format!("{}/do", topics.sample(&device.name, command.name)),
                    "payload_press": "PRESS",
                    // Said outright: a retained command would be refused (see the README).
                    "retain": false,
                })),
            });
        }
        for entity in all {
            let object = object_id(&entity.id);
            let mut config = entity.config;
            config.insert("name".into(), human(&entity.id).into());
            config.insert(
                "unique_id".into(),
                format!("{node}_{object}_{}", entity.component).into(),
            );
            if let Some(register) = entity.state {
                config.insert(
                    "state_topic".into(),
                    topics.sample(&device.name, register).into(),
                );
            }
            config.insert(
                "availability".into(),
                json!([
                    { "topic": topics.status() },
                    { "topic": topics.availability(&device.name) },
                ]),
            );
            config.insert("availability_mode".into(), "all".into());
            config.insert("device".into(), block.clone());
            config.insert(
                "origin".into(),
                json!({ "name": "optobus", "sw_version": env!("CARGO_PKG_VERSION") }),
            );
            configurations.push((
                format!(
                    "{discovery_prefix}/{}/{node}/{object}/config",
                    entity.component
                ),
                Json::Object(config),
            ));
        }
    }
    configurations
}

/// One entity before its common members.
struct Entity {
    component: &'static str,
    /// The register's or command's name, or `register.field`.
    id: String,
    /// The register whose samples are its state.
    state: Option<&'static str>,
    config: Map<String, Json>,
}

/// The entity that sets a writable register: a `select` of its codes, a `switch`, or a
/// `number` within its range, in its steps.
fn control(register: &'static RegisterInfo, topic: &str) -> Option<Entity> {
    let command_topic = format!("{topic}/set");
    let (component, mut config) = match register.kind {
        ValueKind::Enum => ("select", codes(register.codes, "value_json")),
        ValueKind::Bool => (
            "switch",
            object(json!({
                "value_template": "{{ 'true' if value_json.value else 'false' }}",
                "state_on": "true",
                "state_off": "false",
                "payload_on": "true",
                "payload_off": "false",
            })),
        ),
        ValueKind::Scalar(scalar) => {
            let scale = register.scale.unwrap_or(Scale::ONE);
            let (low, high) = register.range.unwrap_or(match scalar {
                Scalar::U16 => (0, i64::from(u16::MAX)),
                Scalar::I16 => (i64::from(i16::MIN), i64::from(i16::MAX)),
                Scalar::U32 => (0, i64::from(u32::MAX)),
                Scalar::I32 => (i64::from(i32::MIN), i64::from(i32::MAX)),
            });
            let value = |raw: i64| Fixed::new(raw, scale).to_f64();
            let mut config = number(register.unit, register.scale, "value_json.value");
            config.remove("state_class");
            config.remove("suggested_display_precision");
            config.insert("min".into(), value(low).into());
            config.insert("max".into(), value(high).into());
            config.insert("step".into(), value(1).into());
            config.insert("mode".into(), "box".into());
            ("number", config)
        }
        _ => return None,
    };
    if component == "select" {
        config.remove("device_class");
    }
    config.insert("command_topic".into(), command_topic.into());
    // Said outright: a retained command would be refused (see the README).
    config.insert("retain".into(), false.into());
    Some(Entity {
        component,
        id: register.name.to_owned(),
        state: Some(register.name),
        config,
    })
}

/// The entities of one polled register: one, or one per field of a packed or record value.
fn entities(register: &'static RegisterInfo) -> Vec<Entity> {
    let single = |config| Entity {
        component: "sensor",
        id: register.name.to_owned(),
        state: Some(register.name),
        config,
    };
    match register.kind {
        ValueKind::Bool => vec![Entity {
            component: "binary_sensor",
            id: register.name.to_owned(),
            state: Some(register.name),
            config: object(json!({
                "value_template": "{{ 'ON' if value_json.value else 'OFF' }}",
            })),
        }],
        ValueKind::Enum => vec![single(codes(register.codes, "value_json"))],
        ValueKind::Scalar(_) => vec![single(number(
            register.unit,
            register.scale,
            "value_json.value",
        ))],
        ValueKind::Packed(fields) => fields
            .iter()
            .map(|field| {
                let path = format!("value_json.fields.{}", field.name);
                let config = if field.codes.is_empty() {
                    number(field.unit, field.scale, &format!("{path}.value"))
                } else {
                    codes(field.codes, &path)
                };
                Entity {
                    component: "sensor",
                    id: format!("{}.{}", register.name, field.name),
                    state: Some(register.name),
                    config,
                }
            })
            .collect(),
        ValueKind::Record(members) => members
            .iter()
            .map(|member| {
                let path = format!("value_json.fields.{}", member.name);
                let config = if member.codes.is_empty() {
                    number(member.unit, member.scale, &format!("{path}.value"))
                } else {
                    codes(member.codes, &path)
                };
                Entity {
                    component: "sensor",
                    id: format!("{}.{}", register.name, member.name),
                    state: Some(register.name),
                    config,
                }
            })
            .collect(),
        ValueKind::Ipv4 | ValueKind::Version(_) => vec![single(object(json!({
            "value_template": "{{ value_json.text }}",
            "entity_category": "diagnostic",
        })))],
    }
}

/// A measurement: its unit as Home Assistant writes it, the device class that unit says, and
/// as many decimals as one step of the register has.
fn number(unit: Option<&str>, scale: Option<Scale>, path: &str) -> Map<String, Json> {
    let mut config = object(json!({
        "value_template": format!("{{{{ {path} }}}}"),
        "state_class": "measurement",
        "suggested_display_precision": decimals(scale),
    }));
    if let Some(unit) = unit {
        let (symbol, class) = home_assistant_unit(unit);
        config.insert("unit_of_measurement".into(), symbol.into());
        if let Some(class) = class {
            config.insert("device_class".into(), class.into());
        }
    }
    config
}

/// An enumerated value: its code names as the options.
fn codes(codes: &[optobus_device::CodeInfo], path: &str) -> Map<String, Json> {
    let options: Vec<&str> = codes.iter().map(|c| c.name).collect();
    object(json!({
        "value_template": format!("{{{{ {path}.name }}}}"),
        "device_class": "enum",
        "options": options,
    }))
}

/// Decimals one step shows: a step of 1e-6 shows 6.
fn decimals(scale: Option<Scale>) -> u8 {
    match scale {
        Some(Scale::Decimal { exponent }) if exponent < 0 => exponent.unsigned_abs(),
        Some(Scale::Ratio { denominator, .. }) => {
            // The decimals of 1/denominator, at most 9.
            let mut digits = 0u8;
            let mut power = 1u64;
            while power < u64::from(denominator.get()) && digits < 9 {
                power *= 10;
                digits += 1;
            }
            digits
        }
        _ => 0,
    }
}

/// A spec's unit as Home Assistant spells it, with the device class whose units (in Home
/// Assistant's list) include it.
pub fn home_assistant_unit(unit: &str) -> (&str, Option<&'static str>) {
    match unit {
        "mm" | "cm" | "m" | "km" => (unit, Some("distance")),
        "degC" | "°C" => ("°C", Some("temperature")),
        "s" | "ms" | "min" | "h" | "d" => (unit, Some("duration")),
        // Home Assistant spells micro with the Greek mu; older releases do not accept μs as a
        // duration or μV as a voltage, so these go without a class.
        "us" | "µs" => ("μs", None),
        "uV" | "µV" => ("μV", None),
        "V" | "mV" => (unit, Some("voltage")),
        "A" | "mA" => (unit, Some("current")),
        "Hz" | "kHz" | "MHz" | "GHz" => (unit, Some("frequency")),
        _ => (unit, None),
    }
}

/// `text` with every character Home Assistant does not take in an id made `_`.
fn object_id(text: &str) -> String {
    text.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// `distance_1` as `Distance 1`, `results.temperature` as `Results temperature`.
fn human(id: &str) -> String {
    let spaced = id.replace(['_', '.'], " ");
    let mut chars = spaced.chars();
    match chars.next() {
        Some(first) => first.to_uppercase().chain(chars).collect(),
        None => spaced,
    }
}

fn object(value: Json) -> Map<String, Json> {
    match value {
        Json::Object(map) => map,
        _ => Map::new(),
    }
}
