//! `optobus simulate`: a virtual device served over Modbus TCP, a pty or a serial port, or
//! several on one RTU line (`p-series@1 ccs@3`, or a line of a bus file), with seeded faults
//! and RS-485 line timing on request; every exchange logged on stderr.

use std::collections::BTreeSet;
use std::path::PathBuf;
use std::time::Duration;

use clap::Args;
use optobus_bus::LinePickError;
use optobus_codec::LineFormat;
use optobus_device::DeviceInfo;
use optobus_simulator::{
    Exchange, Faults, FaultsError, Line, Member, Protocol, ServedLine, Simulator,
};

use crate::connect::{DeviceArgs, Global};
use crate::error::CliError;
use crate::log::note;
use crate::render::{counted, print};
use crate::{inputs, models, target};

/// `optobus simulate`'s arguments.
#[derive(Debug, Args)]
pub(crate) struct SimulateArgs {
    /// The model (default: --model); or several devices on one RTU line, each as MODEL@SLAVE
    /// (`p-series@1 ccs@3 rangefinder@5`).
    #[arg(value_name = "MODEL[@SLAVE]")]
    models: Vec<String>,
    /// Serve the devices of a line of this bus file on one RTU line, each at its slave with
    /// its `faults:` (`optobus bus schema` prints the keys of a bus file).
    #[arg(long, value_name = "FILE", conflicts_with = "models")]
    bus: Option<PathBuf>,
    /// With --bus, the line whose devices to serve (default: the file's only line, or its
    /// only `simulated: true` line).
    #[arg(long, value_name = "NAME", requires = "bus")]
    line: Option<String>,
    /// Serve RTU on a new pseudo-terminal and print its path.
    #[arg(long)]
    pty: bool,
    /// Stop after this long, at most 24 h (default: until Ctrl-C).
    #[arg(long, value_parser = inputs::RUN_FOR.parser(), allow_hyphen_values = true)]
    duration: Option<Duration>,
    /// Inject seeded faults into the replies, e.g. `delay=0.1,corrupt=0.05` (kinds: corrupt,
    /// truncate, garbage, wrong_slave, split, drop, delay, disconnect; also late=, pause=,
    /// timeout=, seed=).
    #[arg(long, value_name = "SPEC")]
    faults: Option<String>,
    /// Seed of --faults (overrides its seed=; default 0): same seed, same faults.
    #[arg(long, requires = "faults")]
    seed: Option<u64>,
    /// Time RTU serving (--pty, --serial) like an RS-485 line of the model's factory format
    /// (or --baud, --parity): a character time per byte, t3.5 gaps, --turnaround.
    #[arg(long)]
    line_timing: bool,
    /// With --line-timing, the device's reaction time after a request's t3.5 (at most 24 h).
    #[arg(long, requires = "line_timing", default_value = "0", value_parser = inputs::TURNAROUND.parser(), allow_hyphen_values = true)]
    turnaround: Duration,
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
}

/// The faults `--faults` and `--seed` give; a bad spec is refused in one line.
fn faults(args: &SimulateArgs) -> Result<Option<Faults>, CliError> {
    let Some(spec) = &args.faults else {
        return Ok(None);
    };
    let mut faults: Faults = spec
        .parse()
        .map_err(|e: FaultsError| CliError::new(format!("--faults `{spec}`: {e}")))?;
    if let Some(seed) = args.seed {
        faults = faults.seed(seed);
    }
    Ok(Some(faults))
}

/// `optobus simulate`: serves a virtual device, or a line of several, until Ctrl-C or
/// `--duration`, with `--faults` in its replies and, on RTU, `--line-timing`. Every exchange
/// is logged on stderr through [`note!`] (a thread of its own writes it), so a slow or
/// closed stderr never holds up a reply.
pub(crate) async fn run(global: &Global, args: &SimulateArgs) -> Result<(), CliError> {
    if global.target.sim_speed.is_some() {
        return Err(CliError::new(
            "--sim-speed sets how fast a device command's own simulator answers (no --serial or --tcp)",
        )
        .hint("time a served RTU line with --line-timing"));
    }
    let several = args.bus.is_some() || args.models.len() > 1;
    if several {
        serve_several(global, args).await
    } else {
        serve_one(global, args).await
    }
}

/// Logs an exchange on stderr.
fn log_exchange(exchange: &Exchange<'_>) {
    note!("{} {exchange}", crate::render::time_of_day());
}

/// One device, at `--slave` or its factory address, over TCP (answering every unit id), a pty
/// or a serial port.
async fn serve_one(global: &Global, args: &SimulateArgs) -> Result<(), CliError> {
    let named = args.models.first().map(String::as_str);
    if let Some((model, slave)) = named.and_then(|n| n.rsplit_once('@')) {
        // One MODEL@SLAVE is one device at that slave.
        return serve_list(
            global,
            args,
            &[(models::find(model)?, slave_of(model, slave)?)],
        )
        .await;
    }
    let device = global.device_or(named)?;
    global.check_line(device)?;
    let slave = global.slave.unwrap_or(device.default_slave);
    if slave == 0 {
        return Err(CliError::new(
            "a device never has slave address 0: it is the broadcast address",
        )
        .hint("serve at 1 to 247 with --slave"));
    }
    let member = Member {
        name: models::name(device),
        simulator: Simulator::new(device).slave(slave),
        faults: None,
    };
    let format = Some(global.target.line_format(device));
    serve_line_of(global, args, Serve::One(member), format, faults(args)?).await
}

