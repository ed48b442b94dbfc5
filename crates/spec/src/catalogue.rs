//! The models a program knows: its built-in ones, and spec files checked and described once
//! per path. The `optobus` tool and the bus share this one catalogue.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use optobus_device::DeviceInfo;

use crate::source::{read_yaml, ReadError};
use crate::{check_text, describe, Rejected};

/// Models by name, and spec files described once.
#[derive(Debug, Default)]
pub struct Catalogue {
    built_in: Vec<&'static DeviceInfo>,
    loaded: Mutex<HashMap<PathBuf, Result<&'static DeviceInfo, Arc<SpecError>>>>,
}

/// Why a spec file gives no model.
#[derive(Debug)]
pub enum SpecError {
    /// The file could not be read (too large, not a file, not UTF-8, or the system's failure).
    Read {
        /// The path as given, for messages.
        name: String,
        /// Why.
        source: ReadError,
    },
    /// The spec did not pass its checks.
    Rejected(Box<Rejected>),
}

impl std::fmt::Display for SpecError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Read { name, source } => write!(f, "cannot read {name}: {source}"),
            Self::Rejected(rejected) => write!(
                f,
                "{} does not pass the spec checks:\n{}",
                rejected.source.name,
                rejected.render().trim_end()
            ),
        }
    }
}

impl std::error::Error for SpecError {}

impl Catalogue {
    /// A catalogue of `models` (e.g. `[&optobus_p_series::DEVICE, &optobus_ccs::DEVICE]`),
    /// in the order given.
    pub fn new(models: impl IntoIterator<Item = &'static DeviceInfo>) -> Self {
        Self {
            built_in: models.into_iter().collect(),
            loaded: Mutex::default(),
        }
    }

    /// A catalogue of the models that spec texts (file name, text) describe, in the order of
    /// their manuals; a text that does not pass the checks is left out (a build script that
    /// embeds specs refuses those).
    pub fn of_specs(specs: &[(&str, &str)]) -> Self {
        let mut models: Vec<&'static DeviceInfo> = specs
            .iter()
            .filter_map(|(name, text)| crate::check_source(name, text).ok())
            .map(|model| describe(&model))
            .collect();
        models.sort_by_key(|device| device.manual);
        Self::new(models)
    }

    /// The built-in models.
    pub fn built_in(&self) -> &[&'static DeviceInfo] {
        &self.built_in
    }

    /// The built-in model called `name` (its family id or an alias, in any case, with or
    /// without `-` and `_`).
    pub fn find(&self, name: &str) -> Option<&'static DeviceInfo> {
        self.built_in
            .iter()
            .copied()
            .find(|device| device.is_called(name))
    }

    /// The built-in models' names as users type them (`p-series`).
    pub fn names(&self) -> Vec<String> {
        self.built_in
            .iter()
            .map(|d| d.model_name().to_string())
            .collect()
    }

    /// The model the spec file at `path` describes (read with [`read_yaml`], checked like
    /// every spec); each path is read once, and its description lives as long as the process.
    pub fn load(&self, path: &Path) -> Result<&'static DeviceInfo, Arc<SpecError>> {
        let mut loaded = self.loaded.lock().unwrap_or_else(|e| e.into_inner());
        loaded
            .entry(path.to_path_buf())
            .or_insert_with(|| load(path).map_err(Arc::new))
            .clone()
    }
}

fn load(path: &Path) -> Result<&'static DeviceInfo, SpecError> {
    let name = path.display().to_string();
    let text = read_yaml(path).map_err(|source| SpecError::Read {
        name: name.clone(),
        source,
    })?;
    match check_text(&name, text) {
        Ok(model) => Ok(describe(&model)),
        Err(rejected) => Err(SpecError::Rejected(rejected)),
    }
}
