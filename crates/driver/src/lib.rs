//! The runtime under every generated optobus driver.
//!
//! `optobus-codegen` turns a spec into a typed driver (`Ccs<T>`, `Ccf<T>`, …) whose methods
//! are thin: each names its register's [`RegisterInfo`] in the generated `DEVICE` table and
//! the Rust type of its value. Everything else happens here, once for all families:
//!
//! - [`Core`] reads a register or a group (merging adjacent registers into the fewest reads,
//!   split at the device's maximum, and reading around reserved ranges for a device that
//!   refuses them, remembered in its [`DeviceMemory`]), writes one register (two words in the spec's write
//!   order, or the rangefinder's 4-byte FC06), runs commands and waits out their busy time,
//!   and downloads a data buffer page by page where the spec describes one.
//! - [`Decode`] and [`Encode`] turn words into typed values and back; every write is
//!   validated (range, defined codes, fits its bits, exactly representable) before a byte is
//!   sent.
//! - [`identify`] finds which model a device is, from each candidate spec's fingerprint
//!   (its registers, its table bounds, its stored settings), with read-only requests.
//! - [`units`] holds the exact fixed-point quantities readings come in (`Millimetres`, …).
//!
//! Register reads and writes are `tracing` events at DEBUG, target `optobus_driver` (register
//! name, words, decoded value); the transport's frames are at TRACE, target
//! `optobus_transport`.
//!
//! Nothing here knows about sockets: the bytes go through an [`optobus_transport::Transport`].
#![forbid(unsafe_code)]
#![cfg_attr(docsrs, feature(doc_cfg))]

mod address;
#[cfg(feature = "serde")]
pub mod array_serde;
mod buffer;
mod buffer_request;
#[cfg(feature = "serde")]
pub mod code_serde;
mod connect;
mod convert;
mod core;
mod error;
pub mod identify;
mod memory;
mod plan;
pub mod scan;
#[cfg(feature = "serde")]
pub mod shapes;
pub mod units;

pub use crate::address::{address_change, AddressChange};
pub use crate::buffer::{BufferTiming, DownloadProgress};
pub use crate::buffer_request::{BufferRefusal, BufferRequest, BufferSource};
#[cfg(feature = "tcp")]
#[cfg_attr(docsrs, doc(cfg(feature = "tcp")))]
pub use crate::connect::tcp_config;
pub use crate::connect::{line_format, rtu_config, serial_settings};
pub use crate::core::{
    CommandWait, Core, Finish, PartialRead, Readings, COMPLETION_POLL, TRACE_TARGET,
};
pub use convert::{
    encode_code, encode_integer, encode_packed, raw_bits, word_array, CodeEnum, Decode, Encode,
    RawValue,
};
pub use error::{Error, ErrorKind};
pub use memory::DeviceMemory;
pub use optobus_codec::value::{Fixed, ParseFixedError, Scale};
pub use optobus_device::{BufferInfo, CommandInfo, DeviceInfo, GroupInfo, RegisterInfo};
pub use optobus_transport::{self as transport, Transport};
pub use plan::{
    plan_reads, plan_reads_bridging, plan_write, Bridging, ReadSpan, WritePart, WriteStep,
};
