//! Typed async driver for the LC-RS series distance sensor (Modbus RTU).
//!
//! Everything in this crate except the re-exports is generated at build time from
//! `specs/lc_rs.yaml`, the transcription of the vendor manual: [`LcRs`] has one async
//! method per readable register, one `set_…` per writable one, one per command and one
//! `read_…` per register group; [`DEVICE`] describes the device as data for generic tools.
#![forbid(unsafe_code)]
#![deny(missing_docs)]

include!(concat!(env!("OUT_DIR"), "/lc_rs.rs"));

pub use optobus_driver::{units, Error, Fixed, Transport};
