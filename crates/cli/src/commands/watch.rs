//! `optobus watch`: registers or groups read again and again, redrawn in place; with
//! `--chart`, each number's recent history as a sparkline beside it.

use std::collections::VecDeque;
use std::io::{IsTerminal, Write};
use std::time::Duration;

use clap::Args;
use crossterm::terminal;
use optobus_chart::sparkline;
use serde_json::json;

use crate::connect::{failed_read, DeviceArgs, Global, Names};
use crate::error::CliError;
use crate::log::note;
use crate::render::{redraw, screen, time_of_day, timestamp, values_json, values_text};
use crate::{inputs, models};
use optobus_device::RegisterInfo;
use optobus_driver::ErrorKind;
use optobus_inspect::{decode_values, Value};

#[derive(Debug, Args)]
pub(crate) struct WatchArgs {
    #[command(flatten)]
    names: Names,
    /// Time between refreshes (1 ms to 24 h).
    #[arg(long, default_value = "200ms", value_parser = inputs::INTERVAL.parser(), allow_hyphen_values = true)]
    interval: Duration,
    /// Stop after this many refreshes (default: until Ctrl-C).
    #[arg(long)]
    count: Option<u64>,
    /// Beside each number, a sparkline of its last 40 readings (gaps where invalid).
    #[arg(long)]
    chart: bool,
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
}

/// Redraws the values every `--interval` until Ctrl-C (or `--count` refreshes).
pub(crate) async fn run(global: &Global, args: &WatchArgs) -> Result<(), CliError> {
    if args.chart && global.json {
        return Err(
            CliError::new("--chart draws for people; --json prints data")
                .hint("plot JSON data with your own tools, or a recording with `optobus plot`"),
        );
    }
    let (registers, mut core) = global.connect_to_read(&args.names, "watch").await?;
    let device = core.device();
    let terminal = std::io::stdout().is_terminal() && !global.json;
    let mut drawn_lines = 0u16;
    let mut last: Option<String> = None;
    let mut refresh = 0u64;
    let mut history = vec![VecDeque::new(); registers.len()];
    // The kind of failure last reported on stderr and the reads failed since, while the
    // device keeps failing.
    let mut failing: Option<(ErrorKind, u64)> = None;
    let ctrl_c = tokio::signal::ctrl_c();
    tokio::pin!(ctrl_c);
    loop {
        let started = tokio::time::Instant::now();
        let outcome = tokio::select! {
            outcome = core.read_group_partly(&registers) => outcome,
            _ = &mut ctrl_c => break,
        };
        refresh += 1;
        // Piped: a failure on stderr once, again when its kind changes, and the recovery.
        let piped = !terminal && !global.json;
        let outcome = match outcome {
            Ok(readings) => {
                if let Some((_, failed)) = failing.take().filter(|_| piped) {
                    note!("{}  recovered after {failed} failed reads", time_of_day());
                }
                Ok(decode_values(&registers, &readings))
            }
            Err(partial) => {
                let kind = partial.error.kind();
                let error = failed_read(*partial, &registers);
                let (known, failed) = failing.map_or((None, 0), |(k, n)| (Some(k), n));
                if piped && known != Some(kind) {
                    note!("{}  ! {error} — retrying", time_of_day());
                }
                failing = Some((kind, failed + 1));
                Err(error)
            }
        };
        let block = match &outcome {
            Ok(values) if global.json => {
                json!({"time": timestamp(), "values": values_json(values)}).to_string() + "\n"
            }
            Ok(values) => {
                let text = if args.chart {
                    chart_text(values, &mut history)
                } else {
                    values_text(values)
                };
                last = Some(text.clone());
                format!(
                    "{}  {} · slave {} · every {} ms\n{text}",
                    time_of_day(),
                    models::name(device),
                    core.slave(),
                    args.interval.as_millis()
                )
            }
            Err(error) if global.json => {
                json!({"time": timestamp(), "error": error.to_string()}).to_string() + "\n"
            }
            // Piped: the failure went to stderr above; stdout keeps the values.
            Err(_) if !terminal => String::new(),
            // Keep the last values on screen, marked, and try again.
            Err(error) => format!(
                "{}  ! {error} — retrying\n{}",
                time_of_day(),
                last.as_deref().unwrap_or("")
            ),
        };
        let mut out = std::io::stdout().lock();
        if terminal {
            drawn_lines = redraw(&mut out, drawn_lines, &block, screen(terminal::size().ok()));
        } else {
            let _ = out.write_all(block.as_bytes());
        }
        let _ = out.flush();
        if args.count.is_some_and(|n| refresh >= n) {
            break;
        }
        tokio::select! {
            () = tokio::time::sleep_until(core.transport_mut().next_read(started, args.interval)) => {}
            _ = &mut ctrl_c => break,
        }
    }
    Ok(())
}

