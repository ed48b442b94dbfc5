//! `optobus ui`: the console in the browser, for the demo bus or for one device (`--model`,
//! `--spec`, `--serial`, `--tcp`) made into a one-device bus; prints the page's address.

use std::net::SocketAddr;
use std::time::Duration;

use clap::Args;
use optobus_bus::{Bus, BusFile, HttpConfig};
use optobus_device::DeviceInfo;

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

/// A YAML string (JSON's quoting is YAML's).
fn quoted(text: &str) -> String {
    serde_json::Value::from(text).to_string()
}

/// The one-device bus of `global`: its port (or a simulated line), model or spec, slave,
/// timeout, and a poll of its measurements (or its first group).
fn one_device(global: &Global, every: Duration) -> Result<BusFile, CliError> {
    let device: &'static DeviceInfo = global.device()?;
    global.check_line(device)?;
    let slave = global.answering_slave(device, "ui")?;
    let target = &global.target;
    let format = target.line_format(device);
    let port = match (&target.serial, &target.tcp) {
        (Some(path), _) => format!("serial: {}", quoted(path)),
        (None, Some(address)) => format!("tcp: {}", quoted(address)),
        (None, None) => "simulated: true".to_owned(),
    };
    let parity = format!("{:?}", format.parity).to_lowercase();
    let model = match &global.spec {
        Some(path) => {
            let path = std::fs::canonicalize(path).unwrap_or_else(|_| path.clone());
            format!("spec: {}", quoted(&path.display().to_string()))
        }
        None => format!("model: {}", quoted(&device.model_name().to_string())),
    };
    let group = device
        .groups
        .iter()
        .find(|g| g.name == "measurements")
        .or(device.groups.first());
    let poll = match group {
        Some(group) => format!(
            "[{{ read: {}, every: {}ms }}]",
            group.name,
            every.as_millis()
        ),
        None => "[]".to_owned(),
    };
    let line_format = if target.tcp.is_some() {
        String::new()
    } else {
        format!(
            ", baud: {}, parity: {parity}, data_bits: {}, stop_bits: {}, any_format: {}",
            format.baud, format.data_bits, format.stop_bits, global.any_baud
        )
    };
    let text = format!(
        "lines: [{{ name: line, {port}{line_format} }}]\n\
         devices: [{{ name: {name}, {model}, slave: {slave}, timeout: {timeout}ms, poll: {poll} }}]\n",
        name = quoted(&device.model_name().to_string()),
        timeout = target.timeout.as_millis(),
    );
    BusFile::parse("the device given", &text, ".".as_ref(), models::catalogue())
        .map_err(|rejected| CliError::new(rejected.render()))
}

pub(crate) async fn run(global: &Global, args: &UiArgs) -> Result<(), CliError> {
    let addressed = global.model.is_some()
        || global.spec.is_some()
        || global.target.addressed().is_some()
        || std::env::var_os(crate::connect::MODEL_VARIABLE).is_some();
    let file = if addressed {
        one_device(global, args.every)?
    } else {
        let mut demo = super::run::demo(None)?;
        // The console is the point here: no gateway to collide with another program's port.
        for line in &mut demo.lines {
            line.gateway = None;
        }
        demo
    };
    crate::log::show_operations();
    let bus = Bus::new(file);
    let running = bus.start().map_err(|e| CliError::failed(e.to_string()))?;
    let server = optobus_console::serve(&running, &HttpConfig::new(args.http))
        .await
        .map_err(|e| CliError::failed(e.to_string()))?;
    note!("optobus: the console is on {}", server.url());
    crate::render::print(&server.url());
    let stop = async {
        match args.duration {
            Some(duration) => tokio::time::sleep(duration).await,
            None => std::future::pending().await,
        }
    };
    tokio::select! {
        _ = tokio::signal::ctrl_c() => {}
        () = stop => {}
    }
    drop(server);
    drop(running);
    Ok(())
}
