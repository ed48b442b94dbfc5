//! Why a transaction failed: the one error type of every client.

use std::fmt;
use std::time::Duration;

use optobus_codec::{DecodeError, EncodeError, ExceptionCode, LineFormatError};

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
                let plural = if *attempts == 1 { "" } else { "s" };
                write!(f, "cannot connect ({attempts} attempt{plural}): {source}")
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
