//! The options every command takes, and what they mean for reaching the device: the slave
//! address, the line checks, a connection, and reading registers over it.

use clap::Args;
use optobus_device::{DeviceInfo, RegisterInfo};
use optobus_driver::identify::{identify, ConnectAs, Identification};
use optobus_driver::transport::Client;
use optobus_driver::{Core, PartialRead};
use optobus_inspect::{decode_values, Value};

use crate::error::{driver_error, CliError};
use crate::target::{self, Target};
use crate::{inputs, models};

/// Options every command takes: which model, and how to print.
#[derive(Debug, Args)]
pub(crate) struct Options {
    /// Sensor family (help from the models, at startup; see [`MODEL_VARIABLE`] for the
    /// default).
    #[arg(long, short, global = true)]
    pub(crate) model: Option<String>,
    /// A spec file to use as the model instead of a built-in one (checked like
    /// `optobus-codegen check`).
    #[arg(long, global = true, value_name = "SPEC.yaml")]
    pub(crate) spec: Option<std::path::PathBuf>,
    /// Print data as JSON.
    #[arg(long, global = true)]
    pub(crate) json: bool,
}

/// Options of the commands that talk to a device (or serve one): where it is, the line, the
/// slave address. Commands that only describe models or frames do not take them.
#[derive(Clone, Debug, Args)]
#[command(next_help_heading = "Device options")]
pub(crate) struct DeviceArgs {
    /// Where the device is and how to talk to it.
    #[command(flatten)]
    pub(crate) target: Target,
    /// Allow a --baud (or scan --bauds) rate the model's manual does not list.
    #[arg(long)]
    pub(crate) any_baud: bool,
    /// Slave address, 1 to 247 (default: the model's factory setting); 0 broadcasts a write
    /// (`set`, `do`), which no device answers.
    #[arg(long, value_parser = inputs::parse_slave, allow_hyphen_values = true)]
    pub(crate) slave: Option<u8>,
}

/// What a device command was given besides its own arguments: the common options and the
/// device options.
#[derive(Debug)]
pub(crate) struct Global {
    pub(crate) model: Option<String>,
    pub(crate) spec: Option<std::path::PathBuf>,
    pub(crate) json: bool,
    pub(crate) target: Target,
    pub(crate) any_baud: bool,
    pub(crate) slave: Option<u8>,
}

impl Options {
    /// The model `--spec` describes, or else the one a command names itself (`simulate ccs`),
    /// or else the one `--model` names. (A command's own model argument shares `--model`'s
    /// id, so it also carries `--model`'s value.)
    pub(crate) fn device_or(&self, named: Option<&str>) -> Result<&'static DeviceInfo, CliError> {
        model(self.spec.as_deref(), self.model.as_deref(), named, None)
    }

    /// These options with a device command's `device` options.
    pub(crate) fn with(&self, device: &DeviceArgs) -> Global {
        let DeviceArgs {
            target,
            any_baud,
            slave,
        } = device.clone();
        Global {
            model: self.model.clone(),
            spec: self.spec.clone(),
            json: self.json,
            target,
            any_baud,
            slave,
        }
    }
}

/// The environment variable holding the user's default model.
pub(crate) const MODEL_VARIABLE: &str = "OPTOBUS_MODEL";

/// The model `spec` describes, or else the one `named`, or else `model`, or else the one
/// [`MODEL_VARIABLE`] names, or else the first built-in one, unless `addressed` names a real
/// device (`--tcp …`, `--serial …`): a register map guessed for a real device reads wrong
/// values, so there the model must be given.
fn model(
    spec: Option<&std::path::Path>,
    model: Option<&str>,
    named: Option<&str>,
    addressed: Option<&str>,
) -> Result<&'static DeviceInfo, CliError> {
    if let Some(spec) = spec {
        return models::load(spec);
    }
    if let Some(name) = named.or(model) {
        return models::find(name);
    }
    if let Some(name) = std::env::var(MODEL_VARIABLE)
        .ok()
        .filter(|n| !n.trim().is_empty())
    {
        return models::find(&name).map_err(|e| e.prefixed(&format!("{MODEL_VARIABLE}: ")));
    }
    match addressed {
        None => models::all()
            .first()
            .copied()
            .ok_or_else(|| CliError::new("the tool has no built-in model")),
        Some(device) => Err(CliError::new(format!(
            "which model is at {device}? give --model ({}) or --spec FILE",
            models::names().join(", ")
        ))
        .hint(format!(
            "or set {MODEL_VARIABLE}; `optobus identify {device}` finds the model that answers"
        ))),
    }
}

/// Options of the commands that write (`set`, `do`): the copy of a per-channel register, the
/// confirmation a drastic write needs, and the device.
#[derive(Debug, Args)]
pub(crate) struct WriteArgs {
    /// Copy of a per-channel register or command (CCF channels 1 to 4).
    #[arg(long)]
    pub(crate) channel: Option<u8>,
    /// Confirm a write that stores, restarts or resets the device, or that writes a register
    /// such a command writes.
    #[arg(long)]
    pub(crate) yes: bool,
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
}

