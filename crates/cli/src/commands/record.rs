//! `optobus record`: registers or groups sampled into a CSV file, as fast as the line allows
//! or every `--interval`, for `--duration` or `--count` samples; Ctrl-C ends it cleanly.

use std::path::PathBuf;
use std::time::{Duration, SystemTime};

use clap::Args;
use optobus_driver::transport::timing::deadline_from;
use optobus_service::recording::{csv_cells, csv_headers, RecordingFile};
use tokio::time::Instant;

use crate::connect::{read_values, DeviceArgs, Global, Names};
use crate::error::CliError;
use crate::inputs;
use crate::log::note;
use crate::log::progress_bar;

#[derive(Debug, Args)]
#[command(group = clap::ArgGroup::new("until").args(["duration", "count"]).required(true))]
pub(crate) struct RecordArgs {
    #[command(flatten)]
    names: Names,
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
    /// Record for this long (at most 24 h).
    #[arg(long, value_parser = inputs::RUN_FOR.parser(), conflicts_with = "count")]
    duration: Option<Duration>,
    /// Record this many samples.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    count: Option<u64>,
    /// Time from one sample's start to the next (default: as fast as the line allows).
    #[arg(long, value_parser = inputs::INTERVAL.parser())]
    interval: Option<Duration>,
    /// The CSV file to write: one row per sample.
    #[arg(long)]
    out: PathBuf,
}

/// Samples until `--duration` has passed, `--count` samples are written, or Ctrl-C; a failed
/// read leaves its row's cells empty (nothing read) and is counted.
pub(crate) async fn run(global: &Global, args: &RecordArgs) -> Result<(), CliError> {
    let (registers, mut core) = global.connect_to_read(&args.names, "record").await?;
    let columns: Vec<String> = registers.iter().flat_map(|r| csv_headers(r)).collect();
    let write_failed = |e: optobus_service::ServiceError| CliError::failed(e.to_string());
    let mut csv = RecordingFile::create(&args.out, &columns).map_err(write_failed)?;
    let length = match (args.count, args.duration) {
        (Some(count), _) => count,
        (None, Some(duration)) => u64::try_from(duration.as_millis()).unwrap_or(u64::MAX),
        (None, None) => 0,
    };
    let progress = progress_bar(length, "recording [{bar:30}] {msg}");
    let started = Instant::now();
    let deadline = args.duration.map(|d| deadline_from(started, d));
    let ctrl_c = tokio::signal::ctrl_c();
    tokio::pin!(ctrl_c);
    let (mut samples, mut failed) = (0u64, 0u64);
    loop {
        let sample_started = Instant::now();
        if deadline.is_some_and(|d| sample_started >= d) {
            break;
        }
        let outcome = tokio::select! {
            outcome = read_values(&mut core, &registers) => outcome,
            _ = &mut ctrl_c => break,
        };
        let time = SystemTime::now();
        let elapsed = sample_started.duration_since(started).as_secs_f64();
        let cells: Vec<String> = match &outcome {
            Ok(values) => values
                .iter()
                .flat_map(|(register, value)| csv_cells(register, value))
                .collect(),
            Err(_) => vec![String::new(); columns.len()],
        };
        failed += u64::from(outcome.is_err());
        csv.row(time, elapsed, &cells).map_err(write_failed)?;
        samples += 1;
        match args.count {
            Some(_) => progress.set_position(samples),
            None => progress
                .set_position(u64::try_from(started.elapsed().as_millis()).unwrap_or(u64::MAX)),
        }
        progress.set_message(format!("{samples} samples, {failed} failed"));
        if args.count.is_some_and(|count| samples >= count) {
            break;
        }
        if let Some(interval) = args.interval {
            tokio::select! {
                () = tokio::time::sleep_until(core.transport_mut().next_read(sample_started, interval)) => {}
                _ = &mut ctrl_c => break,
            }
        }
    }
    progress.finish_and_clear();
    csv.flush().map_err(write_failed)?;
    note!(
        "optobus: {samples} samples ({failed} failed) in {:.1} s written to {}",
        started.elapsed().as_secs_f64(),
        args.out.display()
    );
    Ok(())
}
