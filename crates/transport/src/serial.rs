//! Opening a serial port for the RTU client.

#[cfg(all(feature = "serial", unix))]
mod stream;

#[cfg(all(feature = "serial", unix))]
pub use stream::SerialStream;
#[cfg(feature = "serial")]
#[cfg(not(unix))]
use tokio_serial::SerialPortBuilderExt;
#[cfg(all(feature = "serial", not(unix)))]
pub use tokio_serial::SerialStream;
#[cfg(feature = "serial")]
use tokio_serial::{DataBits, FlowControl, StopBits};

use optobus_codec::LineFormat;
#[cfg(feature = "serial")]
use optobus_codec::Parity;

#[cfg(feature = "serial")]
use crate::error::Error;

/// How to open a serial port: its path and line format, no flow control.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SerialSettings {
    /// Device path (`/dev/ttyUSB0`, `COM3`).
    pub path: String,
    /// Baud rate and character format.
    pub line: LineFormat,
}

impl SerialSettings {
    /// `path` at 115200 baud, 8N1; change `line` for other devices.
    pub fn new(path: impl Into<String>) -> Self {
        Self {
            path: path.into(),
            line: LineFormat::new(115_200),
        }
    }

    /// Opens the port; a format no line can have is refused before the port is touched.
    ///
    /// Needs the `serial` feature (of this crate, of `optobus-driver` or of a driver crate:
    /// `features = ["serial"]`); without it there is no `open` (``no method named `open` ``),
    /// so that TCP and in-memory users build no serial stack.
    #[cfg(feature = "serial")]
    #[cfg_attr(docsrs, doc(cfg(feature = "serial")))]
    pub fn open(&self) -> Result<SerialStream, Error> {
        self.line.check().map_err(Error::Line)?;
        let data_bits = match self.line.data_bits {
            5 => DataBits::Five,
            6 => DataBits::Six,
            7 => DataBits::Seven,
            _ => DataBits::Eight,
        };
        let stop_bits = match self.line.stop_bits {
            1 => StopBits::One,
            _ => StopBits::Two,
        };
        let parity = match self.line.parity {
            Parity::None => tokio_serial::Parity::None,
            Parity::Odd => tokio_serial::Parity::Odd,
            Parity::Even => tokio_serial::Parity::Even,
        };
        let builder = tokio_serial::new(&self.path, self.line.baud)
            .data_bits(data_bits)
            .stop_bits(stop_bits)
            .parity(parity)
            .flow_control(FlowControl::None);
        let failed = |error: tokio_serial::Error| {
            Error::Io(std::io::Error::other(format!("{}: {error}", self.path)))
        };
        #[cfg(unix)]
        let port = mio_serial::SerialStream::open(&builder)
            .map(SerialStream::new)
            .map_err(failed);
        #[cfg(not(unix))]
        let port = builder.open_native_async().map_err(failed);
        port
    }
}
