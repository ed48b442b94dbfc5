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
//! - [`Client`]: either of the two above, opened on a [`Port`] (a serial port, RTU over a
//!   TCP socket, a Modbus TCP server) or on any stream: the one client a bus's lines and a
//!   command-line tool hold.
//! - [`ModbusContext`]: a user's `tokio_modbus::client::Context` (TCP or standard RTU), so an
//!   optobus driver can share a connection with other Modbus devices; see its docs for what it
//!   cannot recover from.
//!
//! Cargo features: `serial` opens serial ports with tokio-serial, `tcp` (default) is the
//! TCP client, `tokio-modbus` the bridge; the RTU client over a stream is always there.
//!
//! Every request has a timeout (a huge one means "wait forever", never an overflow);
//! repeatable reads may be retried, writes and reads with a side effect never are. [`Shared`]
//! serialises transactions of several drivers (several slaves on one port) used from
//! different tasks.
//!
//! Every frame sent and received is a `tracing` event at TRACE, target `optobus_transport`
//! (see [`frames`]): install a subscriber (`RUST_LOG=optobus_transport=trace`) to see them.
#![forbid(unsafe_code)]
#![cfg_attr(docsrs, feature(doc_cfg))]

pub use optobus_codec::{
    DecodeError, EncodeError, ExceptionCode, ExceptionShape, LineFormat, LineFormatError, Parity,
    ReadFunction, WriteValue,
};

mod client;
mod error;
pub mod frames;
#[cfg(feature = "tokio-modbus")]
mod modbus;
mod no_wait;
mod rtu;
mod serial;
mod shared;
mod tap;
#[cfg(feature = "tcp")]
mod tcp;
pub mod timing;
mod transact;
mod transport;

pub use client::{Client, ClientConfig, Port, Requests, Stream};
pub use error::Error;
#[cfg(feature = "tokio-modbus")]
#[cfg_attr(docsrs, doc(cfg(feature = "tokio-modbus")))]
pub use modbus::ModbusContext;
pub use no_wait::nobody_waits;
pub use rtu::{RtuClient, RtuConfig};
pub use serial::SerialSettings;
#[cfg(feature = "serial")]
#[cfg_attr(docsrs, doc(cfg(feature = "serial")))]
pub use serial::SerialStream;
pub use shared::Shared;
pub use tap::{Flow, Observe, Tap};
#[cfg(feature = "tcp")]
#[cfg_attr(docsrs, doc(cfg(feature = "tcp")))]
pub use tcp::{resolve, Connect, TcpClient, TcpConfig};
pub use transport::{ReadRequest, Transport, DEFAULT_TIMEOUT};
