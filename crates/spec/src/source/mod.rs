//! A spec file parsed once into a tree of [`Node`]s that keep their line and column, and an
//! index from each YAML path (`registers[3].address`) to the place of its value and key.
//!
//! The reader (`syntax`) takes its values from the tree and the diagnostics take their
//! places from the index, so both come from the same parse.
//!
//! Spec files are input like any other: [`read_yaml`] reads at most [`YAML_LIMIT`] bytes, and
//! the parse refuses anchors and aliases as they stream by ([`ALIAS_RULE`]), so a small file
//! can never expand into a large tree.

mod build;
mod files;

use std::borrow::Cow;
use std::fmt;
use std::ops::Deref;
use std::sync::{Arc, OnceLock};

use foldhash::{HashMap, HashMapExt};

pub use files::{open_limited, read_limited, read_yaml, size_text, Limited, ReadError, YAML_LIMIT};

/// One step of a path into the YAML tree.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Segment {
    /// A mapping key: borrowed for the keys of the spec language, so that the paths of a
    /// model cost one allocation each.
    Key(Cow<'static, str>),
    /// A sequence index.
    Index(usize),
}

/// A path into the YAML tree, such as `registers[3].address`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
pub struct Path(pub Vec<Segment>);

impl Path {
    /// The root of the document.
    pub fn root() -> Self {
        Self::default()
    }

    /// This path extended by a key.
    pub fn key(&self, key: impl Into<Cow<'static, str>>) -> Self {
        self.then(Segment::Key(key.into()))
    }

    /// This path and one more step, in one allocation.
    fn then(&self, step: Segment) -> Self {
        let mut next = Vec::with_capacity(self.0.len() + 1);
        next.extend_from_slice(&self.0);
        next.push(step);
        Self(next)
    }

    /// This path without its last step.
    pub fn parent(&self) -> Self {
        let mut parent = self.clone();
        parent.0.pop();
        parent
    }

    /// This path extended by an index.
    pub fn index(&self, index: usize) -> Self {
        self.then(Segment::Index(index))
    }
}

impl fmt::Display for Path {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, segment) in self.0.iter().enumerate() {
            match segment {
                Segment::Key(key) if i == 0 => write!(f, "{key}")?,
                Segment::Key(key) => write!(f, ".{key}")?,
                Segment::Index(index) => write!(f, "[{index}]")?,
            }
        }
        Ok(())
    }
}

/// A position in the source: 1-based line and column (in characters), and a width to underline.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Span {
    /// Line, from 1.
    pub line: usize,
    /// Column, from 1, in characters.
    pub column: usize,
    /// Characters to underline (at least 1).
    pub width: usize,
}

/// What the index knows about one node.
#[derive(Clone, Debug)]
struct Entry {
    value: Span,
    key: Option<Span>,
    text: Option<String>,
}

/// A parsed YAML node with its position: the one tree both the reader and the diagnostics
/// work from.
#[derive(Clone, Debug)]
pub struct Node {
    /// Where the node starts (scalars: their whole text).
    pub span: Span,
    /// What it holds.
    pub value: Value,
}

/// The text of a scalar: a range of the one buffer that holds the text of every scalar of a
/// file, so that a scalar holds no allocation of its own (a spec's tree has millions of
/// them). Reads as a `str`.
#[derive(Clone)]
pub struct Text {
    /// Every scalar's text, set once the parse ends.
    scalars: Arc<OnceLock<String>>,
    start: usize,
    end: usize,
}

impl Deref for Text {
    type Target = str;

    fn deref(&self) -> &str {
        self.scalars
            .get()
            .and_then(|scalars| scalars.get(self.start..self.end))
            .unwrap_or_default()
    }
}

impl PartialEq<str> for Text {
    fn eq(&self, other: &str) -> bool {
        **self == *other
    }
}

impl fmt::Debug for Text {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(&**self, f)
    }
}

impl fmt::Display for Text {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self)
    }
}

/// The content of a [`Node`].
#[derive(Clone, Debug)]
pub enum Value {
    /// A scalar exactly as written; `plain` when unquoted (only plain scalars are numbers,
    /// booleans or null).
    Scalar {
        /// The text.
        text: Text,
        /// Written without quotes or block style.
        plain: bool,
    },
    /// A sequence.
    Sequence(Vec<Node>),
    /// A mapping, entries in source order (duplicates kept for the reader to report).
    Mapping(Vec<(Node, Node)>),
}

