//! Typed async driver for the CCS single-channel spectral confocal sensor.
//!
//! Everything in this crate except the re-exports is generated at build time from
//! `specs/ccs.yaml`, the transcription of the vendor manual: [`Ccs`] has one async
//! method per readable register, one `set_…` per writable one, one per command and one
//! `read_…` per register group; [`DEVICE`] describes the device as data for generic tools.
#![forbid(unsafe_code)]
#![deny(missing_docs)]

include!(concat!(env!("OUT_DIR"), "/ccs.rs"));

pub use optobus_driver::{units, Error, Fixed, Transport};
