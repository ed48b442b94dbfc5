//! Typed async driver for the CCS single-channel spectral confocal sensor.
//!
//! The driver is generated at build time from `specs/ccs.yaml`, the transcription of the
//! vendor manual: [`Ccs`] has one async method per readable register, one `set_…` per
//! writable one, one per command and one `read_…` per register group; [`DEVICE`] describes
//! the device as data for generic tools.
//!
//! A driver wraps any [`Transport`]: our RTU client on a serial port (settings from the
//! manual's defaults), our Modbus TCP client, an existing `tokio_modbus` context, or, as
//! here, an in-memory line to the simulator generated from the same spec. The example needs
//! these dependencies:
//!
//! ```toml
//! [dependencies]
//! optobus-ccs = "0.1"
//! optobus-simulator = "0.1"   # the simulated sensor; not needed for a real one
//! tokio = { version = "1", features = ["rt", "macros"] }
//! ```
//!
//! ```
//! # #[tokio::main(flavor = "current_thread")]
//! # async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use optobus_ccs::transport::RtuClient;
//! use optobus_ccs::{Ccs, DEVICE};
//!
//! let sim = optobus_simulator::Simulator::new(&DEVICE);
//! let (line, _server) = sim.duplex();
//! // A real sensor: `optobus_ccs::serial_settings(&DEVICE, "/dev/ttyUSB0").open()?` (feature `serial`).
//! let client = RtuClient::with_config(line, optobus_ccs::rtu_config(&DEVICE));
//! let mut sensor = Ccs::with_default_slave(client);
//! let readings = sensor.read_measurements().await?;
//! println!("{readings:?}");
//! # Ok(())
//! # }
//! ```
//!
//! For a real sensor, leave out `optobus-simulator` and open its line instead:
//!
//! - a serial port: `optobus-ccs = { version = "0.1", features = ["serial"] }`, then
//!   `serial_settings(&DEVICE, "/dev/ttyUSB0").open()?` (the manual's factory baud, parity and
//!   format; change its `line` for a device configured otherwise) in place of `line` above;
//! - Modbus TCP (feature `tcp`, on by default): `transport::TcpClient::new(address,
//!   tcp_config(&DEVICE))` in place of the RTU client (`address` a `SocketAddr`; the client
//!   connects at the first request and reconnects after a broken stream).
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(docsrs, feature(doc_cfg))]

// The driver, its types, `DEVICE` and the runtime items the crate re-exports.
include!(concat!(env!("OUT_DIR"), "/ccs.rs"));

/// Settings for our Modbus TCP client to this device (feature `tcp`).
#[cfg(feature = "tcp")]
#[cfg_attr(docsrs, doc(cfg(feature = "tcp")))]
#[doc(inline)]
pub use optobus_driver::tcp_config;
