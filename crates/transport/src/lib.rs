//! The transport under every optobus driver: read words, write one register.
//!
//! It knows nothing about sensor families. Two backends implement [`Transport`]:
//!
//! - [`RtuClient`]: our own Modbus RTU client over any `AsyncRead + AsyncWrite` (a serial
//!   port, a pty, an in-memory duplex), built on `optobus-codec`, so it speaks the frame shapes
//!   tokio-modbus cannot decode (the rangefinder's 10-byte FC06 echo, LC-RS's 7-byte
//!   exceptions). It keeps the 3.5-character silence between frames, drains stale bytes before
//!   a request, resynchronises after a garbled reply, and sends broadcasts without waiting.
//! - [`ModbusContext`]: a user's `tokio_modbus::client::Context` (TCP or standard RTU), so an
//!   optobus driver can share a bus with other Modbus devices.
//!
//! Every request has a timeout; reads may be retried, writes never are. [`Shared`] serialises
//! transactions of several drivers (several slaves on one port) used from different tasks.
#![forbid(unsafe_code)]

use std::fmt;
use std::future::Future;
use std::time::Duration;

pub use optobus_codec::{
    DecodeError, EncodeError, ExceptionCode, ExceptionShape, ReadFunction, WriteValue,
};

mod modbus;
mod rtu;
mod serial;
mod shared;

pub use modbus::ModbusContext;
pub use rtu::{RtuClient, RtuConfig};
pub use serial::{Parity, SerialSettings, SerialStream};
pub use shared::Shared;

/// The default time to wait for a reply.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(1);

/// Reads and writes registers of Modbus slaves.
pub trait Transport: Send {
    /// Reads `count` words from `address` of slave `slave` with FC03 or FC04.
    fn read(
        &mut self,
        slave: u8,
        function: ReadFunction,
        address: u16,
        count: u16,
    ) -> impl Future<Output = Result<Vec<u16>, Error>> + Send;

    /// Writes one register with FC06 (two or four data bytes). Slave 0 broadcasts: the write
    /// is sent and no reply is awaited.
    fn write(
        &mut self,
        slave: u8,
        address: u16,
        value: WriteValue,
    ) -> impl Future<Output = Result<(), Error>> + Send;
}

/// Why a transaction failed.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// No complete reply within the timeout.
    Timeout {
        /// How long we waited.
        after: Duration,
    },
    /// The device answered with an exception.
    Exception {
        /// The request's function code.
        function: u8,
        /// The device's code.
        code: ExceptionCode,
    },
    /// The reply was malformed (bad CRC, wrong slave, wrong length…); the line was
    /// resynchronised.
    Frame(DecodeError),
    /// The request could not be encoded (for example a read of 0 or more than 125 words).
    Request(EncodeError),
    /// The reply carried another number of words than asked for.
    WordCount {
        /// Words asked for.
        expected: u16,
        /// Words received.
        received: usize,
    },
    /// The backend cannot send this request (a 4-byte FC06 or a broadcast through
    /// tokio-modbus).
    Unsupported(&'static str),
    /// The stream was closed.
    Closed,
    /// An I/O error of the underlying stream.
    Io(std::io::Error),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Timeout { after } => write!(f, "no reply within {} ms", after.as_millis()),
            Self::Exception { function, code } => {
                write!(
                    f,
                    "device answered exception {code} to function {function:#04X}"
                )
            }
            Self::Frame(error) => write!(f, "malformed reply: {error}"),
            Self::Request(error) => write!(f, "invalid request: {error}"),
            Self::WordCount { expected, received } => {
                write!(
                    f,
                    "asked for {expected} words, the reply carries {received}"
                )
            }
            Self::Unsupported(what) => write!(f, "not supported by this transport: {what}"),
            Self::Closed => f.write_str("the connection is closed"),
            Self::Io(error) => write!(f, "I/O error: {error}"),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Frame(error) => Some(error),
            Self::Request(error) => Some(error),
            Self::Io(error) => Some(error),
            _ => None,
        }
    }
}

impl From<std::io::Error> for Error {
    fn from(error: std::io::Error) -> Self {
        Self::Io(error)
    }
}

impl Error {
    /// True for failures a read may be retried after (no reply, garbled reply).
    pub fn is_transient(&self) -> bool {
        matches!(self, Self::Timeout { .. } | Self::Frame(_))
    }
}
