//! The spec as written: plain structs mirroring `specs/README.md`, read from the parsed tree.
//!
//! Each struct is declared with [`record!`], which also writes its reader: every key is read
//! on its own, so one file's wrong types, missing keys, unknown and repeated keys are all
//! reported at once, each at its line and column. Nothing here is checked beyond the shape
//! of the YAML; `lower` and `rules` judge the content. Some keys (`section` and `note` outside
//! registers) document the spec for its readers and are accepted but not used.
//!
//! Recovery: a value that cannot be read makes the item holding it unreadable. A list of
//! items ([`Items`]: registers, commands, groups, …) or the `enums` mapping ([`Entries`])
//! leaves such an item out and notes its name, so that the rules do not report references
//! to it again; any other container fails with its item. When a top-level key (`device`,
//! `protocol`, …) cannot be read, only the reading errors are reported.
#![allow(dead_code)]

#[macro_use]
mod reader;

use reader::what;
pub(crate) use reader::{At, Entries, FromNode, Items, Reader, RULE};

pub(crate) use crate::model::{
    Access, Addressing, Apply, Effect, ExceptionStyle, LongWrites, Parity, Role, Table,
};
use crate::source::Node;

names! {
    Table { "holding" => Table::Holding, "input" => Table::Input }
    Access { "r" => Access::Read, "rw" => Access::ReadWrite, "w" => Access::Write }
    Addressing { "word" => Addressing::Word, "field" => Addressing::Field }
    Effect {
        "zero" => Effect::Zero,
        "clear_zero" => Effect::ClearZero,
        "reset" => Effect::Reset,
        "save" => Effect::Save,
        "reboot" => Effect::Reboot,
        "factory_reset" => Effect::FactoryReset,
        "network_reset" => Effect::NetworkReset,
        "buffer_lock" => Effect::BufferLock,
        "buffer_unlock" => Effect::BufferUnlock,
        "none" => Effect::None,
    }
    LongWrites { "split" => LongWrites::Split, "wide" => LongWrites::Wide }
    ExceptionStyle {
        "standard" => ExceptionStyle::Standard,
        "counted_word" => ExceptionStyle::CountedWord,
    }
    Apply {
        "immediately" => Apply::Immediately,
        "after_save_and_power_cycle" => Apply::AfterSaveAndPowerCycle,
    }
    TypeName {
        "bool" => TypeName::Bool,
        "u16" => TypeName::U16,
        "i16" => TypeName::I16,
        "u32" => TypeName::U32,
        "i32" => TypeName::I32,
        "enum" => TypeName::Enum,
        "packed" => TypeName::Packed,
        "ipv4" => TypeName::Ipv4,
        "version" => TypeName::Version,
        "record" => TypeName::Record,
    }
    OrderName { "high_first" => OrderName::HighFirst, "low_first" => OrderName::LowFirst }
    Role {
        "firmware_version" => Role::FirmwareVersion,
        "serial_number" => Role::SerialNumber,
    }
}

/// `none`, `odd` or `even`, exactly as the spec schema spells them.
impl FromNode for Parity {
    fn from_node(node: &Node, path: &At<'_>, reader: &mut Reader) -> Option<Self> {
        let text = reader.scalar(node, path, "a name")?;
        match Parity::from_name(text).filter(|parity| parity.name() == text) {
            Some(parity) => Some(parity),
            None => {
                reader.error(
                    node.span,
                    format!(
                        "{}: unknown parity `{text}`, expected one of `none`, `odd`, `even`",
                        what(path)
                    ),
                    "unknown name",
                );
                None
            }
        }
    }
}

/// Reads a whole spec from its root node.
pub(crate) fn read(root: &Node, reader: &mut Reader) -> Option<SpecFile> {
    SpecFile::from_node(root, &At::Root, reader)
}

record! {
    /// A whole spec file.
    pub(crate) struct SpecFile {
        family: String,
        title: String,
        /// Other names the model answers to in tools.
        aliases: Vec<String> = default,
        manual: Manual,
        device: Device,
        protocol: Protocol,
        enums: Entries<EnumDecl> = default,
        registers: Items<RegisterDecl> = default,
        reserved: Items<ReservedDecl> = default,
        commands: Items<CommandDecl> = default,
        groups: Items<GroupDecl> = default,
        repeats: Items<RepeatDecl> = default,
        buffer: Option<BufferDecl>,
    }
}

record! {
    /// A data buffer read out in pages: the names of the items taking part.
    pub(crate) struct BufferDecl {
        section: Option<String>,
        doc: Option<String>,
        source: Option<String>,
        count: String,
        most: u32,
        lock: String,
        unlock: String,
        page: String,
        read_count: String,
        valid_count: String,
        values: String,
        interval: Option<String>,
        ratio: Option<String>,
        note: Option<String>,
    }
}

