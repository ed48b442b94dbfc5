//! The golden frames: every example frame printed in the five manuals, as data.

use std::fmt;
use std::path::{Path, PathBuf};

use optobus_codec::{ExceptionShape, ReadFunction, Request, WriteValue};
use optobus_spec::source::{Node, SourceFile, Value};
use serde::{Deserialize, Deserializer};

/// The directory holding the golden YAML files.
pub fn directory() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("golden")
}

/// One manual's golden frames.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GoldenFile {
    /// The manual's file name in `shared/manuals`.
    pub manual: String,
    /// The sensor family.
    pub family: String,
    /// How the device frames exception replies.
    pub exception_shape: ShapeName,
    /// The frames, in the manual's order.
    pub frames: Vec<Entry>,
}

/// Loads `tests/golden/<family>.yaml`.
pub fn load(family: &str) -> Result<GoldenFile, String> {
    let path = directory().join(format!("{family}.yaml"));
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    // The parser the specs and bus files are read with, so the golden files obey the same YAML.
    let source = SourceFile::new(path.display().to_string(), text);
    if let Some(error) = &source.syntax_error {
        return Err(format!(
            "{}:{}:{}: {}",
            path.display(),
            error.line,
            error.column,
            error.message
        ));
    }
    let root = source
        .root
        .as_ref()
        .ok_or_else(|| format!("{}: empty", path.display()))?;
    serde_json::from_value(json(root)?).map_err(|e| format!("{}: {e}", path.display()))
}

/// The YAML tree as JSON, so that the serde types above read it: plain scalars follow YAML
/// 1.2's core schema (null, booleans, decimal, `0x`, `0o` and `0b` integers, decimals).
fn json(node: &Node) -> Result<serde_json::Value, String> {
    Ok(match &node.value {
        Value::Scalar { text, plain: false } => serde_json::Value::String(text.to_string()),
        Value::Scalar { .. } if node.is_null() => serde_json::Value::Null,
        Value::Scalar { text, .. } => plain_scalar(text),
        Value::Sequence(items) => items
            .iter()
            .map(json)
            .collect::<Result<Vec<_>, _>>()?
            .into(),
        Value::Mapping(entries) => {
            let mut map = serde_json::Map::new();
            for (key, value) in entries {
                let key = key
                    .text()
                    .ok_or_else(|| format!("line {}: a key that is not text", key.span.line))?;
                map.insert(key.to_owned(), json(value)?);
            }
            map.into()
        }
    })
}

fn plain_scalar(text: &str) -> serde_json::Value {
    let radix = |prefix: &str, radix: u32| {
        let digits = text.strip_prefix(prefix)?;
        i64::from_str_radix(digits, radix).ok()
    };
    match text {
        "true" | "True" | "TRUE" => true.into(),
        "false" | "False" | "FALSE" => false.into(),
        _ => text
            .parse::<i64>()
            .ok()
            .or_else(|| radix("0x", 16))
            .or_else(|| radix("0o", 8))
            .or_else(|| radix("0b", 2))
            .map(serde_json::Value::from)
            .or_else(|| {
                let decimal = text
                    .parse::<f64>()
                    .ok()
                    .filter(|_| text.contains(['.', 'e', 'E']));
                decimal.map(serde_json::Value::from)
            })
            .unwrap_or_else(|| text.into()),
    }
}

/// Exception frame shape names used in the files.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ShapeName {
    /// One-byte code.
    Standard,
    /// Byte count 2 and a 16-bit code.
    CountedWord,
}

impl From<ShapeName> for ExceptionShape {
    fn from(name: ShapeName) -> Self {
        match name {
            ShapeName::Standard => Self::Standard,
            ShapeName::CountedWord => Self::CountedWord,
        }
    }
}

/// RTU or TCP.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Transport {
    /// Modbus RTU (with CRC).
    Rtu,
    /// Modbus TCP (MBAP header).
    Tcp,
}

/// Who sends the frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Direction {
    /// Master to device.
    Request,
    /// Device to master.
    Response,
}

/// Whether the manual prints the frame or only a template we completed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Origin {
    /// Completed from the manual's template and tables.
    Derived,
}

/// Hex bytes written as `"01 03 00 00"`.
#[derive(Clone, PartialEq, Eq)]
pub struct Hex(pub Vec<u8>);

impl fmt::Debug for Hex {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let text: Vec<String> = self.0.iter().map(|b| format!("{b:02X}")).collect();
        write!(f, "\"{}\"", text.join(" "))
    }
}

