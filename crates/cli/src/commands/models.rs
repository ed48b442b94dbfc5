//! `optobus models`: the families the tool has, their transports and defaults.

use std::net::Ipv4Addr;

use optobus_device::TcpInfo;
use optobus_driver::line_format;
use serde_json::{json, Value as Json};

use crate::connect::Options;
use crate::error::CliError;
use crate::models;
use crate::render::{pretty, print};

pub(crate) fn run(options: &Options) -> Result<(), CliError> {
    print(&if options.json { json() } else { text() });
    Ok(())
}

/// The factory IP address, if the manual gives one.
fn factory_ip(tcp: &TcpInfo) -> Option<String> {
    tcp.default_ip.map(|ip| Ipv4Addr::from(ip).to_string())
}

fn json() -> String {
    let list: Vec<Json> = models::all()
        .iter()
        .map(|d| {
            json!({
                "model": d.family,
                "title": d.title,
                "rtu": d.rtu.map(|r| json!({"default_baud": r.default_baud, "bauds": r.bauds, "parity": r.parity.name(), "data_bits": r.data_bits, "stop_bits": r.stop_bits})),
                "tcp": d.tcp.map(|t| json!({"port": t.port, "default_ip": factory_ip(&t)})),
                "default_slave": d.default_slave,
                "registers": d.registers.len(),
                "groups": d.groups.iter().map(|g| g.name).collect::<Vec<_>>(),
                "commands": d.commands.iter().map(|c| c.name).collect::<Vec<_>>(),
            })
        })
        .collect();
    pretty(&Json::Array(list))
}

fn text() -> String {
    let mut out = String::new();
    for d in models::all() {
        out.push_str(&format!("{}  {}\n", models::name(d), d.title));
        if let Some(rtu) = d.rtu {
            let bauds: Vec<String> = rtu.bauds.iter().map(u32::to_string).collect();
            out.push_str(&format!(
                "    RTU  {} (also {}), slave {}\n",
                line_format(d),
                bauds.join("/"),
                d.default_slave
            ));
        }
        if let Some(tcp) = d.tcp {
            let ip = factory_ip(&tcp).unwrap_or_else(|| "-".into());
            out.push_str(&format!("    TCP  port {}, factory IP {ip}\n", tcp.port));
        }
        let groups: Vec<&str> = d.groups.iter().map(|g| g.name).collect();
        let commands: Vec<&str> = d.commands.iter().map(|c| c.name).collect();
        out.push_str(&format!(
            "    {} registers; groups: {}\n    commands: {}\n",
            d.registers.len(),
            groups.join(", "),
            commands.join(", ")
        ));
    }
    out
}
