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

use std::collections::BTreeMap;

use crate::diagnostic::{Diagnostic, Label, Location};
pub(crate) use crate::model::{
    Access, Addressing, Apply, Effect, ExceptionStyle, LongWrites, Parity, Table,
};
use crate::source::{Node, Path, Span, Value};

/// Rule name of every reading error.
pub(crate) const RULE: &str = "yaml";

const HELP: &str = "see specs/README.md for the keys and forms a spec takes";

/// Collects the reading errors of one file.
#[derive(Default)]
pub(crate) struct Reader {
    pub(crate) diagnostics: Vec<Diagnostic>,
}

impl Reader {
    fn error(&mut self, span: Span, message: String, label: impl Into<String>) {
        self.diagnostics.push(Diagnostic {
            rule: RULE,
            message,
            primary: Label {
                location: Location::Span(span),
                text: label.into(),
            },
            secondary: Vec::new(),
            help: Some(HELP.into()),
        });
    }

    /// `node` as a mapping of the given keys: unknown and repeated keys are reported (and
    /// otherwise ignored).
    fn mapping<'n>(&mut self, node: &'n Node, path: &Path, keys: &[&str]) -> Option<Mapping<'n>> {
        let Value::Mapping(entries) = &node.value else {
            self.error(
                node.span,
                format!("{} must be a mapping, not {}", what(path), node.kind()),
                "expected `key: value` lines or `{key: value, …}`",
            );
            return None;
        };
        let mut found: BTreeMap<&str, (&Node, &Node)> = BTreeMap::new();
        for (key, value) in entries {
            let Some(name) = key.text().filter(|_| !key.is_null()) else {
                self.error(
                    key.span,
                    format!("{} has a key that is not a name", what(path)),
                    "expected a name",
                );
                continue;
            };
            if !keys.contains(&name) {
                let mut diagnostic = Diagnostic {
                    rule: RULE,
                    message: format!("{} has an unknown key `{name}`", what(path)),
                    primary: Label {
                        location: Location::Span(key.span),
                        text: "unknown key".into(),
                    },
                    secondary: Vec::new(),
                    help: None,
                };
                diagnostic.help = Some(format!("expected one of: {}", keys.join(", ")));
                self.diagnostics.push(diagnostic);
                continue;
            }
            if let Some((first, _)) = found.get(name) {
                let first = first.span;
                self.diagnostics.push(Diagnostic {
                    rule: RULE,
                    message: format!("{} has `{name}` twice", what(path)),
                    primary: Label {
                        location: Location::Span(key.span),
                        text: "repeated key".into(),
                    },
                    secondary: vec![Label {
                        location: Location::Span(first),
                        text: "first given here".into(),
                    }],
                    help: Some("keep one of them".into()),
                });
                continue;
            }
            found.insert(name, (key, value));
        }
        Some(Mapping {
            node,
            entries: found,
        })
    }

    /// Reads `key` of `map`: absent keys take `T::absent()` or are reported missing.
    pub(crate) fn field<T: FromNode>(
        &mut self,
        map: &Mapping<'_>,
        path: &Path,
        key: &str,
    ) -> Option<T> {
        match map.entries.get(key) {
            Some((_, value)) => T::from_node(value, &path.key(key), self),
            None => T::absent().or_else(|| {
                // Point into the mapping at its first key: a block mapping has no mark of its own.
                let at = match &map.node.value {
                    Value::Mapping(entries) => {
                        entries.first().map_or(map.node.span, |(k, _)| k.span)
                    }
                    _ => map.node.span,
                };
                self.error(
                    at,
                    format!("{} has no `{key}`", what(path)),
                    format!("add `{key}:`"),
                );
                None
            }),
        }
    }

    /// Reads `key` of `map`, or `T::default()` when it is absent or null.
    pub(crate) fn field_or_default<T: FromNode + Default>(
        &mut self,
        map: &Mapping<'_>,
        path: &Path,
        key: &str,
    ) -> Option<T> {
        match map.entries.get(key) {
            Some((_, value)) if !value.is_null() => T::from_node(value, &path.key(key), self),
            _ => Some(T::default()),
        }
    }

    /// The text of a scalar, or a report that `node` is not one.
    fn scalar<'n>(&mut self, node: &'n Node, path: &Path, expected: &str) -> Option<&'n str> {
        match &node.value {
            Value::Scalar { text, .. } if !node.is_null() => Some(text),
            _ => {
                self.error(
                    node.span,
                    format!("{} must be {expected}, not {}", what(path), node.kind()),
                    format!("expected {expected}"),
                );
                None
            }
        }
    }
}

