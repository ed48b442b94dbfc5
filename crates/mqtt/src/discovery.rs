//! Home Assistant MQTT discovery: a Home Assistant device per sensor of the bus, a `sensor`
//! (or `binary_sensor`) per polled register, a `number`, `select` or `switch` per register the
//! bus file lets MQTT write and a `button` per command it lets MQTT run, each tied to the
//! process's and the device's availability.
//!
//! Every entity reads its register's state topic, `<prefix>/<device>/<register>/state`
//! (retained, at most one message per `state_every`), not the sample topic, which carries
//! every sample. A register a command writes is shown as that command's buttons, not also as
//! a `select` that would do the same. The device block carries the firmware's version and the
//! serial number where the spec gives registers those roles (`role:`), read once at start.
//!
//! Topics follow Home Assistant's MQTT discovery documentation:
//! `<discovery prefix>/<component>/<node id>/<object id>/config`, the node id made of the
//! client id and the device's name, the object id of the register's (characters other than
//! letters, digits, `_` and `-` become `_`). A reading with a unit gets the `device_class` its
//! unit says (a length is a `distance`, °C a `temperature`, …) only where Home Assistant
//! accepts that unit for that class; a unit it would refuse gets no class, since an entity
//! whose unit its class does not accept fails to load.

use std::collections::HashMap;

use optobus_bus::{BusFile, DeviceConfig};
use optobus_codec::value::{Fixed, Scale};
use optobus_device::{DeviceInfo, RegisterInfo, Role, Scalar, ValueKind};
use serde_json::{json, Map, Value as Json};

use crate::topics::Topics;

pub mod measurements;

/// What a device said about itself, for its Home Assistant device block.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct Identity {
    /// The firmware's version, as its register reads (`sw_version`).
    pub sw_version: Option<String>,
    /// The serial number, as its register reads (`serial_number`).
    pub serial_number: Option<String>,
}

impl Identity {
    /// Records what the register of `role` read (`text`).
    pub fn set(&mut self, role: Role, text: String) {
        match role {
            Role::FirmwareVersion => self.sw_version = Some(text),
            Role::SerialNumber => self.serial_number = Some(text),
            _ => {}
        }
    }
}

