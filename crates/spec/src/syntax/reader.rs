//! Reading typed values out of the positioned YAML tree: [`Reader`] collects every reading
//! error of a file, [`FromNode`] reads one value, [`Items`] and [`Entries`] recover from an
//! unreadable item, and the `names!` and `record!` macros declare name-valued keys and spec
//! structs.

use std::collections::BTreeMap;

use std::fmt;

use crate::diagnostic::Diagnostic;
use crate::reading::{check_keys, KeyProblem, Slots};
use crate::source::{Node, Span, Value};

/// Rule name of every reading error.
pub(crate) const RULE: &str = crate::source::YAML_RULE;

const HELP: &str = "see specs/README.md for the keys and forms a spec takes";

/// Collects the reading errors of one file.
#[derive(Default)]
pub(crate) struct Reader {
    pub(crate) diagnostics: Vec<Diagnostic>,
}

impl Reader {
    /// A key given twice in one mapping: at `again`, first at `first`.
    fn repeated(&mut self, path: &At<'_>, name: &str, again: Span, first: Span, help: &str) {
        let message = format!("{} has `{name}` twice", what(path));
        self.diagnostics.push(
            Diagnostic::at_span(RULE, again, message)
                .label("repeated key")
                .also_at(first, "first given here")
                .help(help),
        );
    }

    pub(super) fn error(&mut self, span: Span, message: String, label: impl Into<String>) {
        self.diagnostics.push(
            Diagnostic::at_span(RULE, span, message)
                .label(label)
                .help(HELP),
        );
    }

    /// The key-value pairs of `node`, or an error saying a mapping was `expected`.
    fn pairs<'n>(
        &mut self,
        node: &'n Node,
        path: &At<'_>,
        expected: &str,
    ) -> Option<&'n [(Node, Node)]> {
        if let Some(pairs) = node.entries() {
            return Some(pairs);
        }
        let message = format!("{} must be a mapping, not {}", what(path), node.kind());
        self.error(node.span, message, expected);
        None
    }

    /// `node` as a mapping of the given keys: unknown and repeated keys are reported (and
    /// otherwise ignored).
    pub(super) fn mapping<'n>(
        &mut self,
        node: &'n Node,
        path: &At<'_>,
        keys: &'static [&'static str],
    ) -> Option<Mapping<'n>> {
        let entries = self.pairs(
            node,
            path,
            "expected `key: value` lines or `{key: value, …}`",
        )?;
        let found = check_keys(entries, keys, |problem| match problem {
            KeyProblem::NotText { key } => self.error(
                key.span,
                format!("{} has a key that is not a name", what(path)),
                "expected a name",
            ),
            // An unknown key given twice is unknown twice.
            KeyProblem::Unknown { name, key }
            | KeyProblem::Repeated {
                name,
                key,
                known: false,
                ..
            } => self.diagnostics.push(
                Diagnostic::at_span(
                    RULE,
                    key.span,
                    format!("{} has an unknown key `{name}`", what(path)),
                )
                .label("unknown key")
                .help(format!("expected one of: {}", keys.join(", "))),
            ),
            KeyProblem::Repeated {
                name, key, first, ..
            } => self.repeated(path, name, key.span, first, "keep one of them"),
        });
        Some(Mapping {
            node,
            keys,
            entries: found,
        })
    }

    /// Reads the `slot`th key of `map`: absent keys take `T::absent()` or are reported missing.
    pub(crate) fn field<T: FromNode>(
        &mut self,
        map: &Mapping<'_>,
        path: &At<'_>,
        slot: usize,
    ) -> Option<T> {
        let key = map.keys[slot];
        match map.entries[slot] {
            Some((_, value)) => T::from_node(value, &At::Key(path, key), self),
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

    /// The text of a scalar, or a report that `node` is not one.
    pub(super) fn scalar<'n>(
        &mut self,
        node: &'n Node,
        path: &At<'_>,
        expected: &str,
    ) -> Option<&'n str> {
        let text = node.scalar();
        if text.is_none() {
            self.error(
                node.span,
                format!("{} must be {expected}, not {}", what(path), node.kind()),
                format!("expected {expected}"),
            );
        }
        text
    }
}

/// Where a value being read is, such as `registers[3].address`: steps linked on the stack,
/// written out only when a message names the place (most values are read without one).
#[derive(Clone, Copy, Debug)]
pub(crate) enum At<'a> {
    /// The document's root.
    Root,
    /// A mapping key under its parent.
    Key(&'a At<'a>, &'a str),
    /// A sequence index under its parent.
    Index(&'a At<'a>, usize),
}

/// Written like [`crate::source::Path`]: `registers[3].address`.
impl fmt::Display for At<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Root => Ok(()),
            Self::Key(Self::Root, key) => write!(f, "{key}"),
            Self::Key(parent, key) => write!(f, "{parent}.{key}"),
            Self::Index(parent, index) => write!(f, "{parent}[{index}]"),
        }
    }
}

/// How a path is named in messages.
pub(super) fn what(path: &At<'_>) -> String {
    if matches!(path, At::Root) {
        "the spec".into()
    } else {
        format!("`{path}`")
    }
}

/// A mapping's entries (first occurrence), one slot per known key, in the order of `keys`.
pub(crate) struct Mapping<'n> {
    node: &'n Node,
    keys: &'static [&'static str],
    entries: Slots<'n>,
}

