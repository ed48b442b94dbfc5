//! The sensor models the tool knows: every spec of `specs/` at build time (embedded by
//! `build.rs`), described through the same checks as a `--spec` file into the one catalogue
//! the bus files are read with, and found by family id or an alias the spec declares.

use std::path::Path;
use std::sync::OnceLock;

use optobus_device::DeviceInfo;
use optobus_spec::source::ReadError;
use optobus_spec::{Catalogue, SpecError};

use crate::error::CliError;

include!(concat!(env!("OUT_DIR"), "/specs.rs"));

/// The tool's catalogue, shared with the bus files it reads: the built-in models (checked when
/// first needed), and each spec file given (`--spec`, or named by a bus file) read and
/// described once.
pub(crate) fn catalogue() -> &'static Catalogue {
    static CATALOGUE: OnceLock<Catalogue> = OnceLock::new();
    CATALOGUE.get_or_init(|| Catalogue::of_specs(SPECS))
}

/// The model a spec file describes; a spec that does not pass gives the checker's located
/// diagnostics, rendered like rustc.
pub(crate) fn load(path: &Path) -> Result<&'static DeviceInfo, CliError> {
    catalogue().load(path).map_err(|error| {
        // A file that cannot be read is the system's failure; one that is too large, no file
        // or no text, or fails the checks, input refused.
        let message = error.to_string();
        match &*error {
            SpecError::Read {
                source: ReadError::Io(_),
                ..
            } => CliError::failed(message),
            _ => CliError::new(message),
        }
    })
}

/// Every built-in model, in the order of their manuals.
pub(crate) fn all() -> &'static [&'static DeviceInfo] {
    catalogue().built_in()
}

/// The family called `name` (its id or one of its aliases).
pub(crate) fn find(name: &str) -> Result<&'static DeviceInfo, CliError> {
    all()
        .iter()
        .copied()
        .find(|d| d.is_called(name))
        .ok_or_else(|| {
            CliError::new(format!("unknown model `{name}`")).hint(format!(
                "known models: {}; or give a spec file with --spec; see `optobus models`",
                names().join(", ")
            ))
        })
}

/// The model's name as users type it (`p-series`).
pub(crate) fn name(device: &DeviceInfo) -> String {
    device.model_name().to_string()
}

/// The models' names as users type them.
pub(crate) fn names() -> Vec<String> {
    all().iter().map(|d| name(d)).collect()
}