impl Node {
    /// True for a plain `~`, `null` or empty scalar.
    pub fn is_null(&self) -> bool {
        // By length first: most scalars are longer, and their text need not be looked up.
        matches!(&self.value, Value::Scalar { text, plain: true }
            if text.end - text.start <= 4 && matches!(&**text, "" | "~" | "null" | "Null" | "NULL"))
    }

    /// The value under `key`, for a mapping.
    pub fn get(&self, key: &str) -> Option<&Node> {
        match &self.value {
            Value::Mapping(entries) => entries
                .iter()
                .find(|(k, _)| matches!(&k.value, Value::Scalar { text, .. } if **text == *key))
                .map(|(_, v)| v),
            _ => None,
        }
    }

    /// The scalar's text.
    pub fn text(&self) -> Option<&str> {
        match &self.value {
            Value::Scalar { text, .. } => Some(text),
            _ => None,
        }
    }

    /// The text of a scalar that is not null: what a key, or a value read as text, must be.
    pub fn scalar(&self) -> Option<&str> {
        match &self.value {
            Value::Scalar { text, .. } if !self.is_null() => Some(text),
            _ => None,
        }
    }

    /// The entries of a mapping, in source order.
    pub fn entries(&self) -> Option<&[(Node, Node)]> {
        match &self.value {
            Value::Mapping(entries) => Some(entries),
            _ => None,
        }
    }

    /// The items of a sequence.
    pub fn items(&self) -> Option<&[Node]> {
        match &self.value {
            Value::Sequence(items) => Some(items),
            _ => None,
        }
    }

    /// What kind of node this is, for messages.
    pub fn kind(&self) -> &'static str {
        match &self.value {
            Value::Scalar { .. } if self.is_null() => "null",
            Value::Scalar { .. } => "a scalar",
            Value::Sequence(_) => "a list",
            Value::Mapping(_) => "a mapping",
        }
    }
}

/// A YAML syntax error: the parser's message and where it stopped.
#[derive(Clone, Debug)]
pub struct SyntaxError {
    /// The rule it breaks: `yaml`, or [`ALIAS_RULE`].
    pub rule: &'static str,
    /// The parser's words.
    pub message: String,
    /// How to mend it.
    pub help: &'static str,
    /// Line, from 1.
    pub line: usize,
    /// Column, from 1.
    pub column: usize,
}

/// Rule name of text that is not YAML, or that a spec reader cannot read.
pub const YAML_RULE: &str = "yaml";

/// Rule name of the refusal of YAML anchors and aliases.
pub const ALIAS_RULE: &str = "yaml-alias";

/// What kind of file a YAML text is, in the words its syntax errors use ("the spec is not
/// valid YAML", "the bus file is not valid YAML").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FileKind {
    /// The kind with its article, as a sentence starts it: `a spec`.
    pub a: &'static str,
    /// The kind in the plural: `specs`.
    pub plural: &'static str,
    /// The help of a text that is not YAML: `the spec is not valid YAML`.
    pub not_yaml: &'static str,
}

impl FileKind {
    /// A register spec.
    pub const SPEC: Self = Self {
        a: "a spec",
        plural: "specs",
        not_yaml: "the spec is not valid YAML",
    };
}

/// A spec file's text, its parsed tree, and the positions of its nodes by path.
#[derive(Debug)]
pub struct SourceFile {
    /// The name to show in diagnostics (the path as given).
    pub name: String,
    /// The whole text.
    pub text: String,
    /// The document's root, unless the text is not YAML.
    pub root: Option<Node>,
    /// Why the text is not YAML.
    pub syntax_error: Option<SyntaxError>,
    /// The text of every scalar of the tree, one after the other.
    scalars: Arc<OnceLock<String>>,
    /// The positions by path, built at the first lookup: only diagnostics look places up, so
    /// a spec that passes never pays for the index.
    nodes: OnceLock<HashMap<Path, Entry>>,
    /// Where each line of `text` starts.
    line_starts: Vec<usize>,
}

impl SourceFile {
    /// Parses `text` once, into a tree and an index of positions by path. The parse stops at
    /// the first syntax error, anchor or alias.
    pub fn new(name: impl Into<String>, text: impl Into<String>) -> Self {
        Self::of_kind(FileKind::SPEC, name, text)
    }

