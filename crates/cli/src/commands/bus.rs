//! `optobus bus check FILE`: a bus file checked as `optobus run` would read it, every problem
//! at once, located like rustc; nothing is opened.

use std::path::PathBuf;

use clap::Subcommand;
use optobus_bus::BusFile;

use crate::error::CliError;
use crate::models;
use crate::render::print;

#[derive(Debug, Subcommand)]
pub(crate) enum BusCommand {
    /// Check a bus file: lines, devices, polls and outputs, every problem at once.
    Check {
        /// The bus file (YAML; see crates/bus/README.md).
        file: PathBuf,
    },
}

pub(crate) fn run(command: &BusCommand) -> Result<(), CliError> {
    match command {
        BusCommand::Check { file } => {
            let bus = load(file)?;
            let polls: usize = bus.devices.iter().map(|d| d.polls.len()).sum();
            print(&format!(
                "{}: {} lines, {} devices, {polls} polls: ok",
                file.display(),
                bus.lines.len(),
                bus.devices.len()
            ));
            Ok(())
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

/// The checked bus file at `path`: a file that cannot be read is the system's failure, one
/// that does not pass is refused with every problem.
pub(crate) fn load(path: &std::path::Path) -> Result<BusFile, CliError> {
    BusFile::load(path, &models::catalogue()).map_err(|error| match error {
        optobus_bus::LoadError::Read { .. } => CliError::failed(error.to_string()),
        optobus_bus::LoadError::Rejected(rejected) => CliError::new(format!(
            "{} does not pass the bus file checks:\n{}",
            path.display(),
            rejected.render().trim_end()
        )),
    })
}
