//! The transport under every optobus driver: read words, write one register.
//!
//! It knows nothing about sensor families. Three backends implement [`Transport`]:
//!
//! - [`RtuClient`]: our own Modbus RTU client over any `AsyncRead + AsyncWrite` (a serial
//!   port, a pty, an in-memory duplex), built on `optobus-codec`, so it speaks the frame shapes
//!   tokio-modbus cannot decode (the rangefinder's 10-byte FC06 echo, LC-RS's 7-byte
//!   exceptions). It keeps t3.5 of silence before each request to within microseconds,
//!   recovers the line after any fault so that a late reply never answers a later request,
//!   and sends broadcasts without waiting.
//! - [`TcpClient`]: our own Modbus TCP client: replies matched by transaction id (stale ones
//!   skipped), broken connections re-established with a bounded backoff.
//! - [`ModbusContext`]: a user's `tokio_modbus::client::Context` (TCP or standard RTU), so an
//!   optobus driver can share a connection with other Modbus devices; see its docs for what it
//!   cannot recover from.
//!
//! Cargo features: `serial` (default) opens serial ports with tokio-serial, `tcp` (default)
//! is the TCP client, `tokio-modbus` the bridge; the RTU client over a stream is always there.
//!
//! Every request has a timeout (a huge one means "wait forever", never an overflow);
//! repeatable reads may be retried, writes and reads with a side effect never are. [`Shared`]
//! serialises transactions of several drivers (several slaves on one port) used from
//! different tasks.
#![forbid(unsafe_code)]

use std::fmt;
use std::future::Future;
use std::time::Duration;

pub use optobus_codec::{
    DecodeError, EncodeError, ExceptionCode, ExceptionShape, LineFormat, LineFormatError, Parity,
    ReadFunction, WriteValue,
};

#[cfg(feature = "tokio-modbus")]
mod modbus;
mod rtu;
mod serial;
mod shared;
mod tap;
#[cfg(feature = "tcp")]
mod tcp;
pub mod timing;
mod transact;

#[cfg(feature = "tokio-modbus")]
pub use modbus::ModbusContext;
pub use rtu::{RtuClient, RtuConfig};
pub use serial::SerialSettings;
#[cfg(feature = "serial")]
pub use serial::SerialStream;
pub use shared::Shared;
pub use tap::{Flow, Observe, Tap};
#[cfg(feature = "tcp")]
pub use tcp::{resolve, Connect, TapConnect, TcpClient, TcpConfig};

/// The default time to wait for a reply.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(1);

/// One read: `count` words from `address` with FC03 or FC04, and whether a failed attempt may
/// be tried again.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadRequest {
    /// FC03 (holding registers) or FC04 (input registers).
    pub function: ReadFunction,
    /// The first register.
    pub address: u16,
    /// How many words.
    pub count: u16,
    /// False for registers whose read has a side effect (turns a buffer page), where a second
    /// attempt would read something else: one attempt whatever the retry setting.
    pub repeatable: bool,
}

impl ReadRequest {
    /// A repeatable read of `count` words from `address`.
    pub const fn new(function: ReadFunction, address: u16, count: u16) -> Self {
        Self {
            function,
            address,
            count,
            repeatable: true,
        }
    }

    /// The same read, made once whatever the retry setting.
    pub const fn once(self) -> Self {
        Self {
            repeatable: false,
            ..self
        }
    }
}

/// Reads and writes registers of Modbus slaves.
///
/// An implementor provides [`Transport::read_words`] and [`Transport::write`];
/// [`Transport::read`] and [`Transport::read_once`] are shorthands for the two kinds of read.
pub trait Transport: Send {
    /// Carries out `read` at slave `slave`, retrying it (where the transport retries) only if
    /// it is repeatable.
    fn read_words(
        &mut self,
        slave: u8,
        read: ReadRequest,
    ) -> impl Future<Output = Result<Vec<u16>, Error>> + Send;

    /// Reads `count` words from `address` of slave `slave` with FC03 or FC04 (a repeatable
    /// read).
    fn read(
        &mut self,
        slave: u8,
        function: ReadFunction,
        address: u16,
        count: u16,
    ) -> impl Future<Output = Result<Vec<u16>, Error>> + Send {
        self.read_words(slave, ReadRequest::new(function, address, count))
    }

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
    /// The reply was malformed (bad CRC, wrong slave, wrong length…); it was discarded and the
    /// line is recovered before the next request.
    Frame(DecodeError),
    /// The request could not be encoded (a read of 0 or more than 125 words, a reserved
    /// slave address…); nothing was sent.
    Request(EncodeError),
    /// The reply carried another number of words than asked for.
    WordCount {
        /// Words asked for.
        expected: u16,
        /// Words received.
        received: usize,
    },
    /// The backend cannot send this request (a 4-byte FC06 or a broadcast through
    /// tokio-modbus, a broadcast read); nothing was sent.
    Unsupported(&'static str),
    /// The peer closed the connection or the stream ended; a TCP client reconnects on the
    /// next request.
    Closed,
    /// No connection could be made (the first or a renewed one).
    Connect {
        /// Connection attempts since the last working connection.
        attempts: u32,
        /// Why the last attempt failed.
        source: std::io::Error,
    },
    /// A reply answered another request and the backend cannot skip it (tokio-modbus, which
    /// stays one reply behind afterwards; the optobus clients skip stale replies instead).
    Desynchronised(&'static str),
    /// The serial line format cannot work (a baud rate of 0, 9 data bits…).
    Line(LineFormatError),
    /// Another I/O error of the underlying stream.
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
            Self::Closed => f.write_str("the connection was closed by the other end"),
            Self::Connect { attempts, source } => {
                write!(f, "cannot connect ({attempts} attempts): {source}")
            }
            Self::Desynchronised(what) => write!(f, "reply out of step: {what}"),
            Self::Line(error) => write!(f, "unusable serial line format: {error}"),
            Self::Io(error) => write!(f, "I/O error: {error}"),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Frame(error) => Some(error),
            Self::Request(error) => Some(error),
            Self::Connect { source, .. } => Some(source),
            Self::Line(error) => Some(error),
            Self::Io(error) => Some(error),
            _ => None,
        }
    }
}

impl From<std::io::Error> for Error {
    /// A stream that ended or was reset is [`Error::Closed`]; anything else stays
    /// [`Error::Io`].
    fn from(error: std::io::Error) -> Self {
        use std::io::ErrorKind::{
            BrokenPipe, ConnectionAborted, ConnectionReset, NotConnected, UnexpectedEof,
        };
        match error.kind() {
            BrokenPipe | ConnectionAborted | ConnectionReset | NotConnected | UnexpectedEof => {
                Self::Closed
            }
            _ => Self::Io(error),
        }
    }
}

impl Error {
    /// True for failures a repeatable read may be retried after: no reply, a garbled reply,
    /// a connection that closed or could not be made (a TCP client reconnects).
    pub fn is_transient(&self) -> bool {
        matches!(
            self,
            Self::Timeout { .. } | Self::Frame(_) | Self::Closed | Self::Connect { .. }
        )
    }
}