/// A value read from a node of the tree.
pub(crate) trait FromNode: Sized {
    /// Reads `node` (at `path`), reporting every problem to `reader`; `None` when it cannot
    /// be read.
    fn from_node(node: &Node, path: &At<'_>, reader: &mut Reader) -> Option<Self>;

    /// The value of an absent key; `None` makes the key required.
    fn absent() -> Option<Self> {
        None
    }
}

impl<T: FromNode> FromNode for Option<T> {
    fn from_node(node: &Node, path: &At<'_>, reader: &mut Reader) -> Option<Self> {
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
    fn from_node(node: &Node, path: &At<'_>, reader: &mut Reader) -> Option<Self> {
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
            fn from_node(node: &Node, path: &At<'_>, reader: &mut Reader) -> Option<Self> {
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
    fn from_node(node: &Node, path: &At<'_>, reader: &mut Reader) -> Option<Self> {
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
    fn from_node(node: &Node, path: &At<'_>, reader: &mut Reader) -> Option<Self> {
        let items = sequence(node, path, reader)?;
        let read: Vec<Option<T>> = items
            .iter()
            .enumerate()
            .map(|(i, item)| T::from_node(item, &At::Index(path, i), reader))
            .collect();
        read.into_iter().collect()
    }
}

fn sequence<'n>(node: &'n Node, path: &At<'_>, reader: &mut Reader) -> Option<&'n [Node]> {
    let items = node.items();
    if items.is_none() {
        reader.error(
            node.span,
            format!("{} must be a list, not {}", what(path), node.kind()),
            "expected `[…]` or `- ` lines",
        );
    }
    items
}

impl FromNode for (i64, i64) {
    fn from_node(node: &Node, path: &At<'_>, reader: &mut Reader) -> Option<Self> {
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
        let min = i64::from_node(&items[0], &At::Index(path, 0), reader);
        let max = i64::from_node(&items[1], &At::Index(path, 1), reader);
        Some((min?, max?))
    }
}

/// What a list or mapping of named items gave: the items read (`found`), and the names of
/// those that could not be read and were left out (`unread`).
#[derive(Debug, Default)]
pub(crate) struct Read<C> {
    found: C,
    /// Names of the items left out.
    pub(crate) unread: Vec<String>,
}

/// A list of named items, each with its index in the file.
pub(crate) type Items<T> = Read<Vec<(usize, T)>>;

/// A mapping from names to items.
pub(crate) type Entries<T> = Read<BTreeMap<String, T>>;

impl<T> Items<T> {
    /// The items read, with their index in the file.
    pub(crate) fn iter(&self) -> impl Iterator<Item = (usize, &T)> {
        self.found.iter().map(|(i, item)| (*i, item))
    }

    /// The items read, with their index in the file, taken out (the names of those left out
    /// stay).
    pub(crate) fn take(&mut self) -> Vec<(usize, T)> {
        std::mem::take(&mut self.found)
    }

    /// The items read, mutable, with their index in the file.
    pub(crate) fn iter_mut(&mut self) -> impl Iterator<Item = (usize, &mut T)> {
        self.found.iter_mut().map(|(i, item)| (*i, item))
    }
}

impl<T: FromNode> FromNode for Items<T> {
    fn from_node(node: &Node, path: &At<'_>, reader: &mut Reader) -> Option<Self> {
        let items = sequence(node, path, reader)?;
        let mut read = Self {
            found: Vec::with_capacity(items.len()),
            unread: Vec::new(),
        };
        for (i, item) in items.iter().enumerate() {
            match T::from_node(item, &At::Index(path, i), reader) {
                Some(value) => read.found.push((i, value)),
                None => read
                    .unread
                    .extend(item.get("name").and_then(Node::text).map(str::to_owned)),
            }
        }
        Some(read)
    }
}

impl<T> Entries<T> {
    /// The entries read, by name.
    pub(crate) fn entries(&self) -> &BTreeMap<String, T> {
        &self.found
    }
}

impl<T: FromNode> FromNode for Entries<T> {
    fn from_node(node: &Node, path: &At<'_>, reader: &mut Reader) -> Option<Self> {
        let pairs = reader.pairs(node, path, "expected `name: …` entries")?;
        let mut read = Self::default();
        let mut first: BTreeMap<&str, Span> = BTreeMap::new();
        for (key, value) in pairs {
            let Some(name) = reader.scalar(key, path, "a name") else {
                continue;
            };
            if let Some(span) = first.insert(name, key.span) {
                reader.repeated(path, name, key.span, span, "rename one of them");
                continue;
            }
            match T::from_node(value, &At::Key(path, name), reader) {
                Some(item) => {
                    read.found.insert(name.to_owned(), item);
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
            fn from_node(node: &Node, path: &At<'_>, reader: &mut Reader) -> Option<Self> {
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
            fn from_node(node: &Node, path: &At<'_>, reader: &mut Reader) -> Option<Self> {
                const KEYS: &[&str] = &[$([$($key,)? stringify!($field)][0]),*];
                let map = reader.mapping(node, path, KEYS)?;
                // Fields are read in the order of `KEYS`: the `slot`th key is the field's.
                let mut slot = 0;
                $(
                    let $field = record!(@read reader, map, path, slot, $ty $(, $default)?);
                    slot += 1;
                )*
                let _ = slot;
                Some(Self { $($field: $field?,)* })
            }
        }
    };
    (@read $reader:ident, $map:ident, $path:ident, $slot:ident, $ty:ty) => {
        $reader.field::<$ty>(&$map, $path, $slot)
    };
    (@read $reader:ident, $map:ident, $path:ident, $slot:ident, $ty:ty, default) => {
        // Absent or null (`Option`'s own reading) is the default.
        $reader
            .field::<Option<$ty>>(&$map, $path, $slot)
            .map(Option::unwrap_or_default)
    };
}
