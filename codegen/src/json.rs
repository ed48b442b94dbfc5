//! `dump --json`: the checked model with repeats expanded, in a stable shape other tools read.
//!
//! Field names are part of the interface: `family`, `device`, `registers[]` with `name`,
//! `table`, `address`, `words`, `access`, `type`, `scale`, `unit`, `enum`, `range`,
//! `allowed_values`, `action`, `role`, `sentinel`, `section`, then `commands`, `groups` and `buffer`
//! (its keys as in the spec; `null` without one).

use serde_json::{json, Map, Value};

use optobus_spec::model::{Addressing, Apply, ExceptionStyle, Kind, LongWrites, Model, Register};

/// The wire type: `u16`, `i16`, `u32`, `i32`, or `ipv4` / `version` / `record` for values
/// spread over several words.
fn wire_type(register: &Register) -> String {
    match &register.kind {
        Kind::Ipv4 | Kind::Version(_) | Kind::Record(_) => register.kind.name().to_owned(),
        _ => register.scalar().map_or_else(
            || register.kind.name().to_owned(),
            |s| s.as_str().to_owned(),
        ),
    }
}

fn codes(model: &Model, register: &Register) -> Value {
    let Kind::Enum(reference) = &register.kind else {
        return Value::Null;
    };
    let Some(def) = model.enum_def(reference) else {
        return Value::Null;
    };
    let map: Map<String, Value> = def
        .codes
        .iter()
        .map(|c| (c.code.to_string(), Value::String(c.name.clone())))
        .collect();
    Value::Object(map)
}

fn register_json(model: &Model, register: &Register) -> Value {
    json!({
        "name": register.name,
        "table": register.table.as_str(),
        "address": register.address.0,
        "words": register.words.0,
        "access": register.access.as_str(),
        "type": wire_type(register),
        "kind": register.kind.name(),
        "scale": register.scale.as_ref().map(|s| s.text.clone()),
        "unit": register.unit,
        "enum": codes(model, register),
        "range": register.range.map(|(min, max)| vec![min, max]),
        "allowed_values": register.allowed_values.as_ref().map(|(values, _)| values),
        "action": register.action,
        "role": register.role.map(optobus_spec::model::Role::name),
        "sentinel": register.sentinel,
        "section": register.section,
        "doc": register.doc,
        "zh": register.zh,
    })
}

/// The checked model as JSON.
pub fn dump(model: &Model) -> Value {
    let device = &model.device;
    json!({
        "family": model.family,
        "title": model.title,
        "aliases": model.aliases,
        "manual": {"file": model.manual.file, "version": model.manual.version},
        "device": {
            "rtu": device.rtu.as_ref().map(|rtu| json!({
                "default_baud": rtu.default_baud,
                "bauds": rtu.bauds,
                "parity": rtu.parity.name(),
                "data_bits": rtu.data_bits,
                "stop_bits": rtu.stop_bits,
            })),
            "tcp": device.tcp.as_ref().map(|tcp| json!({
                "port": tcp.port,
                "default_ip": tcp.default_ip.map(|ip| ip.to_string()),
            })),
            "slave": {"default": device.default_slave, "min": device.min_slave, "max": device.max_slave},
            "functions": device.functions,
            "max_read_words": device.max_read_words,
            "power_up_ms": device.power_up_ms,
            "tables": {"holding": device.holding_size, "input": device.input_size},
            "addressing": match model.protocol.addressing { Addressing::Word => "word", Addressing::Field => "field" },
            "long_writes": match model.protocol.long_writes { LongWrites::Split => "split", LongWrites::Wide => "wide" },
            "exception": match model.protocol.exception { ExceptionStyle::Standard => "standard", ExceptionStyle::CountedWord => "counted_word" },
            "apply": match model.protocol.apply { Apply::Immediately => "immediately", Apply::AfterSaveAndPowerCycle => "after_save_and_power_cycle" },
            "exception_codes": model.protocol.exception_codes.as_ref().map(|r| r.name.clone()),
        },
        "registers": model.registers.iter().map(|r| register_json(model, r)).collect::<Vec<_>>(),
        "commands": model.commands.iter().map(|c| json!({
            "name": c.name,
            "register": c.register,
            "value": c.value,
            "busy_ms": c.busy_ms,
            "done_when": c.done_when,
            "within_ms": c.within_ms,
            "doc": c.doc,
        })).collect::<Vec<_>>(),
        "groups": model.groups.iter().map(|g| json!({
            "name": g.name,
            "registers": g.registers.iter().map(|(name, _)| name.clone()).collect::<Vec<_>>(),
            "doc": g.doc,
        })).collect::<Vec<_>>(),
        "buffer": model.buffer.as_ref().map(|b| json!({
            "source": b.source.as_ref().map(|n| n.name.clone()),
            "count": b.count.name,
            "most": b.most.0,
            "lock": b.lock.name,
            "unlock": b.unlock.name,
            "page": b.page.name,
            "read_count": b.read_count.name,
            "valid_count": b.valid_count.name,
            "values": b.values.name,
            "interval": b.interval.as_ref().map(|n| n.name.clone()),
            "ratio": b.ratio.as_ref().map(|n| n.name.clone()),
            "doc": b.doc,
        })),
    })
}
