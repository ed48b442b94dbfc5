//! `optobus buffer`: the P series' buffered download, with a progress bar, as CSV or JSON.

use std::path::PathBuf;
use std::time::Duration;

use clap::Args;
use optobus_p_series::{MeasurementSource, PSeries, DEVICE};

use crate::chart::{check_out, draw, Series};
use crate::connect::{DeviceArgs, Global};
use crate::error::{driver_error, CliError};
use crate::log::note;
use crate::render::{print, progress_bar};
use crate::{inputs, link, models};

#[derive(Debug, Args)]
pub(crate) struct BufferArgs {
    /// Values to buffer and download (at most 2500).
    #[arg(long)]
    count: u16,
    /// Measurement to buffer: distance_1, distance_2 or thickness.
    #[arg(long, default_value = "distance_1")]
    source: String,
    /// How long to let the sensor buffer before reading out (at most 24 h).
    #[arg(long, default_value = "1s", value_parser = inputs::WAIT.parser(), allow_hyphen_values = true)]
    wait: Duration,
    /// Write `index,value_mm` CSV here instead of stdout.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also draw the values over their index as SVG here.
    #[arg(long, value_name = "FILE.svg")]
    plot: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
}

/// Buffers `--count` values of `--source`, downloads them and writes CSV (or JSON).
pub(crate) async fn run(global: &Global, args: &BufferArgs) -> Result<(), CliError> {
    let device = global.device()?;
    // The download is the P-series driver's own procedure: only its model has it.
    if *device != DEVICE {
        return Err(CliError::new(format!(
            "`buffer` is the P series' buffered download; {} has no data buffer",
            device.family
        ))
        .hint(format!("use --model {}", models::name(&DEVICE))));
    }
    if let Some(path) = &args.plot {
        check_out(path)?;
    }
    let (count, wait) = (args.count, args.wait);
    let source = input(count, &args.source)?;
    let slave = global.answering_slave(device, "buffer")?;
    global.check_line(device)?;
    let link = link::open(device, slave, &global.target).await?;
    let mut sensor = PSeries::new(link, slave)?;
    sensor
        .start_buffering(source, count)
        .await
        .map_err(|e| driver_error(e, Some("buffer_report_count")))?;
    note!(
        "optobus: buffering {count} values of {source}; reading out in {} ms",
        wait.as_millis()
    );
    tokio::time::sleep(wait).await;
    let bar = progress_bar(u64::from(count), "[{bar:30}] {pos}/{len} values, {msg}");
    let values = sensor
        .download_buffer(|p| {
            bar.set_length(p.expected as u64);
            bar.set_position(p.received as u64);
            bar.set_message(format!("{} pages", p.pages));
        })
        .await
        .map_err(|e| driver_error(e, Some("buffer")))?;
    bar.finish();
    if let Some(path) = &args.plot {
        let points = values.iter().enumerate();
        let points = points.map(|(i, v)| (i as f64, v.as_ref().map(|v| v.to_f64())));
        let series = Series {
            label: format!("{} [mm]", args.source),
            points: points.collect(),
        };
        draw(path, "index", &[series])?;
    }
    if global.json && args.out.is_none() {
        let list: Vec<serde_json::Value> = values
            .iter()
            .map(|v| serde_json::json!(v.as_ref().map(|v| v.to_f64())))
            .collect();
        print(&serde_json::json!({"unit": "mm", "values": list}).to_string());
        return Ok(());
    }
    let mut csv = String::from("index,value_mm\n");
    for (index, value) in values.iter().enumerate() {
        let value = value.as_ref().map(|v| v.millimetres().to_string());
        csv.push_str(&format!("{index},{}\n", value.unwrap_or_default()));
    }
    match &args.out {
        Some(path) => {
            std::fs::write(path, csv)
                .map_err(|e| CliError::new(format!("cannot write {}: {e}", path.display())))?;
            note!(
                "optobus: {} values written to {}",
                values.len(),
                path.display()
            );
        }
        None => print(&csv),
    }
    Ok(())
}

/// The measurement `source` names, with `count` checked against the values the P series lets
/// be read out (appendix 3): both refused before anything is opened or sent.
fn input(count: u16, source: &str) -> Result<MeasurementSource, CliError> {
    let most = optobus_p_series::download::MAX_DOWNLOAD;
    if !(1..=most).contains(&count) {
        return Err(CliError::new(format!(
            "--count {count}: the P series buffers 1 to {most} values for reading out"
        )));
    }
    let register = DEVICE
        .register("buffer_data_type")
        .ok_or_else(|| CliError::new("the P-series spec has no buffer_data_type"))?;
    let words = optobus_inspect::parse_value(register, source)?;
    Ok(MeasurementSource::from_raw(u32::from(
        words.first().copied().unwrap_or(0),
    )))
}