/// The discovery configurations of every polled register of every device of `file`, and of
/// its measurements (see [`measurements`]), as (topic, payload), for a publisher with
/// `client_id` and topic `prefix`, with what each device (by name) said about itself
/// (`identities`) in its device block.
pub fn configurations_with(
    file: &BusFile,
    discovery_prefix: &str,
    client_id: &str,
    prefix: &str,
    identities: &HashMap<String, Identity>,
) -> Vec<(String, Json)> {
    let topics = Topics::new(prefix);
    let mut configurations = Vec::new();
    for device in &file.devices {
        let line = &file.lines[device.line].name;
        let node = object_id(&format!("{client_id}_{}", device.name));
        // No spec names a manufacturer or vendor, so none is claimed.
        let mut block = object(json!({
            "identifiers": [object_id(&format!("optobus_{client_id}_{line}_{}", device.slave))],
            "name": device.name,
            "model": device.device.title,
        }));
        if let Some(identity) = identities.get(&device.name) {
            let known = [
                ("sw_version", &identity.sw_version),
                ("serial_number", &identity.serial_number),
            ];
            for (key, value) in known {
                if let Some(value) = value {
                    block.insert(key.into(), value.as_str().into());
                }
            }
        }
        let block = Json::Object(block);
        let mut all: Vec<Entity> = polled(device).into_iter().flat_map(entities).collect();
        all.extend(controls(device).into_iter().filter_map(control));
        for command in &device.writable.commands {
            all.push(Entity {
                component: "button",
                id: command.name.to_owned(),
                state: None,
                command: Some("do"),
                config: object(json!({
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
            if let Some(verb) = entity.command {
                config.insert(
                    "command_topic".into(),
                    format!("{}/{verb}", topics.sample(&device.name, &entity.id)).into(),
                );
            }
            if let Some(register) = entity.state {
                config.insert(
                    "state_topic".into(),
                    topics.state(&device.name, register).into(),
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
    configurations.extend(measurements::configurations(
        file,
        discovery_prefix,
        client_id,
        prefix,
    ));
    configurations
}

/// The registers `device` polls, once each, in address order.
fn polled(device: &DeviceConfig) -> Vec<&'static RegisterInfo> {
    let mut registers: Vec<&'static RegisterInfo> = device
        .polls
        .iter()
        .flat_map(|poll| poll.registers.iter().copied())
        .collect();
    registers.sort_by_key(|r| (r.table, r.address));
    registers.dedup_by_key(|r| (r.table, r.address, r.name));
    registers
}

/// The writable registers of `device` shown as controls: all but those a writable command
/// writes (CCS `position_zero`, `trigger_count_reset`), which its buttons stand for.
pub(crate) fn controls(device: &DeviceConfig) -> Vec<&'static RegisterInfo> {
    let writable = &device.writable;
    writable
        .registers
        .iter()
        .copied()
        .filter(|register| {
            !writable.commands.iter().any(|command| {
                command.register == register.name
                    || register.member_name() == Some(command.register)
            })
        })
        .collect()
}

/// Whether a control's register can be read for its state (without changing the device).
fn has_state(register: &RegisterInfo) -> bool {
    register.readable() && register.read_is_repeatable()
}

/// The registers of `device` whose state topics Home Assistant reads: what it polls, and the
/// controls that can be read.
pub(crate) fn state_registers(device: &DeviceConfig) -> Vec<&'static RegisterInfo> {
    let mut registers = polled(device);
    for register in controls(device) {
        if has_state(register) && !registers.iter().any(|r| r.name == register.name) {
            registers.push(register);
        }
    }
    registers
}

/// The controls of `device` read for their state, at start and at each refresh.
pub(crate) fn read_for_state(device: &DeviceConfig) -> Vec<&'static RegisterInfo> {
    controls(device)
        .into_iter()
        .filter(|r| has_state(r))
        .collect()
}

/// The registers that name the device, by the role the spec gives them (`role:`): read once
/// at start for its device block.
pub(crate) fn identity_registers(device: &DeviceInfo) -> Vec<(Role, &'static RegisterInfo)> {
    [Role::FirmwareVersion, Role::SerialNumber]
        .into_iter()
        .filter_map(|role| Some((role, device.register_with_role(role)?)))
        .filter(|(_, register)| has_state(register))
        .collect()
}

/// One entity before its common members.
struct Entity {
    component: &'static str,
    /// The register's or command's name, or `register.field`.
    id: String,
    /// The register whose state topic is its state.
    state: Option<&'static str>,
    /// The verb of its command topic (`set`, `do`), on its id's topic.
    command: Option<&'static str>,
    config: Map<String, Json>,
}

/// The entity that sets a writable register: a `select` of its codes, a `switch`, or a
/// `number` within its range, in its steps; its state is the register's state topic where it
/// can be read (otherwise Home Assistant shows what it last sent).
fn control(register: &'static RegisterInfo) -> Option<Entity> {
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
    // Said outright: a retained command would be refused (see the README).
    config.insert("retain".into(), false.into());
    Some(Entity {
        component,
        id: register.name.to_owned(),
        state: has_state(register).then_some(register.name),
        command: Some("set"),
        config,
    })
}

/// The entities of one polled register: one, or one per field of a packed or record value.
fn entities(register: &'static RegisterInfo) -> Vec<Entity> {
    let single = |config| Entity {
        component: "sensor",
        id: register.name.to_owned(),
        state: Some(register.name),
        command: None,
        config,
    };
    match register.kind {
        ValueKind::Bool => vec![Entity {
            component: "binary_sensor",
            id: register.name.to_owned(),
            state: Some(register.name),
            command: None,
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
                    command: None,
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
                    command: None,
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
