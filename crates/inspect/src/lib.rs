//! Modbus frames of any optobus device, explained: what `optobus frame` prints, as a library a
//! PLC tool or a bus sniffer can reuse.
//!
//! - [`encode_read`] and [`encode_write`] give the exact request frames (RTU or Modbus TCP)
//!   the drivers send, from the driver's own read and write plans
//!   ([`optobus_driver::plan_reads`], [`optobus_driver::plan_write`]), each with a
//!   description.
//! - [`decode`] explains any byte string leniently: the frames in it (candidate lengths from
//!   the codec, a good CRC deciding), every field, the CRC checked, registers named, values
//!   decoded ([`Value`]), exception codes with the meanings the spec gives, and notes on
//!   anything a device would refuse. It never panics, whatever the bytes. An
//!   [`ExplainedFrame`] displays as the text `optobus frame decode` prints.
//! - [`near`] and [`did_you_mean`] find the names near a misspelt one, for every message that
//!   refuses a name.
//! - [`parse_number`] reads a 16-bit address or raw word in decimal or `0x` hex;
//!   [`hex_and_decimal`] writes one back as `0x0010 (16)`.
//! - [`parse_hex`] reads bytes written in hex however a capture or a person writes them;
//!   [`hex`] writes them back as `01 04 0C`.
//! - [`resolve`] finds the registers a name stands for (a register, a repeat member and its
//!   copies, a group); [`parse_value`] turns a value as people type it (`100us`, `42.5`, a
//!   code's name or the manual's words for it, `name=value` fields) into the register's
//!   validated words, refused with a one-line [`ParseError`] as the driver would refuse it;
//!   [`decode_value`] turns words back into a [`Value`].
//!
//! Everything works from a device description (`DEVICE` of a family crate), and every result
//! is plain data that serialises (with `serde`) to the JSON `optobus frame --json` prints.

mod decode;
mod encode;
mod error;
mod explain;
mod frame;
mod hex;
mod layout;
mod near;
mod number;
mod parse;
mod resolve;
mod value;

pub use decode::decode;
pub use encode::{encode_read, encode_read_of, encode_write, encode_write_of, EncodedFrame};
pub use error::Error;
pub use frame::{CrcCheck, ExplainedFrame, Field, FrameKind, Framing, RegisterValue};
pub use hex::{hex, parse_hex, HexError};
pub use near::{did_you_mean, near};
pub use number::{hex_and_decimal, parse_number};
pub use optobus_codec::EncodeError;
pub use parse::{base_unit, code_list, in_base_unit, parse_value, ParseError};
pub use resolve::{resolve, resolve_one, resolve_readable, ResolveError};
pub use value::{
    accepted_values_text, decode_readings, decode_value, decode_values, range_text, values_text,
    Value,
};
