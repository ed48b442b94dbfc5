//! Connecting to a device: a serial port, a TCP address (the transport's [`Port`], opened to
//! its [`Client`] as the bus's lines are), or the built-in simulator. (With `--verbose` the
//! transport's own frame events are shown: see `log::show_frames`.)

use std::net::SocketAddr;
use std::time::Duration;

use clap::Args;
use optobus_device::DeviceInfo;
use optobus_driver::transport::{
    self, Client, ClientConfig, Error as WireError, LineFormat, Port, SerialSettings,
};
use optobus_driver::{line_format, rtu_config, tcp_config};
use optobus_simulator::{Line, Simulator};

use crate::error::CliError;
use crate::inputs::{self, ParityArg, SimSpeed};

/// How to reach the device, from the command line.
#[derive(Clone, Debug, Args)]
pub(crate) struct Target {
    /// Serial port of the device (e.g. /dev/ttyUSB0); default settings from the manual.
    #[arg(long, conflicts_with = "tcp")]
    pub(crate) serial: Option<String>,
    /// Baud rate, when the device is not at its factory setting: one its manual lists.
    #[arg(long)]
    pub(crate) baud: Option<u32>,
    /// Parity: none, odd or even (n, o, e).
    #[arg(long, ignore_case = true)]
    pub(crate) parity: Option<ParityArg>,
    /// Data bits per character, 5 to 8 (default: the model's factory setting).
    #[arg(long, value_parser = clap::value_parser!(u8).range(5..=8))]
    pub(crate) data_bits: Option<u8>,
    /// Stop bits, 1 or 2 (default: the model's factory setting).
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=2))]
    pub(crate) stop_bits: Option<u8>,
    /// Modbus TCP address of the device: HOST or HOST:PORT.
    #[arg(long)]
    pub(crate) tcp: Option<String>,
    /// Reply timeout, e.g. 500ms or 2s (1 ms to 24 h).
    #[arg(long, default_value = "1s", value_parser = inputs::TIMEOUT.parser(), allow_hyphen_values = true)]
    pub(crate) timeout: Duration,
    /// Print every frame sent and received, in hex with the local time, and the registers
    /// read and written, on stderr.
    #[arg(long, short)]
    pub(crate) verbose: bool,
    /// How fast the built-in simulator answers (no --serial or --tcp): `line` (the default),
    /// timed as the model's serial line (factory format, or --baud, --parity…), as a device
    /// would; `full`, as fast as memory allows.
    #[arg(long, value_enum, conflicts_with_all = ["serial", "tcp"])]
    pub(crate) sim_speed: Option<SimSpeed>,
}

impl Target {
    /// The real device the options address, as given (`--tcp HOST`, `--serial PORT`); `None`
    /// for the built-in simulator.
    pub(crate) fn addressed(&self) -> Option<String> {
        match (&self.tcp, &self.serial) {
            (Some(address), _) => Some(format!("--tcp {address}")),
            (None, Some(port)) => Some(format!("--serial {port}")),
            (None, None) => None,
        }
    }

    /// The model's factory line format with `--baud`, `--parity`, `--data-bits` and
    /// `--stop-bits` applied.
    pub(crate) fn line_format(&self, device: &DeviceInfo) -> LineFormat {
        let parity = self.parity.map(ParityArg::parity);
        line_format(device).changed(self.baud, parity, self.data_bits, self.stop_bits)
    }
}

/// `host`, `host:port` or `[v6]:port`, with the device's port as the default.
pub(crate) async fn resolve_tcp(address: &str, default_port: u16) -> Result<SocketAddr, CliError> {
    transport::resolve(address, default_port)
        .await
        .map_err(|e| CliError::failed(format!("cannot resolve `{address}`: {e}")))
}

/// Opens the link `target` describes to `device`; without a serial port or TCP address, the
/// built-in simulator (said on stderr).
pub(crate) async fn open(
    device: &'static DeviceInfo,
    slave: u8,
    target: &Target,
) -> Result<Client, CliError> {
    if target.verbose {
        crate::log::show_frames();
    }
    let mut config = ClientConfig {
        rtu: rtu_config(device),
        tcp: tcp_config(device),
    };
    config.rtu.timeout = target.timeout;
    config.tcp.timeout = target.timeout;
    if let Some(path) = &target.serial {
        let settings = SerialSettings {
            path: path.clone(),
            line: target.line_format(device),
        };
        config.rtu.line = Some(settings.line);
        return Port::Serial(settings)
            .open(config, |stream| stream)
            .await
            .map_err(|e| {
                CliError::failed(format!("cannot open {path}: {e}")).hint(
                    "check the path, that no other program holds the port, and your permissions",
                )
            });
    }
    if let Some(address) = &target.tcp {
        let default_port = device.tcp.map_or(502, |t| t.port);
        // Resolved here to say which of resolving and connecting failed.
        let address = resolve_tcp(address, default_port).await?;
        let cannot_connect = |e: WireError| {
            let why = match e {
                WireError::Connect { source, .. } => source.to_string(),
                other => other.to_string(),
            };
            CliError::failed(format!("cannot connect to {address}: {why}"))
        };
        let port = Port::Tcp {
            address: address.to_string(),
            default_port,
        };
        let mut client = port
            .open(config, |stream| stream)
            .await
            .map_err(cannot_connect)?;
        client.connect().await.map_err(cannot_connect)?;
        return Ok(client);
    }
    // A broadcast reaches the simulator at its own address.
    let address = if slave == 0 {
        device.default_slave
    } else {
        slave
    };
    let reached = if slave == 0 {
        ", which a broadcast reaches"
    } else {
        ""
    };
    crate::log::note!(
        "optobus: no --serial or --tcp given: using the built-in {} simulator (slave \
         {address}{reached})",
        crate::models::name(device)
    );
    let simulator = Simulator::new(device).slave(address);
    let (stream, _server) = match target.sim_speed.unwrap_or(SimSpeed::Line) {
        SimSpeed::Line => {
            let format = target.line_format(device);
            format.check().map_err(|e| {
                CliError::new(format!("the simulator cannot time this line: {e}"))
                    .hint("give a rate the model's manual lists, or --sim-speed full")
            })?;
            // The client keeps the line's t3.5, as on a serial port.
            config.rtu.line = Some(format);
            simulator.duplex_line(Line::new(format))
        }
        SimSpeed::Full => {
            // The line is memory: no serial timing.
            config.rtu.line = None;
            simulator.duplex()
        }
    };
    Ok(Client::rtu(stream, config.rtu))
}
