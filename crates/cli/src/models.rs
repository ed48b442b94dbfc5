//! The sensor families the tool knows, by family id or a friendly alias.

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

/// Extra names a family answers to.
fn aliases(family: &str) -> &'static [&'static str] {
    match family {
        "p_series" => &["p", "tsltp", "tsltpe", "laser-displacement"],
        "rangefinder" => &["laser-rangefinder", "ranger"],
        "ccs" => &["confocal", "spectral-confocal"],
        "lc_rs" => &["lc", "lcrs"],
        "ccf" => &["confocal-4", "four-channel"],
        _ => &[],
    }
}

/// The family called `name`.
pub(crate) fn find(name: &str) -> Result<&'static DeviceInfo, CliError> {
    let wanted = normalise(name);
    MODELS
        .iter()
        .copied()
        .find(|d| {
            normalise(d.family) == wanted
                || aliases(d.family).iter().any(|a| normalise(a) == wanted)
        })
        .ok_or_else(|| {
            let known: Vec<&str> = MODELS.iter().map(|d| d.family).collect();
            CliError::new(format!("unknown model `{name}`")).hint(format!(
                "known models: {}; see `optobus models`",
                known.join(", ")
            ))
        })
}