    /// [`SourceFile::new`] of a YAML file of another kind than a spec, whose syntax errors
    /// name that kind.
    pub fn of_kind(kind: FileKind, name: impl Into<String>, text: impl Into<String>) -> Self {
        let text = text.into();
        let parsed = build::parse(&text, kind);
        let mut documents = parsed.documents.into_iter();
        let root = documents.next();
        let syntax_error = parsed.syntax_error.or_else(|| {
            let second = documents.next()?;
            Some(SyntaxError {
                rule: YAML_RULE,
                message: format!("{} is one YAML document; this starts another", kind.a),
                help: kind.not_yaml,
                line: second.span.line,
                column: second.span.column,
            })
        });
        Self {
            name: name.into(),
            text,
            root,
            syntax_error,
            scalars: parsed.scalars,
            nodes: OnceLock::new(),
            line_starts: parsed.line_starts,
        }
    }

    /// The text of every scalar of the tree (keys included), one after the other: a pass that
    /// looks at every scalar's characters reads it in one sweep.
    pub fn scalars(&self) -> &str {
        self.scalars.get().map_or("", String::as_str)
    }

    /// Every node's place by path (built once, at the first lookup).
    fn nodes(&self) -> &HashMap<Path, Entry> {
        self.nodes.get_or_init(|| {
            let mut nodes = HashMap::new();
            if let Some(root) = &self.root {
                index(root, Path::root(), None, &mut nodes);
            }
            nodes
        })
    }

    /// The span of the value at `path`, or of the nearest ancestor that has one.
    pub fn span(&self, path: &Path) -> Option<Span> {
        let mut path = path.clone();
        loop {
            if let Some(node) = self.nodes().get(&path) {
                return Some(node.value);
            }
            path.0.pop()?;
        }
    }

    /// The span of the key naming the value at `path`.
    pub fn key_span(&self, path: &Path) -> Option<Span> {
        self.nodes().get(path).and_then(|node| node.key)
    }

    /// The scalar's text exactly as written (for values YAML would otherwise reinterpret,
    /// such as `1e-6`).
    pub fn scalar(&self, path: &Path) -> Option<&str> {
        self.nodes().get(path).and_then(|node| node.text.as_deref())
    }

    /// Line `line` (1-based) without its newline (as [`str::lines`] gives it); a lookup in
    /// an index of line starts, so that rendering many diagnostics stays linear.
    pub fn line(&self, line: usize) -> Option<&str> {
        let start = *self.line_starts.get(line.checked_sub(1)?)?;
        let rest = &self.text[start..];
        let text = rest.split_once('\n').map_or(rest, |(text, _)| text);
        if start == self.text.len() {
            return None;
        }
        Some(text.strip_suffix('\r').unwrap_or(text))
    }
}

/// Records every node's position under its path; a repeated key keeps its first place.
fn index(node: &Node, path: Path, key: Option<Span>, out: &mut HashMap<Path, Entry>) {
    if out.contains_key(&path) {
        return;
    }
    out.insert(
        path.clone(),
        Entry {
            value: node.span,
            key,
            text: node.text().map(str::to_owned),
        },
    );
    match &node.value {
        Value::Scalar { .. } => {}
        Value::Sequence(items) => {
            for (i, item) in items.iter().enumerate() {
                index(item, path.index(i), None, out);
            }
        }
        Value::Mapping(entries) => {
            for (k, v) in entries {
                if let Some(text) = k.text() {
                    index(v, path.key(text.to_owned()), Some(k.span), out);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_values_keys_and_raw_text() {
        let source = SourceFile::new(
            "t.yaml",
            "family: x\nregisters:\n  - name: a\n    scale: 1e-6\n  - {name: b, address: 0x10}\n",
        );
        let first = Path::root().key("registers").index(0);
        assert_eq!(
            source.span(&first.key("name")),
            Some(Span {
                line: 3,
                column: 11,
                width: 1
            })
        );
        assert_eq!(source.scalar(&first.key("scale")), Some("1e-6"));
        let second = Path::root().key("registers").index(1).key("address");
        assert_eq!(
            source.span(&second).map(|s| (s.line, s.column)),
            Some((5, 24))
        );
        assert_eq!(source.key_span(&second).map(|s| s.column), Some(15));
        assert_eq!(source.line(2), Some("registers:"));
        assert_eq!(source.line(6), None);
        let crlf = SourceFile::new("t.yaml", "a: 1\r\nb: 2\r\n");
        assert_eq!(
            (crlf.line(1), crlf.line(2), crlf.line(3)),
            (Some("a: 1"), Some("b: 2"), None)
        );
        // Unknown paths fall back to the nearest ancestor.
        assert_eq!(source.span(&first.key("doc")).map(|s| s.line), Some(3));
    }
}
