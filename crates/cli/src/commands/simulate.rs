//! `optobus simulate`: a virtual device served over Modbus TCP, a pty or a serial port, with
//! seeded faults and RS-485 line timing on request; every exchange logged on stderr.

use std::time::Duration;

use clap::Args;
use optobus_device::DeviceInfo;
use optobus_driver::serial_settings;
use optobus_simulator::{Faults, FaultsError, Line, Simulator};

use crate::connect::{DeviceArgs, Global};
use crate::error::CliError;
use crate::log::Log;
use crate::render::print;
use crate::{inputs, link};

/// `optobus simulate`'s arguments.
#[derive(Debug, Args)]
pub(crate) struct SimulateArgs {
    /// The model (default: --model).
    model: Option<String>,
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

/// The emulated line of `--line-timing`: the model's factory format with `--baud` and
/// `--parity` applied, and `--turnaround`.
fn line(device: &DeviceInfo, global: &Global, args: &SimulateArgs) -> Result<Line, CliError> {
    let format = global.target.line_format(device);
    format
        .check()
        .map_err(|e| CliError::new(format!("--line-timing cannot time this line: {e}")))?;
    Ok(Line::new(format).turnaround(args.turnaround))
}

/// `optobus simulate`: serves a virtual device until Ctrl-C or `--duration`, with `--faults`
/// in its replies and, on RTU, `--line-timing`. Every exchange is logged on stderr by a
/// thread of its own ([`Log`]), so a slow or closed stderr never holds up a reply.
pub(crate) async fn run(global: &Global, args: &SimulateArgs) -> Result<(), CliError> {
    let device = global.device_or(args.model.as_deref())?;
    if global.target.sim_speed.is_some() {
        return Err(CliError::new(
            "--sim-speed sets how fast a device command's own simulator answers (no --serial or --tcp)",
        )
        .hint("time a served RTU line with --line-timing"));
    }
    global.check_line(device)?;
    let slave = global.slave.unwrap_or(device.default_slave);
    if slave == 0 {
        return Err(CliError::new(
            "a device never has slave address 0: it is the broadcast address",
        )
        .hint("serve at 1 to 247 with --slave"));
    }
    let faults = faults(args)?;
    let rtu = args.pty || global.target.serial.is_some();
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
    let faulty = faults.as_ref().map(|f| format!(", faults {f}"));
    let timed = line.as_ref().map(|line| {
        let turnaround = args.turnaround;
        format!(
            ", line timed at {}, turnaround {turnaround:?}",
            line.format()
        )
    });
    let extras = faulty.unwrap_or_default() + &timed.unwrap_or_default();
    let log = Log::start();
    let mut sim = Simulator::new(device).slave(slave).observe({
        let log = log.clone();
        move |exchange| log.line(format!("{} {exchange}", crate::render::time_of_day()))
    });
    if let Some(faults) = &faults {
        sim = sim.faults(faults.clone());
    }
    let line_stats = line.as_ref().map(Line::stats);
    let served = async {
        let (server, place) = serve(device, global, args.pty, line, &sim).await?;
        log.line(format!(
            "optobus: simulating {} (slave {slave}) on {place}{extras}",
            crate::models::name(device)
        ));
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
            log.line(format!("optobus: {}", stats.summary(faults)));
        }
        if let Some(stats) = line_stats {
            log.line(format!("optobus: {stats}"));
        }
        Ok(())
    }
    .await;
    // The summary and whether lines were dropped, if stderr takes them.
    log.finish(Duration::from_millis(200));
    served
}

/// Starts serving `sim`: on a new pty, on `--serial` or on `--tcp`, RTU timed as `line` says;
/// prints where on stdout and gives what must be kept alive, and where it serves for the log.
async fn serve(
    device: &'static DeviceInfo,
    global: &Global,
    pty: bool,
    line: Option<Line>,
    sim: &Simulator,
) -> Result<(Box<dyn std::any::Any>, String), CliError> {
    Ok(if pty {
        let pty = match line {
            Some(line) => sim.serve_pty_line(line),
            None => sim.serve_pty(),
        }
        .map_err(|e| CliError::failed(format!("cannot open a pty: {e}")))?;
        let path = pty.path().display().to_string();
        print(&path);
        (Box::new(pty), format!("RTU at {path}"))
    } else if let Some(path) = &global.target.serial {
        let mut settings = serial_settings(device, path.as_str());
        settings.line = global.target.line_format(device);
        let port = settings
            .open()
            .map_err(|e| CliError::failed(format!("cannot open {path}: {e}")))?;
        print(path);
        let sim = sim.clone();
        let task = tokio::spawn(async move {
            match line {
                Some(line) => sim.serve_line(port, &line).await,
                None => sim.serve_rtu(port).await,
            }
        });
        (Box::new(task), format!("RTU at {path}"))
    } else {
        let address = global.target.tcp.as_deref().unwrap_or("127.0.0.1:5020");
        let address = link::resolve_tcp(address, 5020).await?;
        let server = sim.serve_tcp(address).await.map_err(|e| {
            CliError::failed(format!("cannot listen on {address}: {e}"))
                .hint("is another server using the port? try --tcp 127.0.0.1:0")
        })?;
        let address = server.local_addr();
        print(&address.to_string());
        (Box::new(server), format!("Modbus TCP at {address}"))
    })
}
