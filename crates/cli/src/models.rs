//! The sensor families the tool knows, by family id or an alias the spec declares.

use optobus_device::DeviceInfo;

use crate::error::CliError;

/// Every family, in the order of the manuals.
pub(crate) const MODELS: [&DeviceInfo; 5] = [
    &optobus_p_series::DEVICE,
    &optobus_rangefinder::DEVICE,
    &optobus_ccs::DEVICE,
    &optobus_lc_rs::DEVICE,
    &optobus_ccf::DEVICE,
];

/// Lower case without `-`, `_` and spaces, so `P-Series`, `p_series` and `pseries` agree.
fn normalise(name: &str) -> String {
    name.chars()
        .filter(|c| c.is_ascii_alphanumeric())
        .map(|c| c.to_ascii_lowercase())
        .collect()
}

/// The family called `name` (its id or one of its aliases).
pub(crate) fn find(name: &str) -> Result<&'static DeviceInfo, CliError> {
    let wanted = normalise(name);
    MODELS
        .iter()
        .copied()
        .find(|d| normalise(d.family) == wanted || d.aliases.iter().any(|a| normalise(a) == wanted))
        .ok_or_else(|| {
            CliError::new(format!("unknown model `{name}`")).hint(format!(
                "known models: {}; see `optobus models`",
                names().join(", ")
            ))
        })
}

/// The model's name as users type it (`p-series`).
pub(crate) fn name(device: &DeviceInfo) -> String {
    device.family.replace('_', "-")
}

/// The models' names as users type them.
pub(crate) fn names() -> Vec<String> {
    MODELS.iter().map(|d| name(d)).collect()
}
