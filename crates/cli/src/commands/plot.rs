//! `optobus plot`: a file `optobus record` wrote, drawn as SVG or PNG: each value column over the
//! elapsed seconds, with the units of its header.

use std::path::PathBuf;

use clap::Args;

use crate::chart::{check_out, draw, Series};
use crate::error::CliError;
use crate::log::note;

#[derive(Debug, Args)]
pub(crate) struct PlotArgs {
    /// A CSV file of `optobus record` (time, `elapsed [s]`, one column per register).
    file: PathBuf,
    /// The chart to write: `.svg` or `.png`.
    #[arg(long)]
    out: PathBuf,
}

/// Reads the recording: the x axis label and one series per value column with a number in it.
fn series(args: &PlotArgs) -> Result<(String, Vec<Series>), CliError> {
    let shown = args.file.display();
    // A file that cannot be read is the system's failure; text that is no CSV, input refused.
    let unreadable = |e: csv::Error| {
        let message = format!("cannot read {shown}: {e}");
        match e.kind() {
            csv::ErrorKind::Io(_) => CliError::failed(message),
            _ => CliError::new(message),
        }
    };
    let mut reader = csv::Reader::from_path(&args.file).map_err(unreadable)?;
    let headers = reader.headers().map_err(unreadable)?.clone();
    let Some(x_label) = headers.get(1).filter(|h| h.starts_with("elapsed")) else {
        return Err(CliError::new(format!(
            "{shown} is no recording: its second column is not the elapsed time"
        ))
        .hint("record one with `optobus record`"));
    };
    let mut series: Vec<Series> = headers
        .iter()
        .skip(2)
        .map(|label| Series {
            label: label.to_owned(),
            points: Vec::new(),
        })
        .collect();
    for row in reader.records() {
        let row = row.map_err(unreadable)?;
        let Some(x) = row.get(1).and_then(|x| x.parse::<f64>().ok()) else {
            continue;
        };
        for (one, cell) in series.iter_mut().zip(row.iter().skip(2)) {
            one.points.push((x, cell.parse::<f64>().ok()));
        }
    }
    series.retain(|one| one.points.iter().any(|(_, y)| y.is_some()));
    if series.is_empty() {
        return Err(CliError::new(format!("{shown} holds no numbers to plot")));
    }
    Ok((x_label.to_owned(), series))
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
