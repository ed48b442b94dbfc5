//! `optobus buffer`: the buffered download of any model whose spec has a data buffer, with a
//! progress bar, as CSV or JSON.

use std::path::PathBuf;
use std::time::Duration;

use clap::Args;
use optobus_chart::{check_out, draw, Series};
use optobus_device::{DeviceInfo, RegisterInfo};
use optobus_driver::{BufferRefusal, BufferRequest, Core, Encode, Fixed};
use optobus_service::recording::{buffer_csv, buffer_points, header};

use crate::connect::{DeviceArgs, Global};
use crate::error::{driver_error, CliError};
use crate::log::note;
use crate::log::progress_bar;
use crate::render::{counted, print};
use crate::{inputs, models, target};

#[derive(Debug, Args)]
pub(crate) struct BufferArgs {
    /// Values to buffer and download (at most what the model's buffer hands out).
    #[arg(long)]
    count: u32,
    /// What to buffer: a code of the buffer's source register (default: its first code).
    #[arg(long)]
    source: Option<String>,
    /// How long to let the sensor buffer before reading out (at most 24 h).
    #[arg(long, default_value = "1s", value_parser = inputs::WAIT.parser(), allow_hyphen_values = true)]
    wait: Duration,
    /// Write `index,value_<unit>` CSV here instead of stdout.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also draw the values over time here (one every sampling interval × ratio, read from
    /// the device), as SVG or PNG (by the extension).
    #[arg(long, value_name = "FILE")]
    plot: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
}

/// Buffers `--count` values of `--source`, downloads them and writes CSV (or JSON).
pub(crate) async fn run(global: &Global, args: &BufferArgs) -> Result<(), CliError> {
    let device = global.device()?;
    if device.buffer.is_none() {
        return Err(refused(device, args.count, BufferRefusal::NoBuffer));
    }
    if let Some(path) = &args.plot {
        check_out(path)?;
    }
    let (count, wait) = (args.count, args.wait);
    let parse = |register: &'static RegisterInfo, text: &str| {
        Ok::<_, CliError>(register.raw(&optobus_inspect::parse_value(register, text)?))
    };
    let request = BufferRequest::check(device, count, args.source.as_deref(), parse)
        .map_err(|refusal| refused(device, count, refusal))?;
    let (buffer, values_register, source) = (request.buffer, request.values, request.source);
    let slave = global.answering_slave(device, "buffer")?;
    global.check_line(device)?;
    let link = target::open(device, slave, &global.target).await?;
    let mut core = Core::new(link, slave, device).map_err(|e| driver_error(e, None))?;
    let code = source.as_ref().map(|s| s.code);
    core.start_buffering(code.as_ref().map(|c| c as &dyn Encode), count)
        .await
        .map_err(|e| driver_error(e, Some(buffer.count)))?;
    let what = source.as_ref().map_or("", |s| s.name.as_str());
    note!(
        "optobus: buffering {} of {what}; reading out in {} ms",
        counted(count, "value"),
        wait.as_millis()
    );
    tokio::time::sleep(wait).await;
    // Read before the download: the interval and ratio the values were buffered at.
    let timing = match &args.plot {
        Some(_) => core
            .read_buffer_timing()
            .await
            .map_err(|e| driver_error(e, buffer.interval))?,
        None => None,
    };
    if let Some(timing) = timing {
        note!(
            "optobus: values {:?} apart (sampling interval {:?} × ratio {})",
            timing.period(),
            timing.interval,
            timing.ratio
        );
    }
    let bar = progress_bar(u64::from(count), "[{bar:30}] {pos}/{len} values, {msg}");
    let values: Vec<Option<Fixed>> = core
        .download_buffer(|p| {
            bar.set_length(p.expected as u64);
            bar.set_position(p.received as u64);
            bar.set_message(counted(p.pages, "page"));
        })
        .await
        .map_err(|e| driver_error(e, Some("buffer")))?;
    bar.finish();
    let unit = values_register.unit.unwrap_or("");
    if let Some(path) = &args.plot {
        let (x_label, points) = buffer_points(timing, &values);
        let label = header(what, Some(unit).filter(|unit| !unit.is_empty()));
        draw(path, &x_label, &[Series { label, points }])?;
    }
    if global.json && args.out.is_none() {
        // Exact text, as every quantity in the tool's JSON; null where invalid.
        print(&serde_json::json!({"unit": unit, "values": values}).to_string());
        return Ok(());
    }
    let csv = buffer_csv(unit, &values);
    match &args.out {
        Some(path) => {
            std::fs::write(path, csv)
                .map_err(|e| CliError::new(format!("cannot write {}: {e}", path.display())))?;
            note!(
                "optobus: {} written to {}",
                counted(values.len(), "value"),
                path.display()
            );
        }
        None => print(&csv),
    }
    Ok(())
}

/// A buffered read-out refused before anything was opened or sent, said with its option.
fn refused(device: &DeviceInfo, count: u32, refusal: BufferRefusal<CliError>) -> CliError {
    match refusal {
        BufferRefusal::NoBuffer => {
            let with: Vec<String> = models::all()
                .iter()
                .filter(|d| d.buffer.is_some())
                .map(|d| models::name(d))
                .collect();
            CliError::new(format!(
                "`buffer` downloads a model's data buffer; {} has no data buffer",
                models::name(device)
            ))
            .hint(format!("use --model {}", with.join(" or --model ")))
        }
        BufferRefusal::Count { .. } => CliError::new(format!("--count {count}: {refusal}")),
        BufferRefusal::OneKindOnly { .. } => CliError::new(format!("--source: {refusal}")),
        BufferRefusal::Source(error) => error,
        BufferRefusal::NotInSpec(_) | BufferRefusal::NoCodes(_) => {
            CliError::new(refusal.to_string())
        }
    }
}
