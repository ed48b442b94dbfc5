//! `optobus registers`: a model's register map, groups and commands, from its spec.

use clap::Args;
use optobus_device::DeviceInfo;
use serde_json::{json, Value as Json};

use crate::connect::Global;
use crate::error::CliError;
use crate::models;
use crate::render::{pretty, print};
use crate::values;

#[derive(Debug, Args)]
pub(crate) struct RegistersArgs {
    /// The model (default: --model).
    model: Option<String>,
}

pub(crate) fn run(global: &Global, args: &RegistersArgs) -> Result<(), CliError> {
    let device = models::find(args.model.as_deref().unwrap_or(&global.model))?;
    print(&text(device, global.json));
    Ok(())
}

fn text(device: &'static DeviceInfo, json: bool) -> String {
    let rows: Vec<(String, Json)> = device.registers.iter().map(values::describe).collect();
    if json {
        return pretty(&json!({
            "model": device.family,
            "registers": rows.iter().map(|(_, j)| j.clone()).collect::<Vec<_>>(),
            "groups": device.groups.iter().map(|g| json!({"name": g.name, "registers": g.registers, "doc": g.doc})).collect::<Vec<_>>(),
            "commands": device.commands.iter().map(|c| json!({"name": c.name, "register": c.register, "value": c.value, "doc": c.doc})).collect::<Vec<_>>(),
        }));
    }
    let mut out = format!(
        "{} — {}\n{:<34} {:<7} {:>5} {:<2} {:<7} {:<4} range or codes\n",
        device.family, device.title, "register", "table", "addr", "rw", "type", "unit"
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
