//! Charts of recorded values as SVG (plotters): one panel per series, over a shared x axis,
//! with the units on the axes; a gap where a reading was invalid.

use std::path::Path;

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

/// `out` names an SVG file: checked before anything is read or sent.
pub(crate) fn check_out(out: &Path) -> Result<(), CliError> {
    if out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"))
    {
        return Ok(());
    }
    Err(
        CliError::new(format!("{}: charts are written as SVG", out.display()))
            .hint("name the output file `….svg`"),
    )
}

/// Draws `series` over `x_label` into the SVG file `out`.
pub(crate) fn draw(out: &Path, x_label: &str, series: &[Series]) -> Result<(), CliError> {
    check_out(out)?;
    let failed =
        |e: &dyn std::fmt::Display| CliError::failed(format!("cannot draw {}: {e}", out.display()));
    let count = u32::try_from(series.len()).unwrap_or(u32::MAX).max(1);
    let root = SVGBackend::new(out, (1000, PANEL_HEIGHT.saturating_mul(count))).into_drawing_area();
    root.fill(&WHITE).map_err(|e| failed(&e))?;
    let x_bounds = bounds(series.iter().flat_map(|s| s.points.iter().map(|(x, _)| *x)));
    let (x_low, x_high) = x_bounds.unwrap_or((0.0, 1.0));
    for (panel, one) in root.split_evenly((series.len(), 1)).iter().zip(series) {
        let (y_low, y_high) =
            bounds(one.points.iter().filter_map(|(_, y)| *y)).unwrap_or((0.0, 1.0));
        let mut chart = ChartBuilder::on(panel)
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(80)
            .build_cartesian_2d(x_low..x_high, y_low..y_high)
            .map_err(|e| failed(&e))?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(one.label.as_str())
            .draw()
            .map_err(|e| failed(&e))?;
        for run in runs(&one.points) {
            chart
                .draw_series(LineSeries::new(run, &BLUE))
                .map_err(|e| failed(&e))?;
        }
    }
    root.present().map_err(|e| failed(&e))
}
