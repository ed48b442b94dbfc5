//! Commands that are more than a read or a write: serving a simulator, scanning a line, and
//! the P-series buffer download.

use std::io::IsTerminal;
use std::path::Path;
use std::time::Duration;

use clap::Args;
use optobus_codec::{LineFormat, ReadFunction, Request, WriteValue};
use optobus_device::DeviceInfo;
use optobus_driver::transport::Parity;
use optobus_driver::{line_format, serial_settings, Core};
use optobus_simulator::{
    Exchange, FaultKind, FaultStats, Faults, FaultsError, Line, Reply, Simulator,
};

use crate::commands::{answering_slave, print, target};
use crate::error::{driver_error, CliError};
use crate::link::{self, Link};
use crate::log::{self, note, Log};
use crate::{inputs, models, values, Global};

/// One log line for a request the simulator answered.
fn describe(exchange: &Exchange<'_>) -> String {
    let slave = exchange
        .slave
        .map(|s| format!("slave {s} "))
        .unwrap_or_default();
    let request = match exchange.request {
        Some(Request::Read {
            function,
            address,
            count,
        }) => {
            let table = match function {
                ReadFunction::Holding => "holding",
                ReadFunction::Input => "input",
            };
            format!("read {table} {address} x{count}")
        }
        Some(Request::Write { address, value }) => match value {
            WriteValue::Word(word) => format!("write {address} = {word}"),
            WriteValue::DoubleWord(value) => format!("write {address} = {value} (4 bytes)"),
        },
        None => format!("function {:02X}", exchange.function),
    };
    let reply = match exchange.reply {
        Reply::Read { words, .. } => format!("{} words", words.len()),
        Reply::Write { .. } => "echo".to_owned(),
        Reply::Exception { code, .. } => format!("exception {:02X}", code.0),
        Reply::Silent => "no reply".to_owned(),
    };
    format!("{} {slave}{request} -> {reply}", link::timestamp())
}

