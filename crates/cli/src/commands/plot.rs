//! `optobus plot`: a file `optobus record` (or `optobus run --record`) wrote, drawn as SVG or
//! PNG: each value column over the elapsed seconds, with the units of its header, a gap at
//! each invalid reading (`NaN`) and none where a row did not read the column (an empty cell);
//! or a buffer download `optobus buffer --out` saved, over its index.

use std::path::PathBuf;

use clap::Args;
use optobus_spec::source::{open_limited, size_text, ReadError};

use crate::chart::{check_out, draw, Series};
use crate::error::CliError;
use crate::log::note;

#[derive(Debug, Args)]
pub(crate) struct PlotArgs {
    /// A CSV file of `optobus record` (time, `elapsed [s]`, a column per register or field;
    /// `NaN` an invalid reading, empty a cell not read), or of `optobus buffer --out` (index,
    /// value).
    file: PathBuf,
    /// The chart to write: `.svg` or `.png`.
    #[arg(long)]
    out: PathBuf,
}

/// The largest recording `plot` reads: 256 MiB, some three million rows of five values (hours
/// of `optobus record` at the fastest serial line). Its points take about two and a half times
/// the file in memory (some 700 MB at the limit, drawn in about five seconds); a larger file is
/// refused rather than left to exhaust the machine.
const RECORDING_LIMIT: u64 = 256 * 1024 * 1024;

/// Reads the recording: the x axis label and one series per value column with a number in it.
fn series(args: &PlotArgs) -> Result<(String, Vec<Series>), CliError> {
    let shown = args.file.display();
    let too_large = |error: String| {
        CliError::new(format!("cannot read {shown}: {error}")).hint(format!(
            "plot draws recordings of up to {}; plot a part, e.g. `head -n 1000000 {shown} > part.csv`",
            size_text(RECORDING_LIMIT)
        ))
    };
    // A file that cannot be read is the system's failure; one too large, or text that is no
    // CSV, input refused.
    let unreadable = |e: csv::Error| match e.kind() {
        csv::ErrorKind::Io(io) if io.kind() == std::io::ErrorKind::FileTooLarge => {
            too_large(io.to_string())
        }
        csv::ErrorKind::Io(_) => CliError::failed(format!("cannot read {shown}: {e}")),
        _ => CliError::new(format!("cannot read {shown}: {e}")),
    };
    let file = open_limited(&args.file, RECORDING_LIMIT).map_err(|e| match e {
        ReadError::TooLarge { .. } => too_large(e.to_string()),
        ReadError::Io(_) => CliError::failed(format!("cannot read {shown}: {e}")),
        _ => CliError::new(format!("cannot read {shown}: {e}")),
    })?;
    let mut reader = csv::Reader::from_reader(file);
    let headers = reader.headers().map_err(unreadable)?.clone();
    // A recording: time, elapsed seconds, values; a buffer download: index, value.
    let x_column =
        match (headers.get(0), headers.get(1)) {
            (_, Some(elapsed)) if elapsed.starts_with("elapsed") => 1,
            (Some("index"), Some(_)) => 0,
            _ => return Err(CliError::new(format!(
                "{shown} is no recording or buffer download: its columns are neither time, \
                 elapsed, values nor index, value"
            ))
            .hint(
                "record one with `optobus record`, or save a download with `optobus buffer --out`",
            )),
        };
    let x_label = headers.get(x_column).unwrap_or_default().to_owned();
    // A buffer download has a value in every row: an empty cell there is an invalid one.
    let download = x_column == 0;
    let mut series: Vec<Series> = headers
        .iter()
        .skip(x_column + 1)
        .map(|label| Series {
            label: label.to_owned(),
            points: Vec::new(),
        })
        .collect();
    for row in reader.records() {
        let row = row.map_err(unreadable)?;
        let Some(x) = row.get(x_column).and_then(|x| x.parse::<f64>().ok()) else {
            continue;
        };
        for (one, cell) in series.iter_mut().zip(row.iter().skip(x_column + 1)) {
            one.points.extend(point(x, cell, download));
        }
    }
    let (series, textual): (Vec<Series>, Vec<Series>) = series
        .into_iter()
        .partition(|one| one.points.iter().any(|(_, y)| y.is_some()));
    if series.is_empty() {
        return Err(CliError::new(format!("{shown} holds no numbers to plot")));
    }
    if !textual.is_empty() {
        let names: Vec<&str> = textual.iter().map(|one| one.label.as_str()).collect();
        note!(
            "optobus: left out, no numbers in them: {}",
            names.join(", ")
        );
    }
    Ok((x_label, series))
}

/// The point of one cell at `x`: a gap for `NaN` (an invalid reading) or other text; in a
/// recording none for an empty cell (the row did not read that column: the line goes on past
/// it), in a buffer `download` a gap.
fn point(x: f64, cell: &str, download: bool) -> Option<(f64, Option<f64>)> {
    if cell.is_empty() && !download {
        return None;
    }
    Some((x, cell.parse::<f64>().ok().filter(|y| y.is_finite())))
}

pub(crate) fn run(args: &PlotArgs) -> Result<(), CliError> {
    check_out(&args.out)?;
    let (x_label, series) = series(args)?;
    draw(&args.out, &x_label, &series)?;
    note!(
        "optobus: {} series drawn to {}",
        series.len(),
        args.out.display()
    );
    Ok(())
}