/// How a path is named in messages.
fn what(path: &Path) -> String {
    if path.0.is_empty() {
        "the spec".into()
    } else {
        format!("`{path}`")
    }
}

/// A mapping's entries by key (first occurrence).
pub(crate) struct Mapping<'n> {
    node: &'n Node,
    entries: BTreeMap<&'n str, (&'n Node, &'n Node)>,
}

/// A value read from a node of the tree.
pub(crate) trait FromNode: Sized {
    /// Reads `node` (at `path`), reporting every problem to `reader`; `None` when it cannot
    /// be read.
    fn from_node(node: &Node, path: &Path, reader: &mut Reader) -> Option<Self>;

    /// The value of an absent key; `None` makes the key required.
    fn absent() -> Option<Self> {
        None
    }
}

impl<T: FromNode> FromNode for Option<T> {
    fn from_node(node: &Node, path: &Path, reader: &mut Reader) -> Option<Self> {
        if node.is_null() {
            return Some(None);
        }
        T::from_node(node, path, reader).map(Some)
    }

    fn absent() -> Option<Self> {
        Some(None)
    }
}

impl FromNode for String {
    fn from_node(node: &Node, path: &Path, reader: &mut Reader) -> Option<Self> {
        reader.scalar(node, path, "text").map(str::to_owned)
    }
}

/// Reads a plain integer: decimal, `0x…`, `0o…` or `0b…`, optionally signed.
fn parse_integer(text: &str) -> Option<i128> {
    let (negative, digits) = match text.as_bytes().first() {
        Some(b'-') => (true, &text[1..]),
        Some(b'+') => (false, &text[1..]),
        _ => (false, text),
    };
    let (radix, digits) = match digits.get(..2) {
        Some("0x") => (16, &digits[2..]),
        Some("0o") => (8, &digits[2..]),
        Some("0b") => (2, &digits[2..]),
        _ => (10, digits),
    };
    if digits.is_empty() || !digits.chars().all(|c| c.is_digit(radix)) {
        return None;
    }
    let magnitude = i128::from_str_radix(digits, radix).ok()?;
    Some(if negative { -magnitude } else { magnitude })
}

macro_rules! integers {
    ($($ty:ty),*) => {$(
        impl FromNode for $ty {
            fn from_node(node: &Node, path: &Path, reader: &mut Reader) -> Option<Self> {
                let text = reader.scalar(node, path, "an integer")?;
                let plain = matches!(node.value, Value::Scalar { plain: true, .. });
                let Some(value) = parse_integer(text).filter(|_| plain) else {
                    reader.error(
                        node.span,
                        format!("{} must be an integer, not `{text}`", what(path)),
                        "expected an integer (decimal or 0x…)",
                    );
                    return None;
                };
                match <$ty>::try_from(value) {
                    Ok(value) => Some(value),
                    Err(_) => {
                        reader.error(
                            node.span,
                            format!(
                                "{} is {text}, outside {}..={}",
                                what(path),
                                <$ty>::MIN,
                                <$ty>::MAX
                            ),
                            "out of range",
                        );
                        None
                    }
                }
            }
        }
    )*};
}

integers!(u8, u16, u32, u64, i64);

