//! Typed async driver for the P series (TS-LTP-E) laser displacement sensor.
//!
//! Everything in this crate except the re-exports is generated at build time from
//! `specs/p_series.yaml`, the transcription of the vendor manual: [`PSeries`] has one async
//! method per readable register, one `set_…` per writable one, one per command and one
//! `read_…` per register group; [`DEVICE`] describes the device as data for generic tools.
#![forbid(unsafe_code)]
#![deny(missing_docs)]

include!(concat!(env!("OUT_DIR"), "/p_series.rs"));

pub mod download;

pub use optobus_driver::{units, Error, Fixed, Transport};