record! {
    pub(crate) struct Manual {
        file: String,
        version: Option<String>,
        date: Option<String>,
    }
}

record! {
    pub(crate) struct Device {
        transports: Transports,
        slave: SlaveDecl,
        functions: Vec<u8>,
        max_read_words: u16,
        power_up_ms: Option<u32>,
        tables: Tables,
        section: Option<String>,
        note: Option<String>,
    }
}

record! {
    pub(crate) struct Transports {
        rtu: Option<RtuDecl>,
        tcp: Option<TcpDecl>,
    }
}

record! {
    pub(crate) struct RtuDecl {
        default_baud: u32,
        bauds: Vec<u32>,
        parity: Parity,
        data_bits: u8,
        stop_bits: u8,
    }
}

record! {
    pub(crate) struct TcpDecl {
        port: u16,
        default_ip: Option<String>,
    }
}

record! {
    pub(crate) struct SlaveDecl {
        default: u8,
        min: u8,
        max: u8,
    }
}

record! {
    pub(crate) struct Tables {
        holding: u32,
        input: u32,
    }
}

record! {
    pub(crate) struct Protocol {
        addressing: Addressing,
        long_writes: LongWrites,
        exception: ExceptionStyle,
        apply: Apply,
        /// The enum naming the codes the device sends in exception replies.
        exception_codes: Option<String>,
        continuous_send: Option<ContinuousSend>,
        section: Option<String>,
        note: Option<String>,
    }
}

record! {
    pub(crate) struct ContinuousSend {
        register: String,
        code: i64,
    }
}

record! {
    pub(crate) struct EnumDecl {
        doc: Option<String>,
        codes: Vec<CodeDecl>,
        section: Option<String>,
        note: Option<String>,
    }
}

record! {
    pub(crate) struct CodeDecl {
        code: i64,
        name: String,
        meaning: Option<String>,
        doc: Option<String>,
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum OrderName {
    HighFirst,
    LowFirst,
}

record! {
    /// A register, at top level or inside a repeat block.
    pub(crate) struct RegisterDecl {
        name: String,
        table: Table,
        address: u32,
        access: Access,
        "type" => kind: TypeName,
        words: Option<u32>,
        doc: Option<String>,
        zh: Option<String>,
        section: Option<String>,
        /// Kept as written, so that `1e-6` stays exact.
        scale: Option<String>,
        unit: Option<String>,
        range: Option<(i64, i64)>,
        /// The only raw values a write may give (the manual lists them).
        allowed_values: Option<Vec<i64>>,
        "enum" => enum_name: Option<String>,
        codes: Option<Vec<CodeDecl>>,
        sentinel: Option<u64>,
        word_order: Option<OrderName>,
        write_order: Option<OrderName>,
        alias_of: Option<String>,
        read_side_effect: Option<String>,
        /// Writing acts and the manual does not say what a read returns.
        action: bool = default,
        /// What the register is to the device as a whole.
        role: Option<Role>,
        note: Option<String>,
        fields: Option<Vec<FieldDecl>>,
        parts: Option<Vec<String>>,
        /// Only inside a repeat block: this register's own stride.
        stride: Option<u32>,
    }
}

record! {
    /// A bit field of a `packed` register, or a member of a `record`.
    pub(crate) struct FieldDecl {
        name: String,
        lsb: Option<u8>,
        width: Option<u8>,
        "type" => kind: Option<TypeName>,
        "enum" => enum_name: Option<String>,
        codes: Option<Vec<CodeDecl>>,
        range: Option<(i64, i64)>,
        scale: Option<String>,
        unit: Option<String>,
        sentinel: Option<u64>,
        doc: Option<String>,
        note: Option<String>,
    }
}

record! {
    pub(crate) struct ReservedDecl {
        table: Table,
        from: u32,
        to: u32,
        /// Reads may cover the range (an inference the spec cites in `section`).
        readable: bool = default,
        section: Option<String>,
        note: Option<String>,
    }
}

record! {
    pub(crate) struct CommandDecl {
        name: String,
        register: String,
        value: i64,
        busy_ms: Option<u32>,
        effect: Option<Effect>,
        done_when: Option<i64>,
        within_ms: Option<u32>,
        targets: Vec<String> = default,
        doc: Option<String>,
        section: Option<String>,
        note: Option<String>,
    }
}

record! {
    pub(crate) struct GroupDecl {
        name: String,
        doc: Option<String>,
        registers: Vec<String>,
        section: Option<String>,
        note: Option<String>,
    }
}

record! {
    pub(crate) struct RepeatDecl {
        name: String,
        count: u32,
        stride: Stride,
        doc: Option<String>,
        section: Option<String>,
        note: Option<String>,
        registers: Items<RegisterDecl>,
    }
}

record! {
    pub(crate) struct Stride {
        holding: Option<u32>,
        input: Option<u32>,
    }
}