/// `--line-timing` needs an RTU line: a pty or a serial port.
fn check_rtu(global: &Global, args: &SimulateArgs) -> Result<(), CliError> {
    if args.pty || global.target.serial.is_some() {
        return Ok(());
    }
    Err(
        CliError::new("--line-timing times an RTU serial line; Modbus TCP has no line to time")
            .hint("serve RTU with --pty or --serial PORT"),
    )
}

/// The slave address of `MODEL@SLAVE`: 1 to 247.
fn slave_of(model: &str, slave: &str) -> Result<u8, CliError> {
    slave
        .parse::<u8>()
        .ok()
        .filter(|slave| (1..=247).contains(slave))
        .ok_or_else(|| {
            CliError::new(format!(
                "`{model}@{slave}`: a device's slave address is 1 to 247"
            ))
            .hint("e.g. p-series@1 ccs@3")
        })
}

/// Several devices on one RTU line: the `MODEL@SLAVE` list or a line of `--bus`.
async fn serve_several(global: &Global, args: &SimulateArgs) -> Result<(), CliError> {
    if global.slave.is_some() {
        return Err(CliError::new(
            "--slave serves one device; on a line of several each has its own address",
        )
        .hint("name each as MODEL@SLAVE, or give `slave:` in the bus file"));
    }
    if let Some(path) = &args.bus {
        return serve_bus_line(global, args, path).await;
    }
    let mut devices = Vec::new();
    for item in &args.models {
        let (model, slave) = item.rsplit_once('@').ok_or_else(|| {
            CliError::new(format!(
                "`{item}`: devices sharing a line are each named MODEL@SLAVE"
            ))
            .hint("e.g. p-series@1 ccs@3 rangefinder@5")
        })?;
        devices.push((models::find(model)?, slave_of(model, slave)?));
    }
    serve_list(global, args, &devices).await
}

