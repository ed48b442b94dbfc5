//! The runtime form of an optobus spec.
//!
//! `optobus-codegen` emits, for each family, one `static DEVICE: DeviceInfo` built from these
//! types: every register with its table, address, width, access, value type, scale, unit,
//! range or codes and sentinel; the commands, groups, reserved ranges and protocol quirks. The
//! typed driver API is generated separately; this description is what generic tools (the
//! simulator engine, the command-line tool) read. No I/O, no allocator.
#![no_std]
#![forbid(unsafe_code)]

mod check;
mod description;
mod duration;
mod register;
mod words;

pub use check::Invalid;
pub use description::*;
pub use duration::parse_duration;
pub use optobus_codec::value::{Scale, WordOrder, WriteOrder};
pub use optobus_codec::{ExceptionShape, FrameShape, Parity, ReadFunction};
pub use register::*;
pub use words::RawWords;