/// `optobus simulate`'s arguments.
#[derive(Debug, Args)]
pub(crate) struct SimulateArgs {
    /// The model (default: --model).
    pub(crate) model: Option<String>,
    /// Serve RTU on a new pseudo-terminal and print its path.
    #[arg(long)]
    pub(crate) pty: bool,
    /// Stop after this long, at most 24 h (default: until Ctrl-C).
    #[arg(long, value_parser = inputs::parse_run_for, allow_hyphen_values = true)]
    pub(crate) duration: Option<Duration>,
    /// Inject seeded faults into the replies, e.g. `delay=0.1,corrupt=0.05` (kinds: corrupt,
    /// truncate, garbage, wrong_slave, split, drop, delay, disconnect; also late=, pause=,
    /// timeout=, seed=).
    #[arg(long, value_name = "SPEC")]
    pub(crate) faults: Option<String>,
    /// Seed of --faults (overrides its seed=; default 0): same seed, same faults.
    #[arg(long, requires = "faults")]
    pub(crate) seed: Option<u64>,
    /// Time RTU serving (--pty, --serial) like an RS-485 line of the model's factory format
    /// (or --baud, --parity): a character time per byte, t3.5 gaps, --turnaround.
    #[arg(long)]
    pub(crate) line_timing: bool,
    /// With --line-timing, the device's reaction time after a request's t3.5 (at most 24 h).
    #[arg(long, requires = "line_timing", default_value = "0", value_parser = inputs::parse_turnaround, allow_hyphen_values = true)]
    pub(crate) turnaround: Duration,
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

/// The emulated line of `--line-timing`: the model's factory format with `--baud` and
/// `--parity` applied, and `--turnaround`.
fn line(device: &DeviceInfo, global: &Global, args: &SimulateArgs) -> Result<Line, CliError> {
    let format = serial_format(device, global);
    format
        .check()
        .map_err(|e| CliError::new(format!("--line-timing cannot time this line: {e}")))?;
    Ok(Line::new(format).turnaround(args.turnaround))
}

/// The model's factory line format with `--baud` and `--parity` applied.
fn serial_format(device: &DeviceInfo, global: &Global) -> LineFormat {
    let mut format = line_format(device);
    if let Some(baud) = global.baud {
        format.baud = baud;
    }
    if let Some(parity) = global.parity.and_then(|p| Parity::from_name(p.name())) {
        format.parity = parity;
    }
    format
}

/// `9600 baud 8E1`.
fn format_text(format: LineFormat) -> String {
    let parity = match format.parity {
        Parity::None => 'N',
        Parity::Odd => 'O',
        Parity::Even => 'E',
    };
    format!(
        "{} baud {}{parity}{}",
        format.baud, format.data_bits, format.stop_bits
    )
}

/// One line of the faults injected per kind, for the end of a run.
fn fault_summary(faults: &Faults, stats: &FaultStats) -> String {
    let kinds: Vec<String> = FaultKind::ALL
        .into_iter()
        .filter(|&kind| faults.probability(kind) > 0.0 || stats.count(kind) > 0)
        .map(|kind| format!("{kind} {}", stats.count(kind)))
        .collect();
    let kinds = if kinds.is_empty() {
        String::new()
    } else {
        format!(" ({})", kinds.join(", "))
    };
    format!(
        "optobus: faults injected: {} of {} replies{kinds}",
        stats.injected(),
        stats.replies()
    )
}

/// `optobus simulate`: serves a virtual device until Ctrl-C or `--duration`, with `--faults`
/// in its replies and, on RTU, `--line-timing`. Every exchange is logged on stderr by a
/// thread of its own ([`Log`]), so a slow or closed stderr never holds up a reply.
pub(crate) async fn simulate(
    device: &'static DeviceInfo,
    global: &Global,
    args: &SimulateArgs,
) -> Result<(), CliError> {
    let slave = global.slave.unwrap_or(device.default_slave);
    if slave == 0 {
        return Err(CliError::new(
            "a device never has slave address 0: it is the broadcast address",
        )
        .hint("serve at 1 to 247 with --slave"));
    }
    let faults = faults(args)?;
    let rtu = args.pty || global.serial.is_some();
    let line = if args.line_timing {
        if !rtu {
            return Err(CliError::new(
                "--line-timing times an RTU serial line; Modbus TCP has no line to time",
            )
            .hint("serve RTU with --pty or --serial PORT"));
        }
        Some(line(device, global, args)?)
    } else {
        None
    };
    let mut extras = String::new();
    if let Some(faults) = &faults {
        extras.push_str(&format!(", faults {faults}"));
    }
    if let Some(line) = &line {
        extras.push_str(&format!(
            ", line timed at {}, turnaround {:?}",
            format_text(line.format()),
            args.turnaround
        ));
    }
    let log = Log::start();
    let mut sim = Simulator::new(device).slave(slave).observe({
        let log = log.clone();
        move |exchange| log.line(describe(exchange))
    });
    if let Some(faults) = &faults {
        sim = sim.faults(faults.clone());
    }
    let line_stats = line.as_ref().map(Line::stats);
    let serving = Serving {
        device,
        global,
        pty: args.pty,
        slave,
        line,
        extras: &extras,
    };
    let served = match serve(serving, &sim, &log).await {
        Ok(server) => {
            let _ = std::io::Write::flush(&mut std::io::stdout());
            match args.duration {
                Some(duration) => tokio::select! {
                    () = tokio::time::sleep(duration) => {}
                    _ = tokio::signal::ctrl_c() => {}
                },
                None => {
                    let _ = tokio::signal::ctrl_c().await;
                }
            }
            drop(server);
            if let (Some(faults), Some(stats)) = (&faults, sim.fault_stats()) {
                log.line(fault_summary(faults, &stats));
            }
            if let Some(stats) = line_stats {
                log.line(format!(
                    "optobus: line: {} requests, {} replies, {} requests sent within t3.5 of a reply",
                    stats.frames(),
                    stats.replies(),
                    stats.gap_violations()
                ));
            }
            Ok(())
        }
        Err(error) => Err(error),
    };
    // The summary and whether lines were dropped, if stderr takes them.
    log.finish(Duration::from_millis(200));
    served
}

/// Where and how [`serve`] serves.
struct Serving<'a> {
    device: &'static DeviceInfo,
    global: &'a Global,
    pty: bool,
    slave: u8,
    /// `--line-timing` (RTU only).
    line: Option<Line>,
    /// Said after the place in the startup line: faults and line timing in force.
    extras: &'a str,
}