/// The `MODEL@SLAVE` devices on one line, `--faults` in every reply on it.
async fn serve_list(
    global: &Global,
    args: &SimulateArgs,
    devices: &[(&'static DeviceInfo, u8)],
) -> Result<(), CliError> {
    let mut slaves = BTreeSet::new();
    for &(device, slave) in devices {
        global.check_line(device)?;
        if !slaves.insert(slave) {
            return Err(CliError::new(format!(
                "two devices at slave {slave}: each answers its own address"
            )));
        }
    }
    let formats: BTreeSet<String> = devices
        .iter()
        .map(|(device, _)| global.target.line_format(device).to_string())
        .collect();
    let format = match devices.first() {
        Some((device, _)) if formats.len() == 1 => Some(global.target.line_format(device)),
        _ => None,
    };
    let members = devices
        .iter()
        .map(|&(device, slave)| Member {
            name: models::name(device),
            simulator: Simulator::new(device).slave(slave),
            faults: None,
        })
        .collect();
    serve_line_of(global, args, Serve::Several(members), format, faults(args)?).await
}

/// The devices of one line of the bus file at `path`, each with its own faults.
async fn serve_bus_line(
    global: &Global,
    args: &SimulateArgs,
    path: &std::path::Path,
) -> Result<(), CliError> {
    let target = &global.target;
    if target.baud.is_some()
        || target.parity.is_some()
        || target.data_bits.is_some()
        || target.stop_bits.is_some()
    {
        return Err(CliError::new(
            "the bus file sets its line's format; --baud, --parity, --data-bits and --stop-bits do not apply",
        ));
    }
    if args.faults.is_some() {
        return Err(
            CliError::new("--faults does not apply to a bus file's line")
                .hint("give each simulated device its `faults:` in the bus file"),
        );
    }
    let file = crate::bus_file::load(path)?;
    let index = bus_line(&file, args.line.as_deref(), path)?;
    let members = file
        .devices_on(index)
        .map(|(_, config)| Member {
            name: format!("{} {}", models::name(config.device), config.name),
            simulator: config.simulator(),
            faults: config.faults.clone(),
        })
        .collect();
    let format = file.lines.get(index).and_then(|line| line.format);
    serve_line_of(global, args, Serve::Several(members), format, None).await
}

/// The line of the bus file `--line` names, or its only line, or its only simulated line.
fn bus_line(
    file: &optobus_bus::BusFile,
    named: Option<&str>,
    path: &std::path::Path,
) -> Result<usize, CliError> {
    file.pick_line(named).map_err(|error| match error {
        LinePickError::NoSuchLine { name, lines } => {
            CliError::new(format!("{} has no line `{name}`", path.display()))
                .hint(format!("its lines: {}", lines.join(", ")))
        }
        LinePickError::Several { lines } => {
            CliError::new(format!("{} has several lines", path.display())).hint(format!(
                "name the one to serve with --line ({})",
                lines.join(", ")
            ))
        }
    })
}

/// What `simulate` serves: one device, or several on one line.
enum Serve {
    /// One device: over TCP it answers every unit id, and it is named in the log alone.
    One(Member),
    /// Several devices, each at its own slave address.
    Several(Vec<Member>),
}

/// Serves `devices` (a pty or `--serial`, else Modbus TCP) in `format` (where they agree on
/// one, or the bus file gives it), `line_faults` in every reply; logs what the faults did
/// when stopped.
async fn serve_line_of(
    global: &Global,
    args: &SimulateArgs,
    devices: Serve,
    format: Option<LineFormat>,
    line_faults: Option<Faults>,
) -> Result<(), CliError> {
    if args.line_timing {
        check_rtu(global, args)?;
    }
    let rtu = args.pty || global.target.serial.is_some();
    let needs_format = args.line_timing || global.target.serial.is_some();
    let format = match format {
        Some(format) => Some(format),
        None if needs_format => {
            return Err(CliError::new(
                "the devices' factory serial formats differ: the line needs one",
            )
            .hint("give --baud, --parity, --data-bits and --stop-bits"))
        }
        None => None,
    };
    let line = match format.filter(|_| args.line_timing) {
        Some(format) => {
            format
                .check()
                .map_err(|e| CliError::new(format!("--line-timing cannot time this line: {e}")))?;
            Some(Line::new(format).turnaround(args.turnaround))
        }
        None => None,
    };
    let protocol = if rtu { Protocol::Rtu } else { Protocol::Tcp };
    let one = matches!(devices, Serve::One(_));
    let served = match devices {
        Serve::One(member) => ServedLine::one(member, line_faults, log_exchange),
        Serve::Several(members) => ServedLine::new(members, protocol, line_faults, log_exchange),
    };
    let mut extras = served
        .faults()
        .map(|f| format!(", faults {f}"))
        .unwrap_or_default();
    if let Some(line) = &line {
        let turnaround = args.turnaround;
        extras += &format!(
            ", line timed at {}, turnaround {turnaround:?}",
            line.format()
        );
    }
    let line_stats = line.as_ref().map(Line::stats);
    let (server, place) = if rtu {
        serve_rtu(&served, global.target.serial.as_deref(), format, line)?
    } else {
        let (server, place) = serve_tcp(global, &served).await?;
        let picks = if one {
            ""
        } else {
            " (the unit id picks the device)"
        };
        (server, place + picks)
    };
    let who: Vec<String> = served
        .members()
        .iter()
        .map(|member| format!("slave {}: {}", member.simulator.address(), member.name))
        .collect();
    if let (true, [member]) = (one, served.members()) {
        let slave = member.simulator.address();
        note!(
            "optobus: simulating {} (slave {slave}) on {place}{extras}",
            member.name
        );
    } else {
        print(&who.join("\n"));
        note!(
            "optobus: simulating {} ({}) on {place}{extras}",
            counted(who.len(), "device"),
            who.join(", ")
        );
    }
    let _ = std::io::Write::flush(&mut std::io::stdout());
    inputs::until_stopped(args.duration).await;
    drop(server);
    for summary in served.fault_summaries() {
        note!("optobus: {summary}");
    }
    if let Some(stats) = line_stats {
        note!("optobus: {stats}");
    }
    Ok(())
}

/// What keeps a simulation served while it runs, and where it is served, for the log.
type Served = (Box<dyn std::any::Any>, String);

/// Serves `served` as RTU on a new pty, or on the serial port `serial` in `format`, timed as
/// `line` says; prints where on stdout.
fn serve_rtu(
    served: &ServedLine,
    serial: Option<&str>,
    format: Option<LineFormat>,
    line: Option<Line>,
) -> Result<Served, CliError> {
    let (Some(path), Some(format)) = (serial, format) else {
        let pty = served
            .serve_pty(line)
            .map_err(|e| CliError::failed(format!("cannot open a pty: {e}")))?;
        let path = pty.path().display().to_string();
        print(&path);
        return Ok((Box::new(pty), format!("RTU at {path}")));
    };
    let settings = optobus_driver::transport::SerialSettings {
        path: path.to_owned(),
        line: format,
    };
    let port = settings
        .open()
        .map_err(|e| CliError::failed(format!("cannot open {path}: {e}")))?;
    print(path);
    let task = served.serve_stream(port, line);
    Ok((Box::new(task), format!("RTU at {path}")))
}

/// Serves `served` as Modbus TCP on `--tcp` (127.0.0.1:5020 by default); prints where on
/// stdout.
async fn serve_tcp(global: &Global, served: &ServedLine) -> Result<Served, CliError> {
    let address = global.target.tcp.as_deref().unwrap_or("127.0.0.1:5020");
    let address = target::resolve_tcp(address, 5020).await?;
    let server = served.serve_tcp(address).await.map_err(|e| {
        CliError::failed(format!("cannot listen on {address}: {e}"))
            .hint("is another server using the port? try --tcp 127.0.0.1:0")
    })?;
    let address = server.local_addr();
    print(&address.to_string());
    Ok((Box::new(server), format!("Modbus TCP at {address}")))
}
