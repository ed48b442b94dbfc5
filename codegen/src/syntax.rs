//! The spec as written: serde structs mirroring `specs/README.md`, unknown keys rejected.
//!
//! Nothing here is checked beyond YAML types; `lower` and `rules` judge the content. Some keys
//! (`section` and `note` outside registers) document the spec for its readers and are accepted
//! but not used.
#![allow(dead_code)]

use std::collections::BTreeMap;

use serde::Deserialize;

pub(crate) use crate::model::{
    Access, Addressing, Apply, Effect, ExceptionStyle, LongWrites, Parity, Table,
};

/// A whole spec file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SpecFile {
    pub(crate) family: String,
    pub(crate) title: String,
    /// Other names the model answers to in tools.
    #[serde(default)]
    pub(crate) aliases: Vec<String>,
    pub(crate) manual: Manual,
    pub(crate) device: Device,
    pub(crate) protocol: Protocol,
    #[serde(default)]
    pub(crate) enums: BTreeMap<String, EnumDecl>,
    #[serde(default)]
    pub(crate) registers: Vec<RegisterDecl>,
    #[serde(default)]
    pub(crate) reserved: Vec<ReservedDecl>,
    #[serde(default)]
    pub(crate) commands: Vec<CommandDecl>,
    #[serde(default)]
    pub(crate) groups: Vec<GroupDecl>,
    #[serde(default)]
    pub(crate) repeats: Vec<RepeatDecl>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Manual {
    pub(crate) file: String,
    pub(crate) version: Option<String>,
    pub(crate) date: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Device {
    pub(crate) transports: Transports,
    pub(crate) slave: SlaveDecl,
    pub(crate) functions: Vec<u8>,
    pub(crate) max_read_words: u16,
    pub(crate) power_up_ms: Option<u32>,
    pub(crate) tables: Tables,
    pub(crate) section: Option<String>,
    pub(crate) note: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Transports {
    pub(crate) rtu: Option<RtuDecl>,
    pub(crate) tcp: Option<TcpDecl>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RtuDecl {
    pub(crate) default_baud: u32,
    pub(crate) bauds: Vec<u32>,
    #[serde(deserialize_with = "parity")]
    pub(crate) parity: Parity,
    pub(crate) data_bits: u8,
    pub(crate) stop_bits: u8,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct TcpDecl {
    pub(crate) port: u16,
    pub(crate) default_ip: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SlaveDecl {
    pub(crate) default: u8,
    pub(crate) min: u8,
    pub(crate) max: u8,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Tables {
    pub(crate) holding: u32,
    pub(crate) input: u32,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Protocol {
    pub(crate) addressing: Addressing,
    pub(crate) long_writes: LongWrites,
    pub(crate) exception: ExceptionStyle,
    pub(crate) apply: Apply,
    /// The enum naming the codes the device sends in exception replies.
    pub(crate) exception_codes: Option<String>,
    pub(crate) continuous_send: Option<ContinuousSend>,
    pub(crate) section: Option<String>,
    pub(crate) note: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ContinuousSend {
    pub(crate) register: String,
    pub(crate) code: i64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct EnumDecl {
    pub(crate) doc: Option<String>,
    pub(crate) codes: Vec<CodeDecl>,
    pub(crate) section: Option<String>,
    pub(crate) note: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CodeDecl {
    pub(crate) code: i64,
    pub(crate) name: String,
    pub(crate) meaning: Option<String>,
    pub(crate) doc: Option<String>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum TypeName {
    Bool,
    U16,
    I16,
    U32,
    I32,
    Enum,
    Packed,
    Ipv4,
    Version,
    Record,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum OrderName {
    HighFirst,
    LowFirst,
}

/// A register, at top level or inside a repeat block.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RegisterDecl {
    pub(crate) name: String,
    pub(crate) table: Table,
    pub(crate) address: u32,
    pub(crate) access: Access,
    #[serde(rename = "type")]
    pub(crate) kind: TypeName,
    pub(crate) words: Option<u32>,
    pub(crate) doc: Option<String>,
    pub(crate) zh: Option<String>,
    pub(crate) section: Option<String>,
    /// Read from the source text, so that `1e-6` stays exact.
    pub(crate) scale: Option<serde_yaml::Value>,
    pub(crate) unit: Option<String>,
    pub(crate) range: Option<(i64, i64)>,
    /// The only raw values a write may give (the manual lists them).
    pub(crate) allowed_values: Option<Vec<i64>>,
    #[serde(rename = "enum")]
    pub(crate) enum_name: Option<String>,
    pub(crate) codes: Option<Vec<CodeDecl>>,
    pub(crate) sentinel: Option<u64>,
    pub(crate) word_order: Option<OrderName>,
    pub(crate) write_order: Option<OrderName>,
    pub(crate) alias_of: Option<String>,
    pub(crate) read_side_effect: Option<String>,
    /// Writing acts and the manual defines no read.
    #[serde(default)]
    pub(crate) action: bool,
    pub(crate) note: Option<String>,
    pub(crate) fields: Option<Vec<FieldDecl>>,
    pub(crate) parts: Option<Vec<String>>,
    /// Only inside a repeat block: this register's own stride.
    pub(crate) stride: Option<u32>,
}

/// A bit field of a `packed` register, or a member of a `record`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct FieldDecl {
    pub(crate) name: String,
    pub(crate) lsb: Option<u8>,
    pub(crate) width: Option<u8>,
    #[serde(rename = "type")]
    pub(crate) kind: Option<TypeName>,
    #[serde(rename = "enum")]
    pub(crate) enum_name: Option<String>,
    pub(crate) codes: Option<Vec<CodeDecl>>,
    pub(crate) range: Option<(i64, i64)>,
    pub(crate) scale: Option<serde_yaml::Value>,
    pub(crate) unit: Option<String>,
    pub(crate) sentinel: Option<u64>,
    pub(crate) doc: Option<String>,
    pub(crate) note: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ReservedDecl {
    pub(crate) table: Table,
    pub(crate) from: u32,
    pub(crate) to: u32,
    /// The manual sanctions reading the range.
    #[serde(default)]
    pub(crate) readable: bool,
    pub(crate) section: Option<String>,
    pub(crate) note: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct CommandDecl {
    pub(crate) name: String,
    pub(crate) register: String,
    pub(crate) value: i64,
    pub(crate) busy_ms: Option<u32>,
    pub(crate) effect: Option<Effect>,
    #[serde(default)]
    pub(crate) targets: Vec<String>,
    pub(crate) doc: Option<String>,
    pub(crate) section: Option<String>,
    pub(crate) note: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct GroupDecl {
    pub(crate) name: String,
    pub(crate) doc: Option<String>,
    pub(crate) registers: Vec<String>,
    pub(crate) section: Option<String>,
    pub(crate) note: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RepeatDecl {
    pub(crate) name: String,
    pub(crate) count: u32,
    pub(crate) stride: Stride,
    pub(crate) doc: Option<String>,
    pub(crate) section: Option<String>,
    pub(crate) note: Option<String>,
    pub(crate) registers: Vec<RegisterDecl>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Stride {
    pub(crate) holding: Option<u32>,
    pub(crate) input: Option<u32>,
}

/// `none`, `odd` or `even`, exactly as the spec schema spells them.
fn parity<'de, D: serde::Deserializer<'de>>(deserializer: D) -> Result<Parity, D::Error> {
    const NAMES: &[&str] = &["none", "odd", "even"];
    let name = String::deserialize(deserializer)?;
    Parity::from_name(&name)
        .filter(|parity| parity.name() == name)
        .ok_or_else(|| serde::de::Error::unknown_variant(&name, NAMES))
}
