//! The commands that talk to a device (or list what the specs say).

use std::io::{IsTerminal, Write};
use std::time::Duration;

use optobus_device::{CommandInfo, DeviceInfo, Effect, RegisterInfo};
use optobus_driver::{plan_reads, raw_bits, Core};
use serde_json::{json, Map, Value as Json};

use crate::error::{driver_error, CliError};
use crate::link::{self, Link, Target};
use crate::log::note;
use crate::models::{self, MODELS};
use crate::values::{self, Validated};
use crate::{inputs, serve, Command, Global};

/// Runs one command line.
pub(crate) async fn run(global: Global, command: Command) -> Result<(), CliError> {
    match command {
        Command::Models => {
            print(&models_text(global.json));
            Ok(())
        }
        Command::Registers { model } => {
            let device = models::find(model.as_deref().unwrap_or(&global.model))?;
            print(&registers_text(device, global.json));
            Ok(())
        }
        Command::Simulate(args) => {
            let device = models::find(args.model.as_deref().unwrap_or(&global.model))?;
            check_line(device, &global)?;
            serve::simulate(device, &global, &args).await
        }
        Command::Frame(frame) => {
            print(&crate::frame::run(
                &frame,
                global.json,
                global.slave,
                global.tcp.is_some(),
            )?);
            Ok(())
        }
        Command::Scan { bauds, slaves } => {
            serve::scan(&global, bauds.as_deref(), slaves.as_deref()).await
        }
        Command::Buffer {
            count,
            source,
            wait,
            out,
        } => {
            let device = models::find(&global.model)?;
            if device.family != "p_series" {
                return Err(CliError::new(format!(
                    "`buffer` is the P series' buffered download; {} has no data buffer",
                    device.family
                ))
                .hint("use --model p-series"));
            }
            let source = serve::buffer_input(count, &source)?;
            let slave = answering_slave(device, &global, "buffer")?;
            check_line(device, &global)?;
            let link = link::open(device, slave, &target(&global)).await?;
            serve::buffer(link, slave, &global, count, source, wait, out.as_deref()).await
        }
        command => {
            let device = models::find(&global.model)?;
            device_command(device, &global, command).await
        }
    }
}

pub(crate) fn target(global: &Global) -> Target {
    Target {
        serial: global.serial.clone(),
        baud: global.baud,
        parity: global.parity.map(|p| p.name().to_owned()),
        tcp: global.tcp.clone(),
        timeout: global.timeout,
        verbose: global.verbose,
    }
}

/// Prints `text` on stdout with a final newline, ignoring a closed stdout.
pub(crate) fn print(text: &str) {
    let mut out = std::io::stdout().lock();
    // A closed pipe (`| head`) is not an error worth a message.
    let _ = out.write_all(text.as_bytes());
    if !text.ends_with('\n') {
        let _ = out.write_all(b"\n");
    }
    let _ = out.flush();
}