/// Starts serving `sim` as `serving` says; gives what must be kept alive.
async fn serve(
    serving: Serving<'_>,
    sim: &Simulator,
    log: &Log,
) -> Result<Box<dyn std::any::Any>, CliError> {
    let Serving {
        device,
        global,
        pty,
        slave,
        line,
        extras,
    } = serving;
    Ok(if pty {
        let pty = match line {
            Some(line) => sim.serve_pty_line(line),
            None => sim.serve_pty(),
        }
        .map_err(|e| CliError::new(format!("cannot open a pty: {e}")))?;
        print(&pty.path().display().to_string());
        log.line(format!(
            "optobus: simulating {} (slave {slave}) on RTU at {}{extras}",
            device.family,
            pty.path().display()
        ));
        Box::new(pty)
    } else if let Some(path) = &global.serial {
        let mut settings = serial_settings(device, path.as_str());
        settings.line = serial_format(device, global);
        let port = settings
            .open()
            .map_err(|e| CliError::new(format!("cannot open {path}: {e}")))?;
        print(path);
        log.line(format!(
            "optobus: simulating {} (slave {slave}) on RTU at {path}{extras}",
            device.family
        ));
        let sim = sim.clone();
        Box::new(tokio::spawn(async move {
            match line {
                Some(line) => sim.serve_line(port, &line).await,
                None => sim.serve_rtu(port).await,
            }
        }))
    } else {
        let address = global.tcp.as_deref().unwrap_or("127.0.0.1:5020");
        let address = link::resolve_tcp(address, 5020).await?;
        let server = sim.serve_tcp(address).await.map_err(|e| {
            CliError::new(format!("cannot listen on {address}: {e}"))
                .hint("is another server using the port? try --tcp 127.0.0.1:0")
        })?;
        print(&server.local_addr().to_string());
        log.line(format!(
            "optobus: simulating {} (slave {slave}) on Modbus TCP at {}{extras}",
            device.family,
            server.local_addr()
        ));
        Box::new(server)
    })
}

/// `optobus scan`: which baud rate and slave address a device answers on.
pub(crate) async fn scan(
    global: &Global,
    bauds: Option<&str>,
    slaves: Option<&str>,
) -> Result<(), CliError> {
    let device = models::find(&global.model)?;
    answering_slave(device, global, "scan")?;
    let bauds: Vec<u32> = match (bauds, global.baud) {
        (Some(text), _) => inputs::parse_bauds(device, text, global.any_baud)?,
        (None, Some(baud)) => {
            inputs::check_baud(device, "--baud", baud, global.any_baud)?;
            vec![baud]
        }
        (None, None) => device
            .rtu
            .map(|r| r.bauds.to_vec())
            .unwrap_or_else(|| vec![9600]),
    };
    let slaves = match slaves {
        Some(text) => inputs::parse_slaves(text)?,
        None => {
            let (first, last) = inputs::SLAVES;
            (device.slaves.0.max(first)..=device.slaves.1.min(last)).collect()
        }
    };
    let Some(path) = &global.serial else {
        return Err(CliError::new("scan needs a serial port").hint("give --serial PORT"));
    };
    let probe = device
        .registers
        .iter()
        .find(|r| r.access.readable())
        .ok_or_else(|| CliError::new("the model has no readable register"))?;
    let progress = std::io::stderr().is_terminal();
    let mut found = Vec::new();
    for &baud in &bauds {
        let mut target = target(global);
        target.baud = Some(baud);
        // A silent address costs the whole timeout: keep it short unless asked otherwise.
        target.timeout = global.timeout.min(Duration::from_millis(200));
        let link = link::open(device, 0, &target).await?;
        let mut core = Core::with_default_slave(link, device);
        for (i, &slave) in slaves.iter().enumerate() {
            if progress {
                log::stderr(format_args!(
                    "\rscanning {baud} baud: slave {slave} ({}/{})   ",
                    i + 1,
                    slaves.len()
                ));
            }
            core.set_slave(slave)?;
            let answered = match core.read_words(probe).await {
                Ok(_) => true,
                // An exception is an answer too: something lives at this address.
                Err(e) => e.exception().is_some(),
            };
            if answered {
                if progress {
                    note!();
                }
                print(&format!("found: slave {slave} at {baud} baud"));
                found.push((baud, slave));
            }
        }
    }
    if progress {
        note!();
    }
    if global.json {
        let list: Vec<serde_json::Value> = found
            .iter()
            .map(|(baud, slave)| serde_json::json!({"baud": baud, "slave": slave}))
            .collect();
        print(&serde_json::Value::Array(list).to_string());
    }
    if found.is_empty() {
        return Err(CliError::new(format!("no device answered on {path}"))
            .hint("check wiring and parity, or widen --bauds and --slaves"));
    }
    Ok(())
}

