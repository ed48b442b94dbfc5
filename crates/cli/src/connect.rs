//! The options every command takes, and what they mean for reaching the device: the slave
//! address, the line checks, a connection, and reading registers over it.

use std::time::Duration;

use clap::Args;
use optobus_device::{DeviceInfo, RegisterInfo};
use optobus_driver::Core;
use optobus_inspect::{decode_value, Value};

use crate::error::{driver_error, CliError};
use crate::link::{self, Link, Target};
use crate::{inputs, models};

/// Options every command takes.
#[derive(Debug, Args)]
pub(crate) struct Global {
    /// Sensor family (help and default from the models, at startup).
    #[arg(long, short, global = true)]
    pub(crate) model: String,
    /// A spec file to use as the model instead of a built-in one (checked like
    /// `optobus-codegen check`).
    #[arg(long, global = true, value_name = "SPEC.yaml")]
    pub(crate) spec: Option<std::path::PathBuf>,
    /// Serial port of the device (e.g. /dev/ttyUSB0); default settings from the manual.
    #[arg(long, global = true, conflicts_with = "tcp")]
    pub(crate) serial: Option<String>,
    /// Baud rate, when the device is not at its factory setting: one its manual lists.
    #[arg(long, global = true)]
    pub(crate) baud: Option<u32>,
    /// Allow a --baud (or scan --bauds) rate the model's manual does not list.
    #[arg(long, global = true)]
    pub(crate) any_baud: bool,
    /// Parity: none, odd or even (n, o, e).
    #[arg(long, global = true, ignore_case = true)]
    pub(crate) parity: Option<inputs::ParityArg>,
    /// Modbus TCP address of the device: HOST or HOST:PORT.
    #[arg(long, global = true)]
    pub(crate) tcp: Option<String>,
    /// Slave address, 1 to 247 (default: the model's factory setting); 0 broadcasts a write
    /// (`set`, `do`), which no device answers.
    #[arg(long, global = true, value_parser = inputs::parse_slave, allow_hyphen_values = true)]
    pub(crate) slave: Option<u8>,
    /// Reply timeout, e.g. 500ms or 2s (1 ms to 24 h).
    #[arg(long, global = true, default_value = "1s", value_parser = inputs::TIMEOUT.parser(), allow_hyphen_values = true)]
    pub(crate) timeout: Duration,
    /// Print data as JSON.
    #[arg(long, global = true)]
    pub(crate) json: bool,
    /// Print every frame sent and received, in hex with a timestamp, on stderr.
    #[arg(long, short, global = true)]
    pub(crate) verbose: bool,
}

impl Global {
    /// The model `--spec` describes, or else the one `--model` names.
    pub(crate) fn device(&self) -> Result<&'static DeviceInfo, CliError> {
        self.device_or(None)
    }

    /// The model `--spec` describes, or else the one a command names itself (`simulate ccs`),
    /// or else the one `--model` names. (A command's own model argument shares `--model`'s
    /// id, so it also carries `--model`'s value.)
    pub(crate) fn device_or(&self, named: Option<&str>) -> Result<&'static DeviceInfo, CliError> {
        match &self.spec {
            Some(spec) => models::load(spec),
            None => models::find(named.unwrap_or(&self.model)),
        }
    }

    pub(crate) fn target(&self) -> Target {
        Target {
            serial: self.serial.clone(),
            baud: self.baud,
            parity: self.parity.map(inputs::ParityArg::parity),
            tcp: self.tcp.clone(),
            timeout: self.timeout,
            verbose: self.verbose,
        }
    }

    /// The serial line settings that can be checked without a port: `--baud` is one the
    /// model's manual lists (any rate a port can run at with `--any-baud`).
    pub(crate) fn check_line(&self, device: &DeviceInfo) -> Result<(), CliError> {
        match self.baud {
            Some(baud) => inputs::check_baud(device, "--baud", baud, self.any_baud),
            None => Ok(()),
        }
    }

    /// The slave address of a command that needs replies: never 0, the broadcast address.
    pub(crate) fn answering_slave(
        &self,
        device: &DeviceInfo,
        command: &str,
    ) -> Result<u8, CliError> {
        let slave = self.slave.unwrap_or(device.default_slave);
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
    pub(crate) fn writing_slave(&self, device: &DeviceInfo) -> Result<u8, CliError> {
        let slave = self.slave.unwrap_or(device.default_slave);
        if slave == 0 && self.tcp.is_some() {
            return Err(CliError::new(
                "--slave 0 broadcasts on a serial line; Modbus TCP has no broadcast",
            )
            .hint("give the device's unit id, 1 to 247, with --slave"));
        }
        Ok(slave)
    }

    /// Connects to the device these options name (or the built-in simulator), at `slave`.
    pub(crate) async fn connect(
        &self,
        device: &'static DeviceInfo,
        slave: u8,
    ) -> Result<Core<Link>, CliError> {
        let link = link::open(device, slave, &self.target()).await?;
        Core::new(link, slave, device).map_err(CliError::from)
    }
}

/// Reads `registers` in the fewest requests and decodes them.
pub(crate) async fn read_values(
    core: &mut Core<Link>,
    registers: &[&'static RegisterInfo],
) -> Result<Vec<(&'static RegisterInfo, Value)>, CliError> {
    let readings = core.read_group(registers).await.map_err(|e| {
        let names: Vec<&str> = registers.iter().map(|r| r.name).collect();
        driver_error(e, Some(&names.join(", ")))
    })?;
    Ok(registers
        .iter()
        .map(|r| (*r, decode_value(r, readings.words(r))))
        .collect())
}
