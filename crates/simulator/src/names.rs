//! The few register, field and code names the engine looks up.
//!
//! Everything else comes from `DeviceInfo` structure (tables, kinds, units, commands and their
//! effects). These names are shared by the specs that have such registers; the spec schema has
//! no field that says "this is the slave address" yet.

/// The register holding the Modbus slave address (P series, rangefinder, LC-RS).
pub(crate) const SLAVE_ADDRESS: &str = optobus_device::SLAVE_ADDRESS_REGISTER;
/// A register, or a packed field, holding the baud rate (plain number or enum of rates).
pub(crate) const BAUD_RATE: &str = "baud_rate";
/// A register, or a packed field, holding the parity (codes named like `RtuInfo::parity`).
pub(crate) const PARITY: &str = "parity";
/// The P series' input register showing the port of the connected Modbus TCP client.
pub(crate) const HOST_PORT: &str = "connected_host_port";
/// The group listing a device's readings (its read-only members are measurements).
pub(crate) const MEASUREMENTS_GROUP: &str = "measurements";
/// Suffix of the packed register configuring a statistic (`statistic_1` → `statistic_1_config`).
pub(crate) const CONFIG_SUFFIX: &str = "_config";
/// Suffix of unit-less readings that count events (encoder pulses): they run as counters.
pub(crate) const COUNT_SUFFIX: &str = "_count";
/// Code names of a statistic's kind field.
pub(crate) const MAXIMUM: &str = "maximum";
/// See [`MAXIMUM`].
pub(crate) const MINIMUM: &str = "minimum";
/// See [`MAXIMUM`].
pub(crate) const PEAK_TO_PEAK: &str = "peak_to_peak";
