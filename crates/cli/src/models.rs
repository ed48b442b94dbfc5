//! The sensor models the tool knows: every spec of `specs/` at build time (embedded by
//! `build.rs`), described at startup through the same checks as a `--spec` file, and found by
//! family id or an alias the spec declares.

use std::path::Path;
use std::sync::OnceLock;

use optobus_device::DeviceInfo;

use crate::error::CliError;

include!(concat!(env!("OUT_DIR"), "/specs.rs"));

/// The runtime description of a spec's text; a spec that does not pass gives the checker's
/// located diagnostics, rendered like rustc.
pub(crate) fn describe(name: &str, text: &str) -> Result<&'static DeviceInfo, CliError> {
    match optobus_spec::check_source(name, text) {
        Ok(model) => Ok(optobus_spec::describe(&model)),
        Err(rejected) => Err(CliError::new(format!(
            "{name} does not pass the spec checks:\n{}",
            rejected.render().trim_end()
        ))),
    }
}

/// The model a spec file describes (read and described once per run).
pub(crate) fn load(path: &Path) -> Result<&'static DeviceInfo, CliError> {
    static LOADED: OnceLock<Result<&'static DeviceInfo, CliError>> = OnceLock::new();
    let loaded = LOADED.get_or_init(|| {
        let name = path.display().to_string();
        // A file that cannot be read is the system's failure; one that is too large, no file or
        // no text, or fails the checks, input refused.
        let text = optobus_spec::source::read_yaml(path).map_err(|e| {
            let message = format!("cannot read {name}: {e}");
            match e {
                optobus_spec::source::ReadError::Io(_) => CliError::failed(message),
                _ => CliError::new(message),
            }
        })?;
        describe(&name, &text)
    });
    loaded.clone()
}

/// Every built-in model, in the order of their manuals.
pub(crate) fn all() -> &'static [&'static DeviceInfo] {
    static MODELS: OnceLock<Vec<&'static DeviceInfo>> = OnceLock::new();
    MODELS.get_or_init(|| {
        let mut models: Vec<&'static DeviceInfo> = SPECS
            .iter()
            // build.rs refuses to build with a spec that fails its checks.
            .filter_map(|(name, text)| describe(name, text).ok())
            .collect();
        models.sort_by_key(|d| d.manual);
        models
    })
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

/// The built-in models as a bus file names them.
pub(crate) fn catalogue() -> optobus_bus::Catalogue {
    optobus_bus::Catalogue::new(all().iter().copied())
}

/// The model's name as users type it (`p-series`).
pub(crate) fn name(device: &DeviceInfo) -> String {
    device.model_name().to_string()
}

/// The models' names as users type them.
pub(crate) fn names() -> Vec<String> {
    all().iter().map(|d| name(d)).collect()
}

/// Which model a device is, in words: `p-series`, `no model fits`, `several models fit: ccs,
/// ccf`.
pub(crate) fn verdict(verdict: &optobus_driver::identify::Verdict) -> String {
    use optobus_driver::identify::Verdict;
    match verdict {
        Verdict::One(model) => name(model),
        Verdict::None => "no model fits".to_owned(),
        Verdict::Several(models) => {
            let names: Vec<String> = models.iter().map(|m| name(m)).collect();
            format!("several models fit: {}", names.join(", "))
        }
    }
}
