//! Charts of recorded values as SVG or PNG (plotters): one panel per series, over a shared x
//! axis, with the units on the axes; a gap where a reading was invalid. PNG text is drawn with
//! DejaVu Sans, carried in the binary, so a chart looks the same on a machine without fonts.

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::error::CliError;

/// One plotted column: its label (with unit) and its points; `None` is a gap.
pub(crate) struct Series {
    pub(crate) label: String,
    pub(crate) points: Vec<(f64, Option<f64>)>,
}

/// Height of one panel in pixels.
const PANEL_HEIGHT: u32 = 260;

/// The lowest and highest of `values`, widened where they are equal so that a flat line
/// still has an axis.
fn bounds(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (low, high) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(low, high), v| {
        (low.min(v), high.max(v))
    });
    if !low.is_finite() || !high.is_finite() {
        return None;
    }
    let pad = if high > low { (high - low) * 0.05 } else { 1.0 };
    Some((low - pad, high + pad))
}

/// Decimals that tell apart the ticks of an axis from `low` to `high` (about ten ticks).
fn decimals(low: f64, high: f64) -> usize {
    let step = (high - low) / 10.0;
    let decimals = -step.log10().floor();
    if decimals.is_finite() {
        decimals.clamp(0.0, 12.0) as usize
    } else {
        0
    }
}

/// The runs of consecutive valid points: one line each, so that gaps show.
fn runs(points: &[(f64, Option<f64>)]) -> Vec<Vec<(f64, f64)>> {
    let mut runs = vec![Vec::new()];
    for (x, y) in points {
        match y {
            Some(y) => runs.last_mut().map_or((), |run| run.push((*x, *y))),
            None => runs.push(Vec::new()),
        }
    }
    runs.retain(|run| !run.is_empty());
    runs
}

/// The formats a chart is written in, by the output file's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Svg,
    Png,
}

/// `out`'s format: checked before anything is read or sent.
fn format_of(out: &Path) -> Result<Format, CliError> {
    let extension = out.extension().and_then(|e| e.to_str()).unwrap_or("");
    match extension.to_ascii_lowercase().as_str() {
        "svg" => Ok(Format::Svg),
        "png" => Ok(Format::Png),
        _ => Err(CliError::new(format!(
            "{}: charts are written as SVG or PNG",
            out.display()
        ))
        .hint("name the output file `….svg` or `….png`")),
    }
}

/// `out` names an SVG or PNG file: checked before anything is read or sent.
pub(crate) fn check_out(out: &Path) -> Result<(), CliError> {
    format_of(out).map(|_| ())
}

/// Draws `series` over `x_label` into `out`, SVG or PNG by its extension.
pub(crate) fn draw(out: &Path, x_label: &str, series: &[Series]) -> Result<(), CliError> {
    let count = u32::try_from(series.len()).unwrap_or(u32::MAX).max(1);
    let size = (1000, PANEL_HEIGHT.saturating_mul(count));
    let failed = |e: String| CliError::failed(format!("cannot draw {}: {e}", out.display()));
    match format_of(out)? {
        Format::Svg => panels(
            SVGBackend::new(out, size).into_drawing_area(),
            x_label,
            series,
        ),
        Format::Png => {
            use_bundled_font().map_err(failed)?;
            panels(
                BitMapBackend::new(out, size).into_drawing_area(),
                x_label,
                series,
            )
        }
    }
    .map_err(failed)
}

/// Registers DejaVu Sans as plotters' `sans-serif`, once.
fn use_bundled_font() -> Result<(), String> {
    static REGISTER: Once = Once::new();
    let mut result = Ok(());
    REGISTER.call_once(|| {
        result = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        )
        .map_err(|_| "the bundled font does not load".to_owned());
    });
    result
}

/// One panel per series on `root`, stacked, over a shared x axis.
fn panels<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    x_label: &str,
    series: &[Series],
) -> Result<(), String> {
    let failed = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(failed)?;
    let x_bounds = bounds(series.iter().flat_map(|s| s.points.iter().map(|(x, _)| *x)));
    let (x_low, x_high) = x_bounds.unwrap_or((0.0, 1.0));
    let x_decimals = decimals(x_low, x_high);
    for (panel, one) in root.split_evenly((series.len(), 1)).iter().zip(series) {
        let (y_low, y_high) =
            bounds(one.points.iter().filter_map(|(_, y)| *y)).unwrap_or((0.0, 1.0));
        let y_decimals = decimals(y_low, y_high);
        let mut chart = ChartBuilder::on(panel)
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(80)
            .build_cartesian_2d(x_low..x_high, y_low..y_high)
            .map_err(failed)?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(one.label.as_str())
            .x_label_formatter(&|x| format!("{x:.x_decimals$}"))
            .y_label_formatter(&|y| format!("{y:.y_decimals$}"))
            .draw()
            .map_err(failed)?;
        for run in runs(&one.points) {
            chart
                .draw_series(LineSeries::new(run, &BLUE))
                .map_err(failed)?;
        }
    }
    root.present().map_err(failed)
}