/// Readings a sparkline shows.
const CHART_WIDTH: usize = 40;

/// `name  value  ▃▄▅▆▇` lines: `values` added to `history`, each number's recent readings
/// drawn between their lowest and highest beside the aligned lines of [`values_text`].
fn chart_text(
    values: &[(&'static RegisterInfo, Value)],
    history: &mut [VecDeque<Option<f64>>],
) -> String {
    let text = values_text(values);
    let width = text.lines().map(|l| l.chars().count()).max().unwrap_or(0);
    let mut chart = String::new();
    for ((line, (_, value)), past) in text.lines().zip(values).zip(history) {
        if past.len() == CHART_WIDTH {
            past.pop_front();
        }
        past.push_back(value.number());
        let line = format!("{line:<width$}  {}", sparkline(past.make_contiguous()));
        chart.push_str(line.trim_end());
        chart.push('\n');
    }
    chart
}

#[cfg(test)]
mod tests {
    use crate::render::{redraw, screen};

    #[test]
    fn point_10_a_terminal_reporting_0x0_draws_at_a_sane_size() {
        assert_eq!(screen(Some((0, 0))), (80, 24));
        assert_eq!(screen(Some((120, 0))), (80, 24));
        assert_eq!(screen(None), (80, 24));
        assert_eq!(screen(Some((100, 30))), (100, 30));
        let block = "13:05:01.250  p-series · slave 1\ndistance_1  3.584190 mm\n";
        let mut out = Vec::new();
        assert_eq!(redraw(&mut out, 0, block, screen(Some((0, 0)))), 2);
        let clear = "\u{1b}[2K";
        assert_eq!(
            String::from_utf8_lossy(&out),
            format!("{clear}13:05:01.250  p-series · slave 1\n{clear}distance_1  3.584190 mm\n")
        );
    }

    #[test]
    fn a_block_taller_than_the_terminal_is_cut_and_climbed_back_over() {
        let block: String = (1..=10).map(|i| format!("line {i}\n")).collect();
        let mut out = Vec::new();
        let drawn = redraw(&mut out, 0, &block, (80, 4));
        assert_eq!(drawn, 3);
        let clear = "\u{1b}[2K";
        assert_eq!(
            String::from_utf8_lossy(&out),
            format!("{clear}line 1\n{clear}line 2\n{clear}line 3\n")
        );
        let mut out = Vec::new();
        assert_eq!(redraw(&mut out, drawn, "a\nb\n", (80, 4)), 2);
        // Up three lines, each new line cleared as it is written, then the leftover line.
        assert_eq!(
            String::from_utf8_lossy(&out),
            format!("\u{1b}[3F{clear}a\n{clear}b\n\u{1b}[J")
        );
        // A line wider than the terminal is cut, never wrapped.
        let mut out = Vec::new();
        redraw(&mut out, 0, "abcdef\n", (4, 4));
        assert_eq!(String::from_utf8_lossy(&out), format!("{clear}abc\n"));
    }
}
