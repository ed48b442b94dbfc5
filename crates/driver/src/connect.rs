//! Transport settings taken from a device description (its serial defaults and frame shapes).

use optobus_device::DeviceInfo;
#[cfg(feature = "tcp")]
use optobus_transport::TcpConfig;
use optobus_transport::{LineFormat, RtuConfig, SerialSettings};

/// The factory line format of `device` (115200 8N1 for a device without serial settings).
pub fn line_format(device: &DeviceInfo) -> LineFormat {
    device
        .rtu
        .map_or(LineFormat::new(115_200), |rtu| LineFormat {
            baud: rtu.default_baud,
            data_bits: rtu.data_bits,
            parity: rtu.parity,
            stop_bits: rtu.stop_bits,
        })
}

/// Settings for our RTU client on a serial line to `device`: its exception frame shape and
/// factory line format (which sets the silence between frames), the default 1 s timeout, no
/// retries. For an in-memory stream or RTU over TCP set `line: None`.
pub fn rtu_config(device: &DeviceInfo) -> RtuConfig {
    RtuConfig {
        line: Some(line_format(device)),
        exception: device.frame_shape.exception,
        ..RtuConfig::default()
    }
}

/// Settings for our Modbus TCP client to `device`: its exception frame shape, the default
/// timeout and reconnection backoff, no retries (feature `tcp`).
#[cfg(feature = "tcp")]
pub fn tcp_config(device: &DeviceInfo) -> TcpConfig {
    TcpConfig {
        exception: device.frame_shape.exception,
        ..TcpConfig::default()
    }
}

/// The serial port `path` with `device`'s factory line format; change `line` for a device
/// configured otherwise. Opening it (`SerialSettings::open`) needs the `serial` feature
/// (`features = ["serial"]` on the driver crate).
pub fn serial_settings(device: &DeviceInfo, path: impl Into<String>) -> SerialSettings {
    SerialSettings {
        path: path.into(),
        line: line_format(device),
    }
}
