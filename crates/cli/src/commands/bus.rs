//! `optobus bus check FILE`: a bus file checked as `optobus run` would read it, every problem
//! at once, located like rustc (or as JSON with `--json`); nothing is opened.
//! `optobus bus schema`: every key a bus file takes, as an annotated bus file.

use std::path::{Path, PathBuf};

use clap::Subcommand;
use optobus_bus::{BusFile, LoadError};
use optobus_service::ServiceFile;
use serde_json::json;

// Re-exported for `run` until it imports `crate::bus_file::load` itself.
pub(crate) use crate::bus_file::load;
use crate::error::CliError;
use crate::models;
use crate::render::{counted, pretty, print};

#[derive(Debug, Subcommand)]
pub(crate) enum BusCommand {
    /// Check a bus file: lines, devices, polls and outputs, every problem at once (--json:
    /// each as an object with its severity, message, file, line, column and help).
    Check {
        /// The bus file (YAML; `optobus bus schema` prints every key it takes).
        file: PathBuf,
    },
    /// Print the bus file's schema: every key, with its default or an example, as YAML.
    Schema,
}

pub(crate) fn run(json: bool, command: &BusCommand) -> Result<(), CliError> {
    match command {
        BusCommand::Check { file } if json => check_json(file),
        BusCommand::Check { file } => {
            let bus = load(file)?;
            print(&format!("{}: {}: ok", file.display(), summary(&bus)));
            Ok(())
        }
        BusCommand::Schema => {
            print(optobus_bus::file::SCHEMA);
            Ok(())
        }
    }
}

/// `2 lines, 1 device, 3 polls`.
fn summary(bus: &BusFile) -> String {
    let polls: usize = bus.devices.iter().map(|d| d.polls.len()).sum();
    format!(
        "{}, {}, {}",
        counted(bus.lines.len(), "line"),
        counted(bus.devices.len(), "device"),
        counted(polls, "poll")
    )
}

/// `bus check --json`: one JSON object on stdout whether the file passes or not; a file that
/// does not pass is then refused (exit 3) with a line on stderr.
fn check_json(path: &Path) -> Result<(), CliError> {
    let shown = path.display().to_string();
    match ServiceFile::load(path, models::catalogue()) {
        Ok(ServiceFile { bus, .. }) => {
            let polls: usize = bus.devices.iter().map(|d| d.polls.len()).sum();
            print(&pretty(&json!({
                "file": shown,
                "ok": true,
                "lines": bus.lines.len(),
                "devices": bus.devices.len(),
                "polls": polls,
                "diagnostics": [],
            })));
            Ok(())
        }
        Err(error @ LoadError::Read { .. }) => Err(CliError::failed(error.to_string())),
        Err(LoadError::Rejected(rejected)) => {
            print(&pretty(&json!({
                "file": shown,
                "ok": false,
                "diagnostics": rejected.reports(&shown),
            })));
            Err(CliError::new(format!(
                "{shown} does not pass the bus file checks: {}",
                counted(rejected.diagnostics.len(), "error")
            )))
        }
    }
}

/// Refuses `--spec`: a bus file names each device's model or spec file itself.
pub(crate) fn no_spec(options: &crate::connect::Options) -> Result<(), CliError> {
    match &options.spec {
        Some(_) => Err(CliError::new(
            "--spec does not apply to a bus: each device of the bus file names its `model` or `spec`",
        )),
        None => Ok(()),
    }
}