/// The measurement `source` names, with `count` checked against the values the P series lets
/// be read out (appendix 3): both refused before anything is opened or sent.
pub(crate) fn buffer_input(
    count: u16,
    source: &str,
) -> Result<optobus_p_series::MeasurementSource, CliError> {
    use optobus_p_series::{MeasurementSource, DEVICE};
    let register = |name: &str| {
        DEVICE
            .register(name)
            .ok_or_else(|| CliError::new(format!("the P-series spec has no {name}")))
    };
    let most = optobus_p_series::download::MAX_DOWNLOAD;
    if !(1..=most).contains(&count) {
        return Err(CliError::new(format!(
            "--count {count}: the P series buffers 1 to {most} values for reading out"
        )));
    }
    let words = values::parse(register("buffer_data_type")?, source)?;
    Ok(MeasurementSource::from_raw(u32::from(
        words.first().copied().unwrap_or(0),
    )))
}

/// `optobus buffer` (P series): buffer `count` values of `source`, download, write CSV.
pub(crate) async fn buffer(
    link: Link,
    slave: u8,
    global: &Global,
    count: u16,
    source: optobus_p_series::MeasurementSource,
    wait: Duration,
    out: Option<&Path>,
) -> Result<(), CliError> {
    use optobus_p_series::PSeries;
    let mut sensor = PSeries::new(link, slave)?;
    sensor
        .start_buffering(source, count)
        .await
        .map_err(|e| driver_error(e, Some("buffer_report_count")))?;
    note!(
        "optobus: buffering {count} values of {source}; reading out in {} ms",
        wait.as_millis()
    );
    tokio::time::sleep(wait).await;
    let terminal = std::io::stderr().is_terminal();
    let values = sensor
        .download_buffer(|p| {
            let width = 30;
            let done = (p.received * width)
                .checked_div(p.expected)
                .unwrap_or(width);
            let bar = format!(
                "[{}{}] {}/{} values, {} pages",
                "#".repeat(done),
                "-".repeat(width - done.min(width)),
                p.received,
                p.expected,
                p.pages
            );
            if terminal {
                log::stderr(format_args!("\r{bar}"));
            } else {
                note!("{bar}");
            }
        })
        .await
        .map_err(|e| driver_error(e, Some("buffer")))?;
    if terminal {
        note!();
    }
    let mut csv = String::from("index,value_mm\n");
    for (index, value) in values.iter().enumerate() {
        match value {
            Some(value) => csv.push_str(&format!("{index},{}\n", value.millimetres())),
            None => csv.push_str(&format!("{index},\n")),
        }
    }
    if global.json && out.is_none() {
        let list: Vec<serde_json::Value> = values
            .iter()
            .map(|v| match v {
                Some(v) => serde_json::json!(v.to_f64()),
                None => serde_json::Value::Null,
            })
            .collect();
        print(&serde_json::json!({"unit": "mm", "values": list}).to_string());
        return Ok(());
    }
    match out {
        Some(path) => {
            std::fs::write(path, csv)
                .map_err(|e| CliError::new(format!("cannot write {}: {e}", path.display())))?;
            note!(
                "optobus: {} values written to {}",
                values.len(),
                path.display()
            );
        }
        None => print(&csv),
    }
    Ok(())
}
