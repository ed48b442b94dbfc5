//! One client of either protocol, and the port it is opened on: what a bus's lines and a
//! command-line tool talk through, so that neither writes its own.

use std::fmt;
use std::time::Duration;

use optobus_codec::{ExceptionShape, WriteValue};
use tokio::io::{AsyncRead, AsyncWrite};
use tokio::time::Instant;

use crate::error::Error;
use crate::rtu::{RtuClient, RtuConfig};
#[cfg(feature = "serial")]
use crate::serial::SerialSettings;
#[cfg(feature = "tcp")]
use crate::tcp::{TcpClient, TcpConfig};
use crate::transport::{ReadRequest, Transport};

/// A byte stream RTU frames travel on (a serial port, a converter's TCP socket, an in-memory
/// or simulated line).
pub trait Stream: AsyncRead + AsyncWrite + Unpin + Send + 'static {}
impl<S: AsyncRead + AsyncWrite + Unpin + Send + 'static> Stream for S {}

/// A client of whichever protocol its port speaks.
pub enum Client {
    /// RTU frames on a stream.
    Rtu(RtuClient<Box<dyn Stream>>),
    /// Modbus TCP.
    #[cfg(feature = "tcp")]
    #[cfg_attr(docsrs, doc(cfg(feature = "tcp")))]
    Tcp(TcpClient),
}

impl fmt::Debug for Client {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Rtu(client) => f.debug_tuple("Rtu").field(client.config()).finish(),
            #[cfg(feature = "tcp")]
            Self::Tcp(client) => f.debug_tuple("Tcp").field(client.config()).finish(),
        }
    }
}

/// How every request of a client is made, whichever its protocol: what a device's
/// description or a user's options set before its requests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Requests {
    /// How long to wait for a reply.
    pub timeout: Duration,
    /// How many times a failed repeatable read is tried again.
    pub retries: u8,
    /// How the device frames exception replies.
    pub exception: ExceptionShape,
}

impl Client {
    /// An RTU client on `stream` with `config`.
    pub fn rtu(stream: impl Stream, config: RtuConfig) -> Self {
        Self::Rtu(RtuClient::with_config(Box::new(stream), config))
    }

    /// When the last request began to leave, once the line was ready (recovered, silent,
    /// connected).
    pub fn last_request(&self) -> Option<Instant> {
        match self {
            Self::Rtu(client) => client.last_request(),
            #[cfg(feature = "tcp")]
            Self::Tcp(client) => client.last_request(),
        }
    }

    /// When the next of a series of reads every `interval` may start, the last one having
    /// started at `started`: one interval after it, or after its last request went out if the
    /// line held that back (recovering from a fault waits for a quiet line, up to a timeout).
    /// Ticks missed meanwhile are skipped: two reads never go out closer than `interval`.
    pub fn next_read(&self, started: Instant, interval: std::time::Duration) -> Instant {
        let sent = self.last_request().unwrap_or(started);
        crate::timing::deadline_from(started.max(sent), interval)
    }

    /// Opens the connection now where the protocol has one (Modbus TCP, which otherwise
    /// connects on the first request), to tell at once that the server cannot be reached;
    /// an RTU stream is open already.
    pub async fn connect(&mut self) -> Result<(), Error> {
        match self {
            Self::Rtu(_) => Ok(()),
            #[cfg(feature = "tcp")]
            Self::Tcp(client) => client.open().await,
        }
    }

    /// Sets how the next requests are made.
    pub fn set_requests(&mut self, requests: Requests) {
        match self {
            Self::Rtu(client) => {
                let config = client.config_mut();
                config.timeout = requests.timeout;
                config.read_retries = requests.retries;
                config.exception = requests.exception;
            }
            #[cfg(feature = "tcp")]
            Self::Tcp(client) => {
                let config = client.config_mut();
                config.timeout = requests.timeout;
                config.read_retries = requests.retries;
                config.exception = requests.exception;
            }
        }
    }
}

impl Transport for Client {
    async fn read_words(&mut self, slave: u8, read: ReadRequest) -> Result<Vec<u16>, Error> {
        match self {
            Self::Rtu(client) => client.read_words(slave, read).await,
            #[cfg(feature = "tcp")]
            Self::Tcp(client) => client.read_words(slave, read).await,
        }
    }

    async fn write(&mut self, slave: u8, address: u16, value: WriteValue) -> Result<(), Error> {
        match self {
            Self::Rtu(client) => client.write(slave, address, value).await,
            #[cfg(feature = "tcp")]
            Self::Tcp(client) => client.write(slave, address, value).await,
        }
    }
}

/// Where a line is, and so how its client is opened.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Port {
    /// A serial port.
    #[cfg(feature = "serial")]
    #[cfg_attr(docsrs, doc(cfg(feature = "serial")))]
    Serial(SerialSettings),
    /// RTU frames over a TCP socket (a serial-to-Ethernet converter): `host:port`.
    #[cfg(feature = "tcp")]
    #[cfg_attr(docsrs, doc(cfg(feature = "tcp")))]
    RtuOverTcp(String),
    /// A Modbus TCP server: `host`, `host:port` or an IP address, with `default_port` where
    /// the address names none.
    #[cfg(feature = "tcp")]
    #[cfg_attr(docsrs, doc(cfg(feature = "tcp")))]
    Tcp {
        /// The server's address, as given.
        address: String,
        /// The port when `address` names none (502, or the device's).
        default_port: u16,
    },
}

/// The settings a port's client starts with, for either protocol.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClientConfig {
    /// For a serial port and RTU over TCP.
    pub rtu: RtuConfig,
    /// For Modbus TCP.
    #[cfg(feature = "tcp")]
    #[cfg_attr(docsrs, doc(cfg(feature = "tcp")))]
    pub tcp: TcpConfig,
}

impl Port {
    /// Opens the port and gives its client, set up with `config`. An RTU port's stream is
    /// handed to `tap` first (e.g. to keep its frames: `|stream| stream` keeps it as it
    /// is). A Modbus TCP client connects on its first request (or [`TcpClient::open`]);
    /// an address that does not resolve is [`Error::Connect`].
    #[cfg_attr(not(any(feature = "serial", feature = "tcp")), allow(unused_variables))]
    pub async fn open(
        &self,
        config: ClientConfig,
        tap: impl FnOnce(Box<dyn Stream>) -> Box<dyn Stream>,
    ) -> Result<Client, Error> {
        match self {
            #[cfg(feature = "serial")]
            Self::Serial(settings) => Ok(Client::rtu(tap(Box::new(settings.open()?)), config.rtu)),
            #[cfg(feature = "tcp")]
            Self::RtuOverTcp(address) => {
                let stream = tokio::net::TcpStream::connect(address.as_str())
                    .await
                    .map_err(|source| Error::Connect {
                        attempts: 1,
                        source,
                    })?;
                // Requests are single small frames: send each at once.
                let _ = stream.set_nodelay(true);
                Ok(Client::rtu(tap(Box::new(stream)), config.rtu))
            }
            #[cfg(feature = "tcp")]
            Self::Tcp {
                address,
                default_port,
            } => {
                let address =
                    crate::tcp::resolve(address, *default_port)
                        .await
                        .map_err(|source| Error::Connect {
                            attempts: 1,
                            source,
                        })?;
                Ok(Client::Tcp(TcpClient::new(address, config.tcp)))
            }
            #[allow(unreachable_patterns)]
            _ => Err(Error::Unsupported("no port kind is built in")),
        }
    }
}
