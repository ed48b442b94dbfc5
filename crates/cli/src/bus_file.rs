//! The bus file as the tool loads it, for every command that takes one.

use std::path::Path;

use optobus_bus::{BusFile, LoadError};

use crate::error::CliError;
use crate::models;

/// The checked bus file at `path`: a file that cannot be read is the system's failure, one
/// that does not pass is refused with every problem.
pub(crate) fn load(path: &Path) -> Result<BusFile, CliError> {
    BusFile::load(path, models::catalogue()).map_err(|error| match error {
        LoadError::Read { .. } => CliError::failed(error.to_string()),
        LoadError::Rejected(rejected) => CliError::new(format!(
            "{} does not pass the bus file checks:\n{}",
            path.display(),
            rejected.render().trim_end()
        )),
    })
}
