//! Charts of recorded values as SVG or PNG (plotters): one panel per series, over a shared x
//! axis, with the units on the axes; a gap where a reading was invalid. PNG text is drawn with
//! DejaVu Sans, carried in the binary, so a chart looks the same on a machine without fonts.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

/// One plotted column: its label (with unit) and its points; `None` is a gap.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// The y axis label, with the unit (`distance [mm]`).
    pub label: String,
    /// The points, x then y; a `None` y is an invalid reading, drawn as a gap.
    pub points: Vec<(f64, Option<f64>)>,
}

/// Why a chart was not drawn.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ChartError {
    /// The output file's extension is neither `.svg` nor `.png`.
    NotSvgOrPng {
        /// The output file.
        path: PathBuf,
    },
    /// Drawing or writing the chart failed.
    Draw {
        /// The output file.
        path: PathBuf,
        /// What failed.
        reason: String,
    },
}

impl fmt::Display for ChartError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotSvgOrPng { path } => {
                write!(f, "{}: charts are written as SVG or PNG", path.display())
            }
            Self::Draw { path, reason } => write!(f, "cannot draw {}: {reason}", path.display()),
        }
    }
}

impl std::error::Error for ChartError {}

/// Height of one panel in pixels.
const PANEL_HEIGHT: u32 = 260;
/// Width of a chart in pixels: no line is drawn with more columns than this.
const WIDTH: u32 = 1000;

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

/// `points` thinned to what `columns` pixel columns between `low` and `high` can show: in
/// each column, its lowest and highest reading in the order they came (so a spike one sample
/// wide stays visible), then a gap if any reading in it was invalid. Fewer points than two
/// per column are kept as they are.
fn thin(
    points: &[(f64, Option<f64>)],
    (low, high): (f64, f64),
    columns: usize,
) -> Vec<(f64, Option<f64>)> {
    if points.len() <= 2 * columns || high <= low {
        return points.to_vec();
    }
    #[derive(Clone, Copy, Default)]
    struct Column {
        lowest: Option<(f64, f64)>,
        highest: Option<(f64, f64)>,
        gap: Option<f64>,
    }
    let mut kept = vec![Column::default(); columns];
    let last = columns - 1;
    for &(x, y) in points {
        let at = ((x - low) / (high - low) * columns as f64).clamp(0.0, last as f64) as usize;
        let column = &mut kept[at];
        match y {
            None => column.gap = Some(x),
            Some(y) => {
                if column.lowest.is_none_or(|(_, lowest)| y < lowest) {
                    column.lowest = Some((x, y));
                }
                if column.highest.is_none_or(|(_, highest)| y > highest) {
                    column.highest = Some((x, y));
                }
            }
        }
    }
    let mut thinned = Vec::with_capacity(3 * columns);
    for column in kept {
        if let (Some(lowest), Some(highest)) = (column.lowest, column.highest) {
            let (first, second) = if lowest.0 <= highest.0 {
                (lowest, highest)
            } else {
                (highest, lowest)
            };
            thinned.push((first.0, Some(first.1)));
            if second != first {
                thinned.push((second.0, Some(second.1)));
            }
        }
        if let Some(x) = column.gap {
            thinned.push((x, None));
        }
    }
    thinned
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
fn format_of(out: &Path) -> Result<Format, ChartError> {
    let extension = out.extension().and_then(|e| e.to_str()).unwrap_or("");
    match extension.to_ascii_lowercase().as_str() {
        "svg" => Ok(Format::Svg),
        "png" => Ok(Format::Png),
        _ => Err(ChartError::NotSvgOrPng {
            path: out.to_owned(),
        }),
    }
}

/// `out` names an SVG or PNG file: checked before anything is read or sent.
pub fn check_out(out: &Path) -> Result<(), ChartError> {
    format_of(out).map(|_| ())
}

/// Draws `series` over `x_label` into `out`, SVG or PNG by its extension.
pub fn draw(out: &Path, x_label: &str, series: &[Series]) -> Result<(), ChartError> {
    let count = u32::try_from(series.len()).unwrap_or(u32::MAX).max(1);
    let size = (WIDTH, PANEL_HEIGHT.saturating_mul(count));
    let failed = |reason: String| ChartError::Draw {
        path: out.to_owned(),
        reason,
    };
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
        let shown = thin(&one.points, (x_low, x_high), WIDTH as usize);
        for run in runs(&shown) {
            chart
                .draw_series(LineSeries::new(run, &BLUE))
                .map_err(failed)?;
        }
    }
    root.present().map_err(failed)
}

/// A text chart of `readings` for a terminal, one block per reading, from `▁` (the lowest
/// shown) to `█` (the highest); a space where a reading was no number; all `▄` when they are
/// equal.
pub fn sparkline(readings: &[Option<f64>]) -> String {
    const BLOCKS: [char; 8] = ['▁', '▂', '▃', '▄', '▅', '▆', '▇', '█'];
    let numbers = readings.iter().flatten();
    let low = numbers.clone().fold(f64::INFINITY, |a, &b| a.min(b));
    let high = numbers.fold(f64::NEG_INFINITY, |a, &b| a.max(b));
    readings
        .iter()
        .map(|reading| match reading {
            None => ' ',
            Some(_) if high <= low => BLOCKS[3],
            Some(v) => BLOCKS[(((v - low) / (high - low)) * 7.0).round() as usize],
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::{sparkline, thin};

    #[test]
    fn a_sparkline_spans_its_readings_lowest_to_highest_with_gaps() {
        let readings = [Some(1.0), Some(8.0), None, Some(4.5), Some(1.0)];
        assert_eq!(sparkline(&readings), "▁█ ▅▁");
        assert_eq!(sparkline(&[Some(2.0), Some(2.0)]), "▄▄");
        assert_eq!(sparkline(&[None, None]), "  ");
    }

    #[test]
    fn point_2_a_long_series_is_thinned_to_its_extremes_per_column() {
        // 10,000 flat readings with one spike, one dip and one invalid reading, on 10 columns.
        let mut points: Vec<(f64, Option<f64>)> =
            (0..10_000).map(|i| (i as f64, Some(1.0))).collect();
        points[4_321].1 = Some(99.5);
        points[4_322].1 = Some(-7.25);
        points[8_000].1 = None;
        let thinned = thin(&points, (0.0, 10_000.0), 10);
        assert!(thinned.len() <= 30, "{} points", thinned.len());
        // The column of the spike keeps both, in the order they came.
        let column: Vec<_> = thinned
            .iter()
            .filter(|(x, _)| (4_000.0..5_000.0).contains(x))
            .collect();
        assert_eq!(column, [&(4_321.0, Some(99.5)), &(4_322.0, Some(-7.25))]);
        // The invalid reading still breaks the line.
        assert!(thinned.contains(&(8_000.0, None)));
        // A short series is drawn as it is.
        assert_eq!(thin(&points[..20], (0.0, 20.0), 10), &points[..20]);
    }
}
