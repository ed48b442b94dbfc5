//! `optobus registers`: a model's register map, groups and commands, from its spec.

use clap::Args;
use optobus_device::{DeviceInfo, RegisterInfo};
use optobus_inspect::{accepted_values_text, hex_and_decimal};
use serde_json::{json, Value as Json};

use crate::connect::Options;
use crate::error::CliError;

use crate::render::{pretty, print};

#[derive(Debug, Args)]
pub(crate) struct RegistersArgs {
    /// The model (default: --model).
    model: Option<String>,
}

pub(crate) fn run(options: &Options, args: &RegistersArgs) -> Result<(), CliError> {
    let device = options.device_or(args.model.as_deref())?;
    print(&text(device, options.json));
    Ok(())
}

fn text(device: &'static DeviceInfo, json: bool) -> String {
    let mut registers: Vec<&RegisterInfo> = device.registers.iter().collect();
    // People read a map in address order per table; JSON keeps the description's order.
    if !json {
        registers.sort_by_key(|r| (r.table.as_str(), r.address));
    }
    let rows: Vec<(String, Json)> = registers.into_iter().map(describe).collect();
    if json {
        return pretty(&json!({
            "model": device.family,
            "registers": rows.iter().map(|(_, j)| j.clone()).collect::<Vec<_>>(),
            "groups": device.groups.iter().map(|g| json!({"name": g.name, "registers": g.registers, "doc": g.doc})).collect::<Vec<_>>(),
            "commands": device.commands.iter().map(|c| json!({"name": c.name, "register": c.register, "value": c.value, "doc": c.doc})).collect::<Vec<_>>(),
        }));
    }
    let mut out = format!(
        "{} — {}\n{:<34} {:<7} {:<14} {:<2} {:<7} {:<4} range or codes\n",
        crate::models::name(device),
        device.title,
        "register",
        "table",
        "addr",
        "rw",
        "type",
        "unit"
    );
    for (text, _) in rows {
        out.push_str(text.trim_end());
        out.push('\n');
    }
    out.push_str("\ngroups:\n");
    for g in device.groups {
        out.push_str(&format!("  {:<22} {}\n", g.name, g.registers.join(", ")));
    }
    out.push_str("\ncommands (optobus do NAME):\n");
    for c in device.commands {
        out.push_str(&format!("  {:<22} {}\n", c.name, c.doc));
    }
    out
}

/// A register readable in a terminal and as JSON: name, table, address, access, type, unit,
/// range or codes.
fn describe(register: &RegisterInfo) -> (String, Json) {
    let kind = register.kind.name();
    let values = accepted_values_text(register);
    let text = format!(
        "{:<34} {:<7} {:<14} {:<2} {:<7} {:<4} {}",
        register.name,
        register.table.as_str(),
        hex_and_decimal(register.address),
        register.access.as_str(),
        kind,
        register.unit.unwrap_or(""),
        values
    );
    let json = json!({
        "name": register.name,
        "table": register.table.as_str(),
        "address": register.address,
        "words": register.words,
        "access": register.access.as_str(),
        "type": kind,
        "unit": register.unit,
        "scale": register.scale.map(|s| s.to_string()),
        "range": register.range.map(|(a, b)| [a, b]),
        "codes": register.codes.iter().map(|c| json!({"code": c.code, "name": c.name, "meaning": c.meaning})).collect::<Vec<_>>(),
        "sentinel": register.sentinel,
        "doc": register.doc,
        "section": register.section,
    });
    (text, json)
}
