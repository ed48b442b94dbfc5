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
mod explain;
mod hex;
mod layout;
mod parse;
mod resolve;
mod value;

use std::fmt;

use optobus_device::{RegisterInfo, Table};
use serde::ser::{SerializeStruct, Serializer};
use serde::Serialize;

pub use decode::decode;
pub use encode::{encode_read, encode_read_of, encode_write, encode_write_of, EncodedFrame};
pub use hex::{hex, parse_hex, HexError};
pub use optobus_codec::EncodeError;
pub use parse::{code_list, parse_value, ParseError};
pub use resolve::{resolve, resolve_one, resolve_readable, ResolveError};
pub use value::{decode_value, range_text, Value};

/// RTU (slave, PDU, CRC) or Modbus TCP (MBAP header, PDU).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Framing {
    /// Modbus RTU.
    Rtu,
    /// Modbus TCP.
    Tcp,
}

/// What a decoded frame is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FrameKind {
    /// An FC03/FC04 request.
    ReadRequest,
    /// An FC03/FC04 reply.
    ReadReply,
    /// An FC06 request (or an echo without its request before it).
    Write,
    /// The echo of the FC06 request before it.
    WriteEcho,
    /// An exception reply.
    Exception,
    /// A function not decoded further.
    Other,
    /// Bytes left over after the frames before them.
    Undecoded,
}

/// Some bytes of a frame and what they mean.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Field {
    /// The bytes (JSON: `hex`).
    #[serde(rename = "hex", serialize_with = "serialize_hex")]
    pub bytes: Vec<u8>,
    /// What they mean, in words.
    pub meaning: String,
}

impl Field {
    fn new(bytes: &[u8], meaning: impl Into<String>) -> Self {
        Self {
            bytes: bytes.to_vec(),
            meaning: meaning.into(),
        }
    }
}

/// An RTU CRC: what the frame carries and what its bytes give.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CrcCheck {
    /// The CRC the frame carries.
    pub received: u16,
    /// The CRC of the frame's other bytes.
    pub computed: u16,
}

impl CrcCheck {
    /// Whether the frame's CRC is right.
    pub const fn ok(&self) -> bool {
        self.received == self.computed
    }
}

/// `{"ok", "received", "expected"}`, the CRCs in wire order as hex.
impl Serialize for CrcCheck {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut crc = serializer.serialize_struct("CrcCheck", 3)?;
        crc.serialize_field("ok", &self.ok())?;
        crc.serialize_field("received", &hex(&self.received.to_le_bytes()))?;
        crc.serialize_field("expected", &hex(&self.computed.to_le_bytes()))?;
        crc.end()
    }
}

/// A register a frame reads or writes, with its words and value where the frame has them.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RegisterValue {
    /// Register name.
    pub name: &'static str,
    /// Its table.
    #[serde(serialize_with = "serialize_table")]
    pub table: Table,
    /// Its first address.
    pub address: u16,
    /// The words the frame carries for it (JSON: `0x0036` strings).
    #[serde(serialize_with = "serialize_words")]
    pub words: Vec<u16>,
    /// The decoded value, when the frame carries the whole register.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value: Option<Value>,
    /// The value as text.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub text: Option<String>,
    /// Which part of the register a write carries (`low word`), when not all of it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub part: Option<String>,
}

impl RegisterValue {
    fn new(register: &'static RegisterInfo, words: &[u16], value: Option<Value>) -> Self {
        Self {
            name: register.name,
            table: register.table,
            address: register.address,
            words: words.to_vec(),
            text: value.as_ref().map(Value::to_string),
            value,
            part: None,
        }
    }
}

/// One frame explained.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ExplainedFrame {
    /// The frame's bytes (JSON: `hex`).
    #[serde(rename = "hex", serialize_with = "serialize_hex")]
    pub bytes: Vec<u8>,
    /// What the frame is.
    pub kind: FrameKind,
    /// One line saying what it does (JSON: `description`).
    #[serde(rename = "description")]
    pub summary: String,
    /// Every field, in wire order.
    pub fields: Vec<Field>,
    /// The CRC check (RTU only).
    pub crc: Option<CrcCheck>,
    /// The registers it reads or writes.
    pub registers: Vec<RegisterValue>,
    /// What a device would make of it, where that is worth saying.
    pub notes: Vec<String>,
}

/// The summary, then every field's bytes and meaning in aligned columns (long data on a line
/// of its own), then the notes; no final newline. What `optobus frame decode` prints.
impl fmt::Display for ExplainedFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Wider fields (long data) go on their own line rather than pushing every meaning right.
        const MAX_COLUMN: usize = 23;
        f.write_str(&self.summary)?;
        if self.fields.is_empty() {
            write!(f, "\n  {}", hex(&self.bytes))?;
        }
        let column = self
            .fields
            .iter()
            .map(|field| hex(&field.bytes).len())
            .filter(|&len| len <= MAX_COLUMN)
            .max()
            .unwrap_or(2);
        for field in &self.fields {
            let bytes = hex(&field.bytes);
            if bytes.len() > column {
                write!(f, "\n  {bytes}\n  {:column$}  {}", "", field.meaning)?;
            } else {
                write!(f, "\n  {bytes:column$}  {}", field.meaning)?;
            }
        }
        for note in &self.notes {
            write!(f, "\n  note: {note}")?;
        }
        Ok(())
    }
}

/// Why bytes could not be decoded, or a name or value not encoded, in a line for people.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Error {
    /// What is wrong.
    pub message: String,
    /// What to try instead, if anything.
    pub hint: Option<String>,
}

impl Error {
    fn new(message: impl Into<String>) -> Self {
        Self {
            message: message.into(),
            hint: None,
        }
    }

    fn hint(mut self, hint: impl Into<String>) -> Self {
        self.hint = Some(hint.into());
        self
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Error {}

fn serialize_hex<S: Serializer>(bytes: &[u8], serializer: S) -> Result<S::Ok, S::Error> {
    serializer.serialize_str(&hex(bytes))
}

fn serialize_words<S: Serializer>(words: &[u16], serializer: S) -> Result<S::Ok, S::Error> {
    serializer.collect_seq(words.iter().map(|w| format!("0x{w:04X}")))
}

fn serialize_table<S: Serializer>(table: &Table, serializer: S) -> Result<S::Ok, S::Error> {
    serializer.serialize_str(table.as_str())
}
