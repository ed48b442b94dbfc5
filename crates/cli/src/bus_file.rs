//! The bus file as the tool loads it, for every command that takes one.

use std::path::Path;

use optobus_bus::BusFile;
use optobus_service::ServiceFile;

use crate::error::CliError;
use crate::models;

/// The checked bus file at `path`: a file that cannot be read is the system's failure, one
/// that does not pass (its outputs' settings included) is refused with every problem.
pub(crate) fn load(path: &Path) -> Result<BusFile, CliError> {
    load_with_outputs(path).map(|file| file.bus)
}

/// [`load`], with the settings of the outputs the file names.
pub(crate) fn load_with_outputs(path: &Path) -> Result<ServiceFile, CliError> {
    ServiceFile::load(path, models::catalogue()).map_err(|error| CliError::bus_file(path, error))
}
