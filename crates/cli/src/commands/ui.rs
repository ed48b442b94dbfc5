//! `optobus ui`: the console in the browser, for the demo bus or for one device (`--model`,
//! `--spec`, `--serial`, `--tcp`) made into a one-device bus; prints the page's address.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use clap::Args;
use optobus_bus::{BusFile, DeviceConfig, LineConfig, Port};
use optobus_device::DeviceInfo;
use optobus_service::{HttpConfig, Options, OutputsConfig, Service, ServiceFile};

use crate::connect::{DeviceArgs, Global};
use crate::error::CliError;
use crate::inputs;
use crate::log::note;
use crate::models;

#[derive(Debug, Args)]
pub(crate) struct UiArgs {
    /// Where the console listens (bound beyond 127.0.0.1, it refuses every write: give a bus
    /// file with `token_file` to `optobus run` instead).
    #[arg(long, value_name = "ADDRESS", default_value = "127.0.0.1:8080")]
    http: SocketAddr,
    /// How often the device's measurements are polled.
    #[arg(long, default_value = "100ms", value_parser = inputs::EVERY.parser())]
    every: Duration,
    /// Stop after this long (default: until Ctrl-C).
    #[arg(long, value_parser = inputs::RUN_FOR.parser())]
    duration: Option<Duration>,
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
}

/// The one-device bus of `global`: its port (or a simulated line), model or spec, slave,
/// timeout, and a poll of its measurements (or its first group).
fn one_device(global: &Global, every: Duration) -> Result<BusFile, CliError> {
    let device: &'static DeviceInfo = global.device()?;
    global.check_line(device)?;
    let slave = global.answering_slave(device, "ui")?;
    let target = &global.target;
    let port = match (&target.serial, &target.tcp) {
        (Some(path), _) => Port::Serial(path.clone()),
        (None, Some(address)) => Port::tcp(address).map_err(CliError::new)?,
        (None, None) => Port::Simulated,
    };
    let line = LineConfig::new("line", port, target.line_format(device));
    let mut one = DeviceConfig::new(device.model_name().to_string(), device, 0, slave);
    one.timeout = target.timeout;
    if let Some(path) = &global.spec {
        let path = std::fs::canonicalize(path).unwrap_or_else(|_| path.clone());
        one.model = path.display().to_string();
    }
    let one = one.polling_measurements(every).map_err(CliError::new)?;
    Ok(BusFile::one_device(line, one))
}

pub(crate) async fn run(global: &Global, args: &UiArgs) -> Result<(), CliError> {
    let addressed = global.model.is_some()
        || global.spec.is_some()
        || global.target.addressed().is_some()
        || std::env::var_os(crate::connect::MODEL_VARIABLE).is_some();
    let bus = if addressed {
        one_device(global, args.every)?
    } else {
        let mut demo = optobus_service::demo::bus(models::catalogue())
            .map_err(|rejected| CliError::new(rejected.render()))?;
        // The console is the point here: no gateway to collide with another program's port.
        for line in &mut demo.lines {
            line.gateway = None;
        }
        demo
    };
    // The console alone: the bus's other outputs are `optobus run`'s.
    let mut outputs = OutputsConfig::default();
    outputs.http = Some(HttpConfig::new(args.http));
    let file = ServiceFile { bus, outputs };
    crate::log::show_operations();
    let service = Service::start(
        file,
        Options::default(),
        Arc::new(|text: &str| note!("{text}")),
    )
    .await
    .map_err(|e| CliError::failed(e.to_string()))?;
    crate::render::print(service.console_url().unwrap_or_default());
    inputs::until_stopped(args.duration).await;
    service
        .stop()
        .await
        .map_err(|e| CliError::failed(e.to_string()))
}
