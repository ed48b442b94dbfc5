//! Frames as data: how bytes are framed, what kind of frame they are, every field with its
//! meaning, the CRC check, the registers a frame carries, and the text `optobus frame decode`
//! prints.

use std::fmt;

use optobus_device::{RegisterInfo, Table};
use serde::ser::{SerializeStruct, Serializer};
use serde::Serialize;

use crate::hex::hex;
use crate::value::Value;

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
    pub(crate) fn new(bytes: &[u8], meaning: impl Into<String>) -> Self {
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
    pub(crate) fn new(
        register: &'static RegisterInfo,
        words: &[u16],
        value: Option<Value>,
    ) -> Self {
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

pub(crate) fn serialize_hex<S: Serializer>(bytes: &[u8], serializer: S) -> Result<S::Ok, S::Error> {
    serializer.serialize_str(&hex(bytes))
}

fn serialize_words<S: Serializer>(words: &[u16], serializer: S) -> Result<S::Ok, S::Error> {
    serializer.collect_seq(words.iter().map(|w| format!("0x{w:04X}")))
}

fn serialize_table<S: Serializer>(table: &Table, serializer: S) -> Result<S::Ok, S::Error> {
    serializer.serialize_str(table.as_str())
}
