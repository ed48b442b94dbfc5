//! `optobus scan`: which baud rate and slave address a device answers on, and which model
//! answers there (as `identify` finds it); the first one found ends the scan unless `--all`.
//! The scan itself is the driver's (`optobus_driver::scan`); this parses, shows and prints.

use std::time::Duration;

use clap::Args;
use optobus_device::DeviceInfo;
use optobus_driver::identify::Verdict;
use optobus_driver::scan::{parse_slaves, scan, ConnectAt, ScanStep, DEVICE_ADDRESSES};
use optobus_driver::transport::Client;

use crate::connect::{DeviceArgs, Global};
use crate::error::CliError;
use crate::log::note;
use crate::log::progress_bar;
use crate::render::print;
use crate::target::{self, Target};
use crate::{inputs, models};

#[derive(Debug, Args)]
pub(crate) struct ScanArgs {
    /// Baud rates to try, e.g. 9600,115200 (default: --baud, or the model's).
    #[arg(long)]
    bauds: Option<String>,
    /// Slave addresses to try, e.g. 1-10,247 (default: the model's range).
    #[arg(long)]
    slaves: Option<String>,
    /// Go on after the first device that answers, and list every one.
    #[arg(long)]
    all: bool,
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
}

pub(crate) async fn run(global: &Global, args: &ScanArgs) -> Result<(), CliError> {
    let device = global.device()?;
    global.answering_slave(device, "scan")?;
    let bauds: Vec<u32> = match (&args.bauds, global.target.baud) {
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
    let slaves = match &args.slaves {
        Some(text) => parse_slaves(text, "--slaves")?,
        None => {
            let (first, last) = DEVICE_ADDRESSES;
            (device.slaves.0.max(first)..=device.slaves.1.min(last)).collect()
        }
    };
    let Some(path) = &global.target.serial else {
        return Err(CliError::new("scan needs a serial port").hint("give --serial PORT"));
    };
    if !device.registers.iter().any(|r| r.readable()) {
        return Err(CliError::new("the model has no readable register"));
    }
    let candidates = global.candidates()?;
    let mut target = global.target.clone();
    // A silent address costs the whole timeout: keep it short unless asked otherwise.
    target.timeout = global.target.timeout.min(Duration::from_millis(200));
    let progress = progress_bar(
        (bauds.len() * slaves.len()) as u64,
        "scanning {msg} ({pos}/{len})",
    );
    let show = |step: ScanStep<'_>| match step {
        ScanStep::Probing { baud, slave } => {
            progress.set_message(format!("{baud} baud: slave {slave}"));
            progress.inc(1);
        }
        ScanStep::Found(found) => {
            let line = format!(
                "found: slave {} at {} baud: {}",
                found.slave,
                found.baud,
                found.identification.verdict()
            );
            // With --json, stdout carries the JSON only.
            progress.suspend(|| {
                if global.json {
                    note!("optobus: {line}");
                    // Written before the bar is drawn again (notes have a thread of their
                    // own).
                    crate::log::flush(std::time::Duration::from_secs(1));
                } else {
                    print(&line);
                }
            });
        }
    };
    let found = scan(
        &mut LinksAt(&target),
        device,
        &bauds,
        &slaves,
        &candidates,
        args.all,
        show,
    )
    .await?;
    progress.finish_and_clear();
    if global.json {
        let list: Vec<serde_json::Value> = found
            .iter()
            .map(|found| {
                let model = match found.identification.verdict() {
                    Verdict::One(model) => Some(models::name(model)),
                    _ => None,
                };
                serde_json::json!({"baud": found.baud, "slave": found.slave, "model": model})
            })
            .collect();
        print(&serde_json::Value::Array(list).to_string());
    }
    if found.is_empty() {
        return Err(CliError::failed(format!("no device answered on {path}"))
            .hint("check wiring and parity, or widen --bauds and --slaves"));
    }
    Ok(())
}

/// Links to the line a [`Target`] addresses, at a baud rate, framed for each model.
struct LinksAt<'a>(&'a Target);

impl ConnectAt for LinksAt<'_> {
    type Link = Client;
    type Error = CliError;

    async fn connect_at(
        &mut self,
        model: &'static DeviceInfo,
        baud: u32,
    ) -> Result<Client, CliError> {
        let mut target = self.0.clone();
        target.baud = Some(baud);
        target::open(model, model.default_slave, &target).await
    }
}