fn models_text(json: bool) -> String {
    if json {
        let list: Vec<Json> = MODELS
            .iter()
            .map(|d| {
                json!({
                    "model": d.family,
                    "title": d.title,
                    "rtu": d.rtu.map(|r| json!({"default_baud": r.default_baud, "bauds": r.bauds, "parity": r.parity.name(), "data_bits": r.data_bits, "stop_bits": r.stop_bits})),
                    "tcp": d.tcp.map(|t| json!({"port": t.port, "default_ip": t.default_ip.map(|ip| std::net::Ipv4Addr::from(ip).to_string())})),
                    "default_slave": d.default_slave,
                    "registers": d.registers.len(),
                    "groups": d.groups.iter().map(|g| g.name).collect::<Vec<_>>(),
                    "commands": d.commands.iter().map(|c| c.name).collect::<Vec<_>>(),
                })
            })
            .collect();
        return pretty(&Json::Array(list));
    }
    let mut out = String::new();
    for d in MODELS {
        out.push_str(&format!("{}  {}\n", d.family.replace('_', "-"), d.title));
        if let Some(rtu) = d.rtu {
            out.push_str(&format!(
                "    RTU  {} baud {}{}{} (also {}), slave {}\n",
                rtu.default_baud,
                rtu.data_bits,
                rtu.parity
                    .name()
                    .chars()
                    .next()
                    .unwrap_or('n')
                    .to_ascii_uppercase(),
                rtu.stop_bits,
                rtu.bauds
                    .iter()
                    .map(u32::to_string)
                    .collect::<Vec<_>>()
                    .join("/"),
                d.default_slave
            ));
        }
        if let Some(tcp) = d.tcp {
            let ip = tcp
                .default_ip
                .map(|ip| std::net::Ipv4Addr::from(ip).to_string())
                .unwrap_or_else(|| "-".into());
            out.push_str(&format!("    TCP  port {}, factory IP {ip}\n", tcp.port));
        }
        out.push_str(&format!(
            "    {} registers; groups: {}\n    commands: {}\n",
            d.registers.len(),
            d.groups
                .iter()
                .map(|g| g.name)
                .collect::<Vec<_>>()
                .join(", "),
            d.commands
                .iter()
                .map(|c| c.name)
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    out
}

fn registers_text(device: &'static DeviceInfo, json: bool) -> String {
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

fn pretty(json: &Json) -> String {
    serde_json::to_string_pretty(json).unwrap_or_default()
}

/// The registers behind names, in order, without repeats.
fn registers_of(
    device: &'static DeviceInfo,
    names: &[String],
    channel: Option<u8>,
) -> Result<Vec<&'static RegisterInfo>, CliError> {
    let mut registers: Vec<&'static RegisterInfo> = Vec::new();
    for name in names {
        for register in values::resolve(device, name, channel)? {
            if !register.access.readable() {
                return Err(CliError::new(format!("`{}` is write-only", register.name)));
            }
            if !registers.iter().any(|r| r.name == register.name) {
                registers.push(register);
            }
        }
    }
    Ok(registers)
}

/// Reads `registers` in the fewest requests and decodes them.
async fn read_values(
    core: &mut Core<Link>,
    registers: &[&'static RegisterInfo],
) -> Result<Vec<(&'static RegisterInfo, values::Value)>, CliError> {
    let readings = core.read_group(registers).await.map_err(|e| {
        let names: Vec<&str> = registers.iter().map(|r| r.name).collect();
        driver_error(e, Some(&names.join(", ")))
    })?;
    Ok(registers
        .iter()
        .map(|r| (*r, values::decode(r, readings.words(r))))
        .collect())
}

fn values_text(values: &[(&'static RegisterInfo, values::Value)]) -> String {
    let width = values.iter().map(|(r, _)| r.name.len()).max().unwrap_or(0);
    values
        .iter()
        .map(|(r, v)| format!("{:<width$}  {v}\n", r.name))
        .collect()
}

fn values_json(values: &[(&'static RegisterInfo, values::Value)]) -> Json {
    Json::Object(
        values
            .iter()
            .map(|(r, v)| (r.name.to_owned(), v.to_json()))
            .collect::<Map<_, _>>(),
    )
}

/// Connects to the device `global` names (or the built-in simulator), at `slave`.
async fn connect(
    device: &'static DeviceInfo,
    global: &Global,
    slave: u8,
) -> Result<Core<Link>, CliError> {
    let link = link::open(device, slave, &target(global)).await?;
    Core::new(link, slave, device).map_err(CliError::from)
}

/// The serial line settings of `global` that can be checked without a port: `--baud` is one
/// the model's manual lists (any rate a port can run at with `--any-baud`).
pub(crate) fn check_line(device: &DeviceInfo, global: &Global) -> Result<(), CliError> {
    match global.baud {
        Some(baud) => inputs::check_baud(device, "--baud", baud, global.any_baud),
        None => Ok(()),
    }
}

/// The slave address of a command that needs replies: never 0, the broadcast address.
pub(crate) fn answering_slave(
    device: &DeviceInfo,
    global: &Global,
    command: &str,
) -> Result<u8, CliError> {
    let slave = global.slave.unwrap_or(device.default_slave);
    if slave == 0 {
        return Err(CliError::new(format!(
            "`{command}` needs replies, and no device answers slave 0, the broadcast address"
        ))
        .hint(if command == "scan" {
            "scan tries the addresses --slaves lists; leave out --slave"
        } else {
            "give the device's address, 1 to 247, with --slave; `optobus scan` finds it"
        }));
    }
    Ok(slave)
}

/// The slave address of a write: 0 broadcasts it, on a serial line only.
fn writing_slave(device: &DeviceInfo, global: &Global) -> Result<u8, CliError> {
    let slave = global.slave.unwrap_or(device.default_slave);
    if slave == 0 && global.tcp.is_some() {
        return Err(CliError::new(
            "--slave 0 broadcasts on a serial line; Modbus TCP has no broadcast",
        )
        .hint("give the device's unit id, 1 to 247, with --slave"));
    }
    Ok(slave)
}

/// What a command does, in words for a sentence (`stores the current parameters…`).
fn effect_text(command: &CommandInfo) -> String {
    command.doc.trim_end_matches('.').to_lowercase()
}

/// `set` of a register that a drastic command writes (save, reboot, resets) needs `--yes`,
/// as `do` of the command does.
fn confirm_set(
    device: &DeviceInfo,
    register: &'static RegisterInfo,
    words: &[u16],
    yes: bool,
) -> Result<(), CliError> {
    if yes {
        return Ok(());
    }
    let drastic: Vec<&CommandInfo> = device
        .commands
        .iter()
        .filter(|c| inputs::drastic(c))
        .filter(|c| c.register == register.name || register.member_name() == Some(c.register))
        .collect();
    let raw = raw_bits(register, words);
    match (drastic.iter().find(|c| c.value == raw), drastic.as_slice()) {
        (_, []) => Ok(()),
        (Some(command), _) => Err(CliError::new(format!(
            "writing {raw} to `{}` runs `{}`: it {}; add --yes to go ahead",
            register.name,
            command.name,
            effect_text(command)
        ))
        .hint(format!("or run it as `optobus do {} --yes`", command.name))),
        (None, commands) => {
            let names: Vec<String> = commands.iter().map(|c| format!("`{}`", c.name)).collect();
            Err(CliError::new(format!(
                "`{}` is the register of {}, which store, restart or reset the device; add --yes \
                 to go ahead",
                register.name,
                names.join(" and ")
            )))
        }
    }
}

/// For a write to the device's own slave-address register, the new address (1 to 247).
fn new_slave_address(
    device: &DeviceInfo,
    register: &'static RegisterInfo,
    words: &[u16],
) -> Result<Option<u8>, CliError> {
    match device.slave_address_register() {
        Some(own) if own.name == register.name => {}
        _ => return Ok(None),
    }
    let raw = raw_bits(register, words);
    let (first, last) = inputs::SLAVES;
    match u8::try_from(raw)
        .ok()
        .filter(|a| (first..=last).contains(a))
    {
        Some(address) => Ok(Some(address)),
        None => Err(CliError::new(format!(
            "`{}` does not take {raw}: a device's address is {first} to {last}",
            register.name
        ))
        .hint("0 is the broadcast address; Modbus reserves 248 to 255")),
    }
}

/// A command that talks to the device: names and values are checked first, so bad input is
/// refused before any connection is made.
async fn device_command(
    device: &'static DeviceInfo,
    global: &Global,
    command: Command,
) -> Result<(), CliError> {
    check_line(device, global)?;
    match command {
        Command::Read { names, channel } => {
            let registers = registers_of(device, &names, channel)?;
            let slave = answering_slave(device, global, "read")?;
            let mut core = connect(device, global, slave).await?;
            let values = read_values(&mut core, &registers).await?;
            if global.json {
                print(&pretty(&values_json(&values)));
            } else {
                print(&values_text(&values));
            }
            Ok(())
        }
        Command::Dump => {
            let registers: Vec<&'static RegisterInfo> = device
                .registers
                .iter()
                .filter(|r| r.access.readable())
                .collect();
            let requests = plan_reads(device, &registers).len();
            let slave = answering_slave(device, global, "dump")?;
            let mut core = connect(device, global, slave).await?;
            let values = read_values(&mut core, &registers).await?;
            if global.json {
                print(&pretty(&json!({
                    "model": device.family,
                    "slave": core.slave(),
                    "requests": requests,
                    "values": values_json(&values),
                })));
            } else {
                print(&values_text(&values));
                note!(
                    "optobus: {} registers in {requests} requests",
                    registers.len()
                );
            }
            Ok(())
        }
        Command::Watch {
            names,
            interval,
            channel,
            count,
        } => {
            let registers = registers_of(device, &names, channel)?;
            let slave = answering_slave(device, global, "watch")?;
            let mut core = connect(device, global, slave).await?;
            watch(&mut core, &registers, interval, count, global.json).await
        }
        Command::Set {
            name,
            value,
            channel,
            yes,
        } => {
            let register = single(device, &name, channel)?;
            let words = values::parse(register, &value)?;
            let new_address = new_slave_address(device, register, &words)?;
            confirm_set(device, register, &words, yes)?;
            let slave = writing_slave(device, global)?;
            let mut core = connect(device, global, slave).await?;
            core.write(register, &Validated(words.clone()))
                .await
                .map_err(|e| driver_error(e, Some(register.name)))?;
            if slave == 0 {
                let value = values::decode(register, &words);
                if global.json {
                    print(
                        &json!({ register.name: value.to_json(), "broadcast": true }).to_string(),
                    );
                } else {
                    print(&format!(
                        "{}  {value}: broadcast sent, no reply expected",
                        register.name
                    ));
                }
                return Ok(());
            }
            let mut afterwards = None;
            if let Some(address) = new_address {
                if device.needs_save_and_power_cycle {
                    let save = device
                        .commands
                        .iter()
                        .find(|c| c.effect == Effect::Save)
                        .map(|c| format!(" (`optobus do {} --yes`)", c.name))
                        .unwrap_or_default();
                    afterwards = Some(format!(
                        "optobus: the new address {address} applies after save{save} and a power \
                         cycle; until then the device answers at slave {slave}"
                    ));
                } else {
                    // The device answers at its new address from the next request on.
                    core.set_slave(address)?;
                    afterwards = Some(format!(
                        "optobus: the device now answers at slave {address}"
                    ));
                }
            }
            if register.access.readable() {
                let back = core
                    .read_words(register)
                    .await
                    .map_err(|e| driver_error(e, Some(register.name)))?;
                let value = values::decode(register, &back);
                if global.json {
                    print(&pretty(&json!({ register.name: value.to_json() })));
                } else {
                    print(&format!("{}  {value}", register.name));
                }
            } else if !global.json {
                print(&format!("{} written", register.name));
            }
            if let Some(afterwards) = afterwards {
                note!("{afterwards}");
            }
            Ok(())
        }
        Command::Do {
            command,
            channel,
            yes,
        } => {
            let info = device.command(&command).ok_or_else(|| {
                let names: Vec<&str> = device.commands.iter().map(|c| c.name).collect();
                CliError::new(format!("`{command}` is no command of {}", device.family))
                    .hint(format!("commands: {}", names.join(", ")))
            })?;
            if inputs::drastic(info) && !yes {
                return Err(CliError::new(format!(
                    "`{command}` {}; add --yes to go ahead",
                    effect_text(info)
                )));
            }
            let register = single(device, info.register, channel)?;
            let slave = writing_slave(device, global)?;
            if info.busy_ms > 0 && !global.json {
                note!(
                    "optobus: the device is busy for {} ms afterwards",
                    info.busy_ms
                );
            }
            let mut core = connect(device, global, slave).await?;
            core.run(info, register)
                .await
                .map_err(|e| driver_error(e, Some(register.name)))?;
            if slave == 0 {
                if global.json {
                    print(&json!({"command": info.name, "broadcast": true}).to_string());
                } else {
                    print(&format!("{}: broadcast sent, no reply expected", info.name));
                }
            } else if global.json {
                print(&json!({"command": info.name, "done": true}).to_string());
            } else {
                print(&format!("{} done", info.name));
            }
            Ok(())
        }
        _ => Ok(()),
    }
}

/// The one register `name` (with `channel` for per-channel registers) names.
fn single(
    device: &'static DeviceInfo,
    name: &str,
    channel: Option<u8>,
) -> Result<&'static RegisterInfo, CliError> {
    let registers = values::resolve(device, name, channel)?;
    match registers.as_slice() {
        [register] => Ok(register),
        [first, ..] => Err(CliError::new(format!(
            "`{name}` stands for {} registers",
            registers.len()
        ))
        .hint(match first.copy {
            Some(copy) => format!("choose one with --{} N… try --channel N", copy.repeat),
            None => "name one register".into(),
        })),
        [] => Err(CliError::new(format!("`{name}` names no register"))),
    }
}

/// Redraws the values every `interval` until Ctrl-C (or `count` refreshes).
async fn watch(
    core: &mut Core<Link>,
    registers: &[&'static RegisterInfo],
    interval: Duration,
    count: Option<u64>,
    json: bool,
) -> Result<(), CliError> {
    let terminal = std::io::stdout().is_terminal() && !json;
    let mut drawn_lines = 0usize;
    let mut last: Option<String> = None;
    let mut refresh = 0u64;
    let ctrl_c = tokio::signal::ctrl_c();
    tokio::pin!(ctrl_c);
    loop {
        let started = tokio::time::Instant::now();
        let outcome = tokio::select! {
            outcome = read_values(core, registers) => outcome,
            _ = &mut ctrl_c => break,
        };
        refresh += 1;
        let stamp = link::timestamp();
        let block = match &outcome {
            Ok(values) if json => {
                json!({"time": stamp, "values": values_json(values)}).to_string() + "\n"
            }
            Ok(values) => {
                let text = values_text(values);
                last = Some(text.clone());
                format!(
                    "{stamp}  {} · slave {} · every {} ms\n{text}",
                    core.device().family,
                    core.slave(),
                    interval.as_millis()
                )
            }
            Err(error) if json => {
                json!({"time": stamp, "error": error.to_string()}).to_string() + "\n"
            }
            // Keep the last values on screen, marked, and try again.
            Err(error) => format!(
                "{stamp}  ! {error} — retrying\n{}",
                last.as_deref().unwrap_or("")
            ),
        };
        let mut out = std::io::stdout().lock();
        if terminal && drawn_lines > 0 {
            // Back to the top of the last drawing and clear it: the view refreshes in place.
            let _ = write!(out, "\x1b[{drawn_lines}F\x1b[J");
        }
        let _ = out.write_all(block.as_bytes());
        let _ = out.flush();
        drawn_lines = block.lines().count();
        if count.is_some_and(|n| refresh >= n) {
            break;
        }
        tokio::select! {
            () = tokio::time::sleep_until(started + interval) => {}
            _ = &mut ctrl_c => break,
        }
    }
    Ok(())
}