impl FromNode for bool {
    fn from_node(node: &Node, path: &Path, reader: &mut Reader) -> Option<Self> {
        match &node.value {
            Value::Scalar { text, plain: true } if text == "true" => Some(true),
            Value::Scalar { text, plain: true } if text == "false" => Some(false),
            _ => {
                reader.error(
                    node.span,
                    format!("{} must be `true` or `false`", what(path)),
                    "expected a boolean",
                );
                None
            }
        }
    }
}

/// Reads every item; the list fails when any item does (after reporting them all).
impl<T: FromNode> FromNode for Vec<T> {
    fn from_node(node: &Node, path: &Path, reader: &mut Reader) -> Option<Self> {
        let items = sequence(node, path, reader)?;
        let read: Vec<Option<T>> = items
            .iter()
            .enumerate()
            .map(|(i, item)| T::from_node(item, &path.index(i), reader))
            .collect();
        read.into_iter().collect()
    }
}

fn sequence<'n>(node: &'n Node, path: &Path, reader: &mut Reader) -> Option<&'n [Node]> {
    match &node.value {
        Value::Sequence(items) => Some(items),
        _ => {
            reader.error(
                node.span,
                format!("{} must be a list, not {}", what(path), node.kind()),
                "expected `[…]` or `- ` lines",
            );
            None
        }
    }
}

impl FromNode for (i64, i64) {
    fn from_node(node: &Node, path: &Path, reader: &mut Reader) -> Option<Self> {
        let items = sequence(node, path, reader)?;
        if items.len() != 2 {
            reader.error(
                node.span,
                format!(
                    "{} must be two numbers `[min, max]`, not {}",
                    what(path),
                    items.len()
                ),
                "expected `[min, max]`",
            );
            return None;
        }
        let min = i64::from_node(&items[0], &path.index(0), reader);
        let max = i64::from_node(&items[1], &path.index(1), reader);
        Some((min?, max?))
    }
}

/// A list of named items, each with its index in the file; items that could not be read are
/// left out and their names noted.
#[derive(Debug)]
pub(crate) struct Items<T> {
    items: Vec<(usize, T)>,
    /// Names of the items left out.
    pub(crate) unread: Vec<String>,
}

impl<T> Default for Items<T> {
    fn default() -> Self {
        Self {
            items: Vec::new(),
            unread: Vec::new(),
        }
    }
}

impl<T> Items<T> {
    /// The items read, with their index in the file.
    pub(crate) fn iter(&self) -> impl Iterator<Item = (usize, &T)> {
        self.items.iter().map(|(i, item)| (*i, item))
    }
}

impl<T: FromNode> FromNode for Items<T> {
    fn from_node(node: &Node, path: &Path, reader: &mut Reader) -> Option<Self> {
        let mut read = Self::default();
        for (i, item) in sequence(node, path, reader)?.iter().enumerate() {
            match T::from_node(item, &path.index(i), reader) {
                Some(value) => read.items.push((i, value)),
                None => read
                    .unread
                    .extend(item.get("name").and_then(Node::text).map(str::to_owned)),
            }
        }
        Some(read)
    }
}

/// A mapping from names to items; entries that could not be read are left out and noted.
#[derive(Debug)]
pub(crate) struct Entries<T> {
    pub(crate) entries: BTreeMap<String, T>,
    /// Names of the entries left out.
    pub(crate) unread: Vec<String>,
}

impl<T> Default for Entries<T> {
    fn default() -> Self {
        Self {
            entries: BTreeMap::new(),
            unread: Vec::new(),
        }
    }
}