impl<'de> Deserialize<'de> for Hex {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let text = String::deserialize(deserializer)?;
        text.split_whitespace()
            .map(|pair| u8::from_str_radix(pair, 16).map_err(serde::de::Error::custom))
            .collect::<Result<Vec<u8>, _>>()
            .map(Hex)
    }
}

/// One frame from a manual.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Entry {
    /// Unique id.
    pub id: String,
    /// Manual section.
    pub section: String,
    /// RTU or TCP.
    pub transport: Transport,
    /// Request or response.
    pub direction: Direction,
    /// The correct frame.
    pub bytes: Hex,
    /// Slave address or unit id.
    pub slave: u8,
    /// TCP transaction id.
    pub transaction: Option<u16>,
    /// A read request.
    pub read: Option<ReadPdu>,
    /// A write request.
    pub write: Option<WritePdu>,
    /// A read reply.
    pub words: Option<WordsPdu>,
    /// A write reply.
    pub echo: Option<WritePdu>,
    /// An exception reply.
    pub exception: Option<ExceptionPdu>,
    /// For responses: the request in flight.
    pub request: Option<RequestSpec>,
    /// What the manual's text says the data means.
    #[serde(default)]
    pub values: Vec<ValueSpec>,
    /// What the manual printed, when it is wrong.
    pub printed: Option<Hex>,
    /// Errata and remarks.
    pub note: Option<String>,
    /// Set when the frame was completed from a template.
    pub origin: Option<Origin>,
}

/// `read:`.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReadPdu {
    /// 3 or 4.
    pub function: u8,
    /// First register.
    pub address: u16,
    /// Words.
    pub count: u16,
}

/// `write:` and `echo:`.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WritePdu {
    /// Register.
    pub address: u16,
    /// Value.
    pub value: u32,
    /// 2 or 4 data bytes.
    pub width: u8,
}

/// `words:`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WordsPdu {
    /// 3 or 4.
    pub function: u8,
    /// The words.
    pub values: Vec<u16>,
}

/// `exception:`.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExceptionPdu {
    /// The request's function code.
    pub function: u8,
    /// The exception code.
    pub code: u16,
}

/// `request:` of a response.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RequestSpec {
    /// A read.
    pub read: Option<ReadPdu>,
    /// A write.
    pub write: Option<WritePdu>,
}

/// One entry of `values:`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ValueSpec {
    /// What it is.
    pub what: String,
    /// Index of the first word.
    #[serde(default)]
    pub word: usize,
    /// The codec.
    #[serde(rename = "type")]
    pub kind: ValueType,
    /// Word order of 32-bit values.
    pub word_order: Option<WordOrderName>,
    /// The integer the text gives.
    pub raw: i64,
    /// The step, `1e-6` or `1/1048576`.
    pub scale: Option<String>,
    /// The exact decimal in engineering units.
    pub text: Option<String>,
    /// The manual calls this reading invalid.
    #[serde(default)]
    pub sentinel: bool,
}

/// `type:` of a value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ValueType {
    /// One word, unsigned.
    U16,
    /// One word, signed.
    I16,
    /// Two words, unsigned.
    U32,
    /// Two words, signed.
    I32,
    /// High byte of a word.
    U8High,
    /// Low byte of a word.
    U8Low,
    /// The 4-byte payload of a wide FC06.
    U32Bytes,
}

/// `word_order:`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WordOrderName {
    /// High word at the lower index.
    HighFirst,
    /// Low word at the lower index.
    LowFirst,
}

impl ReadPdu {
    /// As a codec request.
    pub fn to_request(self) -> Result<Request, String> {
        let function = ReadFunction::from_code(self.function)
            .ok_or_else(|| format!("function {} is not a read", self.function))?;
        Ok(Request::Read {
            function,
            address: self.address,
            count: self.count,
        })
    }
}

impl WritePdu {
    /// The value with its payload width.
    pub fn to_value(self) -> Result<WriteValue, String> {
        match self.width {
            2 => u16::try_from(self.value)
                .map(WriteValue::Word)
                .map_err(|_| format!("value {:#X} does not fit 2 bytes", self.value)),
            4 => Ok(WriteValue::DoubleWord(self.value)),
            other => Err(format!("width {other} is neither 2 nor 4")),
        }
    }

    /// As a codec request.
    pub fn to_request(self) -> Result<Request, String> {
        Ok(Request::Write {
            address: self.address,
            value: self.to_value()?,
        })
    }
}

impl RequestSpec {
    /// As a codec request.
    pub fn to_request(self) -> Result<Request, String> {
        match (self.read, self.write) {
            (Some(read), None) => read.to_request(),
            (None, Some(write)) => write.to_request(),
            _ => Err("request: needs exactly one of read / write".into()),
        }
    }
}
