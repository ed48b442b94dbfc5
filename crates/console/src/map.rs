//! A device's register map, commands and groups as the page shows them, from its spec.

use optobus_bus::Writable;
use optobus_device::{DeviceInfo, RegisterInfo};
use optobus_inspect::accepted_values_text;

use crate::reply::{CodeJson, CommandJson, DeviceMap, GroupJson, RegisterJson};

/// One register: where it is, its type, unit, range or codes, and the manual's words.
fn register(register: &'static RegisterInfo, writable: &Writable) -> RegisterJson {
    RegisterJson {
        name: register.name,
        table: register.table.as_str(),
        address: register.address,
        address_hex: format!("0x{:04X}", register.address),
        words: register.words,
        access: register.access.as_str(),
        writable: writable.allows_register(register),
        kind: register.kind.name(),
        unit: register.unit,
        range: accepted_values_text(register),
        codes: register
            .codes
            .iter()
            .map(|c| CodeJson {
                code: c.code,
                name: c.name,
            })
            .collect(),
        section: register.section,
        manual_name: register.zh,
        doc: register.doc,
    }
}

/// The whole map of `device`; `writable` tells which registers and commands the bus file lets
/// the network write.
pub(crate) fn device_map(
    name: &str,
    device: &'static DeviceInfo,
    writable: &Writable,
) -> DeviceMap {
    DeviceMap {
        device: name.to_owned(),
        model: device.model_name().to_string(),
        title: device.title,
        buffer: device.buffer.is_some(),
        registers: device
            .registers
            .iter()
            .map(|r| register(r, writable))
            .collect(),
        commands: device
            .commands
            .iter()
            .map(|c| CommandJson {
                name: c.name,
                doc: c.doc,
                drastic: c.effect.is_drastic(),
                allowed: writable.allows_command(c),
                busy_ms: c.busy_ms,
            })
            .collect(),
        groups: device
            .groups
            .iter()
            .map(|g| GroupJson {
                name: g.name,
                registers: g.registers,
            })
            .collect(),
    }
}
