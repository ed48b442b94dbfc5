//! Transport settings taken from a device description (its serial defaults and frame shapes).

use optobus_device::DeviceInfo;
use optobus_transport::{Parity, RtuConfig, SerialSettings};

/// Settings for our RTU client that fit `device`: its exception frame shape and factory
/// baud rate (which sets the silence between frames), the default 1 s timeout, no retries.
pub fn rtu_config(device: &DeviceInfo) -> RtuConfig {
    RtuConfig {
        baud: device
            .rtu
            .map_or(RtuConfig::default().baud, |rtu| rtu.default_baud),
        exception: device.frame_shape.exception,
        ..RtuConfig::default()
    }
}

/// The serial port `path` with `device`'s factory line settings (baud, parity, data and stop
/// bits); change fields for a device configured otherwise.
pub fn serial_settings(device: &DeviceInfo, path: impl Into<String>) -> SerialSettings {
    let mut settings = SerialSettings::new(path);
    if let Some(rtu) = device.rtu {
        settings.baud = rtu.default_baud;
        settings.parity = Parity::from_name(rtu.parity).unwrap_or_default();
        settings.data_bits = rtu.data_bits;
        settings.stop_bits = rtu.stop_bits;
    }
    settings
}
