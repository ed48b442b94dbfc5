//! A device's register map, commands and groups as the page shows them, from its spec.

use optobus_bus::Writable;
use optobus_device::{DeviceInfo, RegisterInfo};
use optobus_inspect::values_text;
use serde_json::{json, Value as Json};

/// One register: where it is, its type, unit, range or codes, and the manual's words.
fn register(register: &'static RegisterInfo, writable: &Writable) -> Json {
    let values = values_text(register);
    json!({
        "name": register.name,
        "table": register.table.as_str(),
        "address": register.address,
        "address_hex": format!("0x{:04X}", register.address),
        "words": register.words,
        "access": register.access.as_str(),
        "writable": writable.allows_register(register),
        "type": register.kind.name(),
        "unit": register.unit,
        "range": values,
        "codes": register.codes.iter().map(|c| json!({"code": c.code, "name": c.name})).collect::<Vec<_>>(),
        "section": register.section,
        "manual_name": register.zh,
        "doc": register.doc,
    })
}

/// The whole map of `device`; `writable` tells which registers and commands the bus file lets
/// the network write.
pub(crate) fn device_map(name: &str, device: &'static DeviceInfo, writable: &Writable) -> Json {
    json!({
        "device": name,
        "model": device.model_name().to_string(),
        "title": device.title,
        "buffer": device.buffer.is_some(),
        "registers": device.registers.iter().map(|r| register(r, writable)).collect::<Vec<_>>(),
        "commands": device.commands.iter().map(|c| json!({
            "name": c.name,
            "doc": c.doc,
            "drastic": c.effect.is_drastic(),
            "allowed": writable.allows_command(c),
            "busy_ms": c.busy_ms,
        })).collect::<Vec<_>>(),
        "groups": device.groups.iter().map(|g| json!({"name": g.name, "registers": g.registers})).collect::<Vec<_>>(),
    })
}
