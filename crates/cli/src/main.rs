//! `optobus`: read, watch, set and simulate optical distance sensors over Modbus.
//!
//! Without `--serial` or `--tcp` every device command runs against the built-in simulator
//! of the chosen model, so the tool works on a laptop with nothing attached.
#![forbid(unsafe_code)]

mod commands;
mod error;
mod frame;
mod link;
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
    /// Baud rate, when the device is not at its factory setting.
    #[arg(long, global = true)]
    baud: Option<u32>,
    /// Parity: none, odd or even.
    #[arg(long, global = true)]
    parity: Option<String>,
    /// Modbus TCP address of the device: HOST or HOST:PORT.
    #[arg(long, global = true)]
    tcp: Option<String>,
    /// Slave address (default: the model's factory setting).
    #[arg(long, global = true)]
    slave: Option<u8>,
    /// Reply timeout, e.g. 500ms or 2s.
    #[arg(long, global = true, default_value = "1s", value_parser = parse_duration)]
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
        /// Time between refreshes.
        #[arg(long, default_value = "200ms", value_parser = parse_duration)]
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
        /// How long to let the sensor buffer before reading out.
        #[arg(long, default_value = "1s", value_parser = parse_duration)]
        wait: Duration,
        /// Write `index,value_mm` CSV here instead of stdout.
        #[arg(long)]
        out: Option<std::path::PathBuf>,
    },
    /// Find the slave address and baud rate a device answers on.
    Scan {
        /// Baud rates to try (default: the model's).
        #[arg(long, value_delimiter = ',')]
        bauds: Vec<u32>,
        /// Slave addresses to try, e.g. 1-10,247 (default: the model's range).
        #[arg(long)]
        slaves: Option<String>,
    },
    /// Serve a virtual device for other Modbus tools: Modbus TCP on --tcp (default
    /// 127.0.0.1:5020), RTU on a new pty (--pty) or on an existing port (--serial).
    Simulate {
        /// The model (default: --model).
        model: Option<String>,
        /// Serve RTU on a new pseudo-terminal and print its path.
        #[arg(long)]
        pty: bool,
        /// Stop after this long (default: until Ctrl-C).
        #[arg(long, value_parser = parse_duration)]
        duration: Option<Duration>,
    },
    /// Encode request bytes, or explain captured frames.
    #[command(subcommand)]
    Frame(frame::FrameCommand),
}

/// `200ms`, `1s`, `1.5s`, `2m`, or a bare number of milliseconds.
fn parse_duration(text: &str) -> Result<Duration, String> {
    let text = text.trim();
    let split = text
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(text.len());
    let (number, unit) = text.split_at(split);
    let number: f64 = number
        .parse()
        .map_err(|_| format!("`{text}` is not a duration (e.g. 200ms, 1s)"))?;
    let seconds = match unit.trim() {
        "" | "ms" => number / 1000.0,
        "s" => number,
        "m" | "min" => number * 60.0,
        "us" | "µs" => number / 1e6,
        other => return Err(format!("unknown time unit `{other}` (use ms, s or m)")),
    };
    Duration::try_from_secs_f64(seconds).map_err(|_| format!("`{text}` is out of range"))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let runtime = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(runtime) => runtime,
        Err(error) => {
            eprintln!("optobus: cannot start: {error}");
            return ExitCode::FAILURE;
        }
    };
    match runtime.block_on(commands::run(cli.global, cli.command)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("optobus: {error}");
            ExitCode::FAILURE
        }
    }
}
