//! `optobus plot`: a file `optobus record` (or `optobus run --record`) wrote, drawn as SVG or
//! PNG: each value column over the elapsed seconds, with the units of its header, a gap at
//! each invalid reading (`NaN`) and none where a row did not read the column (an empty cell);
//! or a buffer download `optobus buffer --out` saved, over its index.

use std::path::PathBuf;

use clap::Args;
use optobus_chart::{check_out, draw, Series};
use optobus_service::recording::{self, ReadRefused};

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

/// Reads the recording: the x axis label and one series per value column with a number in it.
fn series(args: &PlotArgs) -> Result<(String, Vec<Series>), CliError> {
    let shown = args.file.display();
    let read = recording::read(&args.file).map_err(|refused| match refused {
        ReadRefused::TooLarge(error) => {
            CliError::new(format!("cannot read {shown}: {error}")).hint(format!(
                "plot draws recordings of up to {}; plot a part, e.g. `head -n 1000000 {shown} > part.csv`",
                recording::limit_text()
            ))
        }
        ReadRefused::Unreadable(error) => CliError::failed(format!("cannot read {shown}: {error}")),
        ReadRefused::Unparsable(error) => CliError::new(format!("cannot read {shown}: {error}")),
        ReadRefused::NotARecording => CliError::new(format!(
            "{shown} is no recording or buffer download: {refused}"
        ))
        .hint("record one with `optobus record`, or save a download with `optobus buffer --out`"),
        ReadRefused::NoNumbers => CliError::new(format!("{shown} holds no numbers to plot")),
    })?;
    if !read.left_out.is_empty() {
        note!(
            "optobus: left out, no numbers in them: {}",
            read.left_out.join(", ")
        );
    }
    let series = read
        .columns
        .into_iter()
        .map(|column| Series {
            label: column.label,
            points: column.points,
        })
        .collect();
    Ok((read.x_label, series))
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
