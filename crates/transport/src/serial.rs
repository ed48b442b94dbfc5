//! Opening a serial port for the RTU client.

use std::fmt;

pub use tokio_serial::SerialStream;
use tokio_serial::{DataBits, FlowControl, SerialPortBuilderExt, StopBits};

use crate::Error;

/// Parity of a serial line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Parity {
    /// No parity bit.
    #[default]
    None,
    /// Odd parity.
    Odd,
    /// Even parity.
    Even,
}

impl Parity {
    /// `none`, `odd` or `even` (as in the specs); `None` for anything else.
    pub fn from_name(name: &str) -> Option<Self> {
        match name.to_ascii_lowercase().as_str() {
            "none" | "n" => Some(Self::None),
            "odd" | "o" => Some(Self::Odd),
            "even" | "e" => Some(Self::Even),
            _ => None,
        }
    }
}

impl fmt::Display for Parity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::None => "none",
            Self::Odd => "odd",
            Self::Even => "even",
        })
    }
}

/// How to open a serial port: 8 data bits, no flow control, and the rest as given.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SerialSettings {
    /// Device path (`/dev/ttyUSB0`, `COM3`).
    pub path: String,
    /// Line speed.
    pub baud: u32,
    /// Parity.
    pub parity: Parity,
    /// Data bits: 5 to 8.
    pub data_bits: u8,
    /// Stop bits: 1 or 2.
    pub stop_bits: u8,
}

impl SerialSettings {
    /// `path` at 115200 baud, 8N1; change the fields for other devices.
    pub fn new(path: impl Into<String>) -> Self {
        Self {
            path: path.into(),
            baud: 115_200,
            parity: Parity::None,
            data_bits: 8,
            stop_bits: 1,
        }
    }

    /// Opens the port.
    pub fn open(&self) -> Result<SerialStream, Error> {
        let data_bits = match self.data_bits {
            5 => DataBits::Five,
            6 => DataBits::Six,
            7 => DataBits::Seven,
            8 => DataBits::Eight,
            _ => return Err(Error::Unsupported("data bits other than 5 to 8")),
        };
        let stop_bits = match self.stop_bits {
            1 => StopBits::One,
            2 => StopBits::Two,
            _ => return Err(Error::Unsupported("stop bits other than 1 or 2")),
        };
        let parity = match self.parity {
            Parity::None => tokio_serial::Parity::None,
            Parity::Odd => tokio_serial::Parity::Odd,
            Parity::Even => tokio_serial::Parity::Even,
        };
        tokio_serial::new(&self.path, self.baud)
            .data_bits(data_bits)
            .stop_bits(stop_bits)
            .parity(parity)
            .flow_control(FlowControl::None)
            .open_native_async()
            .map_err(|error| Error::Io(std::io::Error::other(format!("{}: {error}", self.path))))
    }
}