/// The registers a reading command names: registers, repeat members or groups.
#[derive(Debug, Args)]
pub(crate) struct Names {
    /// Register or group names (`optobus registers` lists them).
    #[arg(required = true)]
    names: Vec<String>,
    /// Copy of a per-channel register (CCF channels 1 to 4).
    #[arg(long)]
    channel: Option<u8>,
}

impl Global {
    /// The model `--spec` describes, or else the one `--model` names, or else the user's
    /// default; the built-in simulator's default only when no real device is addressed.
    pub(crate) fn device(&self) -> Result<&'static DeviceInfo, CliError> {
        model(
            self.spec.as_deref(),
            self.model.as_deref(),
            None,
            self.target.addressed().as_deref(),
        )
    }

    /// The model `--spec` describes, or else the one a command names itself, or else the one
    /// `--model` names, or else a default (for `simulate`, which serves rather than reaches a
    /// device).
    pub(crate) fn device_or(&self, named: Option<&str>) -> Result<&'static DeviceInfo, CliError> {
        model(self.spec.as_deref(), self.model.as_deref(), named, None)
    }

    /// Before a write to the built-in simulator (neither --serial nor --tcp given), says on
    /// stderr that its state lasts for this command only.
    pub(crate) fn note_if_simulated(&self, command: &str) {
        if self.target.addressed().is_none() {
            crate::log::note!(
                "optobus: the built-in simulator's state lasts for this `{command}` only; serve \
                 a lasting one with `optobus simulate` and point --tcp or --serial at it"
            );
        }
    }

    /// The serial line settings that can be checked without a port: `--baud` is one the
    /// model's manual lists (any rate a port can run at with `--any-baud`).
    pub(crate) fn check_line(&self, device: &DeviceInfo) -> Result<(), CliError> {
        match self.target.baud {
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
        if slave == 0 && self.target.tcp.is_some() {
            return Err(CliError::new(
                "--slave 0 broadcasts on a serial line; Modbus TCP has no broadcast",
            )
            .hint("give the device's unit id, 1 to 247, with --slave"));
        }
        Ok(slave)
    }

    /// The readable registers `names` stands for (checked before anything is opened) and a
    /// connection at the slave that answers `command`.
    pub(crate) async fn connect_to_read(
        &self,
        names: &Names,
        command: &str,
    ) -> Result<(Vec<&'static RegisterInfo>, Core<Client>), CliError> {
        let device = self.device()?;
        self.check_line(device)?;
        let registers = optobus_inspect::resolve_readable(device, &names.names, names.channel)?;
        let slave = self.answering_slave(device, command)?;
        Ok((registers, self.connect(device, slave).await?))
    }

    /// Connects to the device these options name (or the built-in simulator), at `slave`.
    pub(crate) async fn connect(
        &self,
        device: &'static DeviceInfo,
        slave: u8,
    ) -> Result<Core<Client>, CliError> {
        let link = target::open(device, slave, &self.target).await?;
        Core::new(link, slave, device).map_err(CliError::from)
    }
}

/// Links to the device a [`Target`] addresses, framed for each candidate model.
struct LinksAs<'a>(&'a Target);

impl ConnectAs for LinksAs<'_> {
    type Link = Client;
    type Error = CliError;

    async fn connect_as(&mut self, model: &'static DeviceInfo) -> Result<Client, CliError> {
        target::open(model, model.default_slave, self.0).await
    }
}

impl Global {
    /// The models `identify` and `scan` try: the `--spec` model, then every built-in one (all
    /// of them, so that no request reads where one of them changes the device by a read).
    pub(crate) fn candidates(&self) -> Result<Vec<&'static DeviceInfo>, CliError> {
        let mut candidates = Vec::new();
        if let Some(spec) = &self.spec {
            candidates.push(models::load(spec)?);
        }
        candidates.extend(models::all());
        Ok(candidates)
    }

    /// Which of the candidates the device `target` addresses is, asked at `slave` or each
    /// candidate's factory slave.
    pub(crate) async fn identify(
        &self,
        target: &Target,
        slave: Option<u8>,
    ) -> Result<Identification, CliError> {
        let candidates = self.candidates()?;
        identify(&mut LinksAs(target), &candidates, slave).await
    }
}

/// Reads `registers` in the fewest requests and decodes them; a failure names the registers
/// of the request that failed.
pub(crate) async fn read_values(
    core: &mut Core<Client>,
    registers: &[&'static RegisterInfo],
) -> Result<Vec<(&'static RegisterInfo, Value)>, CliError> {
    let readings = core
        .read_group_partly(registers)
        .await
        .map_err(|partial| failed_read(*partial, registers))?;
    Ok(decode_values(registers, &readings))
}

/// A read of `registers` that failed, as the tool says it: the driver's error and the
/// registers of the request that failed.
pub(crate) fn failed_read(partial: PartialRead, registers: &[&'static RegisterInfo]) -> CliError {
    let names: Vec<&str> = partial
        .failed_registers(registers)
        .iter()
        .map(|r| r.name)
        .collect();
    driver_error(partial.error, Some(&names.join(", ")))
}