impl<T: FromNode> FromNode for Entries<T> {
    fn from_node(node: &Node, path: &Path, reader: &mut Reader) -> Option<Self> {
        let Value::Mapping(pairs) = &node.value else {
            reader.error(
                node.span,
                format!("{} must be a mapping, not {}", what(path), node.kind()),
                "expected `name: …` entries",
            );
            return None;
        };
        let mut read = Self::default();
        let mut first: BTreeMap<&str, Span> = BTreeMap::new();
        for (key, value) in pairs {
            let Some(name) = reader.scalar(key, path, "a name") else {
                continue;
            };
            if let Some(span) = first.insert(name, key.span) {
                reader.diagnostics.push(Diagnostic {
                    rule: RULE,
                    message: format!("{} has `{name}` twice", what(path)),
                    primary: Label {
                        location: Location::Span(key.span),
                        text: "repeated key".into(),
                    },
                    secondary: vec![Label {
                        location: Location::Span(span),
                        text: "first given here".into(),
                    }],
                    help: Some("rename one of them".into()),
                });
                continue;
            }
            match T::from_node(value, &path.key(name), reader) {
                Some(item) => {
                    read.entries.insert(name.to_owned(), item);
                }
                None => read.unread.push(name.to_owned()),
            }
        }
        Some(read)
    }
}

/// Name-valued keys: each value of the type and the one way a spec spells it.
macro_rules! names {
    ($($ty:ty { $($spelling:literal => $value:expr),* $(,)? })*) => {$(
        impl FromNode for $ty {
            fn from_node(node: &Node, path: &Path, reader: &mut Reader) -> Option<Self> {
                const SPELLINGS: &[(&str, $ty)] = &[$(($spelling, $value)),*];
                let text = reader.scalar(node, path, "a name")?;
                if let Some((_, value)) = SPELLINGS.iter().find(|(name, _)| *name == text) {
                    return Some(*value);
                }
                let expected: Vec<String> =
                    SPELLINGS.iter().map(|(name, _)| format!("`{name}`")).collect();
                reader.error(
                    node.span,
                    format!(
                        "{}: unknown name `{text}`, expected one of {}",
                        what(path),
                        expected.join(", ")
                    ),
                    "unknown name",
                );
                None
            }
        }
    )*};
}

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
}

/// `none`, `odd` or `even`, exactly as the spec schema spells them.
impl FromNode for Parity {
    fn from_node(node: &Node, path: &Path, reader: &mut Reader) -> Option<Self> {
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

/// Declares a spec struct and its reader. A field is required unless its type is an `Option`
/// or it is marked `= default`; `"key" => field` reads a key that is not a Rust name.
macro_rules! record {
    (
        $(#[$meta:meta])*
        pub(crate) struct $name:ident {
            $(
                $(#[$field_meta:meta])*
                $($key:literal =>)? $field:ident : $ty:ty $(= $default:ident)?
            ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug)]
        pub(crate) struct $name {
            $($(#[$field_meta])* pub(crate) $field: $ty,)*
        }

        impl FromNode for $name {
            fn from_node(node: &Node, path: &Path, reader: &mut Reader) -> Option<Self> {
                const KEYS: &[&str] = &[$([$($key,)? stringify!($field)][0]),*];
                let map = reader.mapping(node, path, KEYS)?;
                $(
                    let $field = record!(
                        @read reader, map, path, [$($key,)? stringify!($field)][0], $ty $(, $default)?
                    );
                )*
                Some(Self { $($field: $field?,)* })
            }
        }
    };
    (@read $reader:ident, $map:ident, $path:ident, $key:expr, $ty:ty) => {
        $reader.field::<$ty>(&$map, $path, $key)
    };
    (@read $reader:ident, $map:ident, $path:ident, $key:expr, $ty:ty, default) => {
        $reader.field_or_default::<$ty>(&$map, $path, $key)
    };
}

/// Reads a whole spec from its root node.
pub(crate) fn read(root: &Node, reader: &mut Reader) -> Option<SpecFile> {
    SpecFile::from_node(root, &Path::root(), reader)
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
        /// Writing acts and the manual defines no read.
        action: bool = default,
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
        /// The manual sanctions reading the range.
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
