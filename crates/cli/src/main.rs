//! `optobus`: read, watch, set and simulate optical distance sensors over Modbus.
//!
//! Without `--serial` or `--tcp` every device command runs against the built-in simulator
//! of the chosen model, so the tool works on a laptop with nothing attached.
#![forbid(unsafe_code)]

mod commands;
mod error;
mod frame;
mod inputs;
mod link;
mod log;
mod models;
mod serve;
mod values;

use std::process::ExitCode;
use std::time::Duration;

use clap::{Args, Parser, Subcommand};

/// Read, watch and set industrial optical distance sensors over Modbus RTU or TCP.
///
/// Without --serial or --tcp, device commands talk to the built-in simulator of --model.
#[derive(Debug, Parser)]
#[command(name = "optobus", version, propagate_version = true)]
struct Cli {
    #[command(flatten)]
    global: Global,
    #[command(subcommand)]
    command: Command,
}

/// Options every command takes.
#[derive(Debug, Args)]
struct Global {
    /// Sensor family: p-series, rangefinder, ccs, lc-rs, ccf (see `optobus models`).
    #[arg(long, short, global = true, default_value = "p-series")]
    model: String,
    /// Serial port of the device (e.g. /dev/ttyUSB0); default settings from the manual.
    #[arg(long, global = true, conflicts_with = "tcp")]
    serial: Option<String>,
    /// Baud rate, when the device is not at its factory setting: one its manual lists.
    #[arg(long, global = true)]
    baud: Option<u32>,
    /// Allow a --baud (or scan --bauds) rate the model's manual does not list.
    #[arg(long, global = true)]
    any_baud: bool,
    /// Parity: none, odd or even (n, o, e).
    #[arg(long, global = true, ignore_case = true)]
    parity: Option<inputs::ParityArg>,
    /// Modbus TCP address of the device: HOST or HOST:PORT.
    #[arg(long, global = true)]
    tcp: Option<String>,
    /// Slave address, 1 to 247 (default: the model's factory setting); 0 broadcasts a write
    /// (`set`, `do`), which no device answers.
    #[arg(long, global = true, value_parser = inputs::parse_slave, allow_hyphen_values = true)]
    slave: Option<u8>,
    /// Reply timeout, e.g. 500ms or 2s (1 ms to 24 h).
    #[arg(long, global = true, default_value = "1s", value_parser = inputs::parse_timeout, allow_hyphen_values = true)]
    timeout: Duration,
    /// Print data as JSON.
    #[arg(long, global = true)]
    json: bool,
    /// Print every frame sent and received, in hex with a timestamp, on stderr.
    #[arg(long, short, global = true)]
    verbose: bool,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// The sensor families, their transports and defaults.
    Models,
    /// The register map of a model: name, table, address, access, type, unit, range or codes.
    Registers {
        /// The model (default: --model).
        model: Option<String>,
    },
    /// Read registers or groups and print typed values with units.
    Read {
        /// Register or group names (`optobus registers` lists them).
        #[arg(required = true)]
        names: Vec<String>,
        /// Copy of a per-channel register (CCF channels 1 to 4).
        #[arg(long)]
        channel: Option<u8>,
    },
    /// Show registers or groups live, refreshed in place; Ctrl-C ends.
    Watch {
        /// Register or group names.
        #[arg(required = true)]
        names: Vec<String>,
        /// Time between refreshes (1 ms to 24 h).
        #[arg(long, default_value = "200ms", value_parser = inputs::parse_interval, allow_hyphen_values = true)]
        interval: Duration,
        /// Copy of a per-channel register.
        #[arg(long)]
        channel: Option<u8>,
        /// Stop after this many refreshes (default: until Ctrl-C).
        #[arg(long)]
        count: Option<u64>,
    },
    /// Every readable register, decoded, read in the fewest transactions.
    Dump,
    /// Write a register: engineering units (`100us`, `42.5`) or code names.
    Set {
        /// Register name.
        name: String,
        /// The value.
        value: String,
        /// Copy of a per-channel register.
        #[arg(long)]
        channel: Option<u8>,
        /// Confirm a write to a register that a command storing, restarting or resetting the
        /// device also writes.
        #[arg(long)]
        yes: bool,
    },
    /// Run a command of the device (zero, reset, save, reboot…).
    Do {
        /// Command name (`optobus models` and `optobus registers` list them).
        command: String,
        /// Channel of a per-channel command.
        #[arg(long)]
        channel: Option<u8>,
        /// Confirm commands that store, restart or reset the device.
        #[arg(long)]
        yes: bool,
    },
    /// P series: buffer and download measurements, with a progress bar.
    Buffer {
        /// Values to buffer and download (at most 2500).
        #[arg(long)]
        count: u16,
        /// Measurement to buffer: distance_1, distance_2 or thickness.
        #[arg(long, default_value = "distance_1")]
        source: String,
        /// How long to let the sensor buffer before reading out (at most 24 h).
        #[arg(long, default_value = "1s", value_parser = inputs::parse_wait, allow_hyphen_values = true)]
        wait: Duration,
        /// Write `index,value_mm` CSV here instead of stdout.
        #[arg(long)]
        out: Option<std::path::PathBuf>,
    },
    /// Find the slave address and baud rate a device answers on.
    Scan {
        /// Baud rates to try, e.g. 9600,115200 (default: --baud, or the model's).
        #[arg(long)]
        bauds: Option<String>,
        /// Slave addresses to try, e.g. 1-10,247 (default: the model's range).
        #[arg(long)]
        slaves: Option<String>,
    },
    /// Serve a virtual device for other Modbus tools: Modbus TCP on --tcp (default
    /// 127.0.0.1:5020), RTU on a new pty (--pty) or on an existing port (--serial).
    Simulate(serve::SimulateArgs),
    /// Encode request bytes, or explain captured frames.
    #[command(subcommand)]
    Frame(frame::FrameCommand),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let runtime = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(runtime) => runtime,
        Err(error) => {
            log::note!("optobus: cannot start: {error}");
            return ExitCode::FAILURE;
        }
    };
    match runtime.block_on(commands::run(cli.global, cli.command)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            log::note!("optobus: {error}");
            ExitCode::FAILURE
        }
    }
}
