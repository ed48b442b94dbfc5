//! The models a bus file may name: the built-in ones its user supplies, and spec files,
//! checked and described by the spec compiler once per path.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use optobus_device::DeviceInfo;

/// Models by name, and spec files described once.
#[derive(Debug, Default)]
pub struct Catalogue {
    built_in: Vec<&'static DeviceInfo>,
    loaded: Mutex<HashMap<PathBuf, Result<&'static DeviceInfo, String>>>,
}

impl Catalogue {
    /// A catalogue of `models` (e.g. `[&optobus_p_series::DEVICE, &optobus_ccs::DEVICE]`).
    pub fn new(models: impl IntoIterator<Item = &'static DeviceInfo>) -> Self {
        Self {
            built_in: models.into_iter().collect(),
            loaded: Mutex::default(),
        }
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

    /// The model the spec file at `path` describes, checked like `optobus-codegen check`;
    /// each path is read once, and its description lives as long as the process.
    pub fn load(&self, path: &Path) -> Result<&'static DeviceInfo, String> {
        let mut loaded = self.loaded.lock().unwrap_or_else(|e| e.into_inner());
        loaded
            .entry(path.to_path_buf())
            .or_insert_with(|| describe(path))
            .clone()
    }
}

fn describe(path: &Path) -> Result<&'static DeviceInfo, String> {
    let name = path.display().to_string();
    let text =
        optobus_spec::source::read_yaml(path).map_err(|e| format!("cannot read {name}: {e}"))?;
    match optobus_spec::check_source(&name, &text) {
        Ok(model) => Ok(optobus_spec::describe(&model)),
        Err(rejected) => Err(format!(
            "it does not pass the spec checks:\n{}",
            rejected.render().trim_end()
        )),
    }
}
