//! `optobus watch`: registers or groups read again and again, redrawn in place.

use std::io::{IsTerminal, Write};
use std::time::Duration;

use clap::Args;
use serde_json::json;

use crate::connect::{read_values, Global, Names};
use crate::error::CliError;
use crate::inputs;
use crate::render::{time_of_day, timestamp, values_json, values_text};

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
}

/// Redraws the values every `--interval` until Ctrl-C (or `--count` refreshes).
pub(crate) async fn run(global: &Global, args: &WatchArgs) -> Result<(), CliError> {
    let (registers, mut core) = global.connect_to_read(&args.names, "watch").await?;
    let device = core.device();
    let terminal = std::io::stdout().is_terminal() && !global.json;
    let mut drawn_lines = 0usize;
    let mut last: Option<String> = None;
    let mut refresh = 0u64;
    let ctrl_c = tokio::signal::ctrl_c();
    tokio::pin!(ctrl_c);
    loop {
        let started = tokio::time::Instant::now();
        let outcome = tokio::select! {
            outcome = read_values(&mut core, &registers) => outcome,
            _ = &mut ctrl_c => break,
        };
        refresh += 1;
        let block = match &outcome {
            Ok(values) if global.json => {
                json!({"time": timestamp(), "values": values_json(values)}).to_string() + "\n"
            }
            Ok(values) => {
                let text = values_text(values);
                last = Some(text.clone());
                format!(
                    "{}  {} · slave {} · every {} ms\n{text}",
                    time_of_day(),
                    device.family,
                    core.slave(),
                    args.interval.as_millis()
                )
            }
            Err(error) if global.json => {
                json!({"time": timestamp(), "error": error.to_string()}).to_string() + "\n"
            }
            // Keep the last values on screen, marked, and try again.
            Err(error) => format!(
                "{}  ! {error} — retrying\n{}",
                time_of_day(),
                last.as_deref().unwrap_or("")
            ),
        };
        let mut out = std::io::stdout().lock();
        if terminal && drawn_lines > 0 {
            // Back to the top of the last drawing and clear it: the view refreshes in place.
            let _ = write!(out, "\x1b[{drawn_lines}F\x1b[J");
        }
        let _ = out.write_all(block.as_bytes());
        let _ = out.flush();
        drawn_lines = block.lines().count();
        if args.count.is_some_and(|n| refresh >= n) {
            break;
        }
        tokio::select! {
            () = tokio::time::sleep_until(started + args.interval) => {}
            _ = &mut ctrl_c => break,
        }
    }
    Ok(())
}
