//! A spec file parsed once into a tree of [`Node`]s that keep their line and column, and an
//! index from each YAML path (`registers[3].address`) to the place of its value and key.
//!
//! The reader (`syntax`) takes its values from the tree and the diagnostics take their
//! places from the index, so both come from the same parse.
//!
//! Spec files are input like any other: [`read_yaml`] reads at most [`YAML_LIMIT`] bytes, and
//! the parse refuses anchors and aliases as they stream by ([`ALIAS_RULE`]), so a small file
//! can never expand into a large tree.

use std::borrow::Cow;
use std::fmt;
use std::io::{self, Read};
use std::ops::Deref;
use std::sync::{mpsc, Arc, OnceLock};

use foldhash::{HashMap, HashMapExt};
use rlsp_yaml_parser::{Event, ScalarStyle};

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

/// Help for a text that is not YAML.
const NOT_YAML: &str = "the spec is not valid YAML";

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
        let text = text.into();
        let mut builder = Builder::default();
        // The scalars of a spec take about a third of its text.
        builder.scalars.reserve(text.len() / 2);
        builder.places = Places::new(&text);
        let syntax_error = builder.parse(&text);
        let syntax_error = syntax_error.or_else(|| {
            let second = builder.documents.get(1)?;
            Some(SyntaxError {
                rule: YAML_RULE,
                message: "a spec is one YAML document; this starts another".into(),
                help: NOT_YAML,
                line: second.span.line,
                column: second.span.column,
            })
        });
        let _ = builder.shared.set(builder.scalars);
        let root = builder.documents.into_iter().next();
        let line_starts = builder.places.line_starts;
        Self {
            name: name.into(),
            text,
            root,
            syntax_error,
            scalars: builder.shared,
            nodes: OnceLock::new(),
            line_starts,
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

/// The most bytes a YAML file read by this crate (a spec, and the bus files to come) may
/// hold: 16 MiB. The largest spec in `specs/` has 42 kB; a generated spec of 100,000
/// registers has 15 MB. The densest file (16 MiB of one-character scalars) makes a tree of
/// under a gigabyte; a spec is checked in some twenty times its size.
pub const YAML_LIMIT: u64 = 16 * 1024 * 1024;

/// Why a file could not be read within its limit.
#[derive(Debug)]
pub enum ReadError {
    /// The system refused (no such file, no permission, …).
    Io(io::Error),
    /// A device, directory or socket: only regular files (and pipes, on Unix) are read.
    NotAFile,
    /// More bytes than the limit.
    TooLarge {
        /// The limit, in bytes.
        limit: u64,
    },
    /// Bytes that are not UTF-8 text.
    NotText {
        /// Where the first bad byte is.
        offset: usize,
    },
}

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Io(error) => write!(f, "{error}"),
            Self::NotAFile => f.write_str("not a regular file (a device, directory or socket)"),
            Self::TooLarge { limit } => {
                write!(f, "larger than the limit of {}", size_text(*limit))
            }
            Self::NotText { offset } => write!(f, "not UTF-8 text (byte {offset})"),
        }
    }
}

impl std::error::Error for ReadError {}

/// A byte count as people read it: `16 MiB`, `512 KiB`, `100 bytes`.
pub fn size_text(bytes: u64) -> String {
    const UNITS: [(u64, &str); 3] = [(1 << 30, "GiB"), (1 << 20, "MiB"), (1 << 10, "KiB")];
    UNITS
        .iter()
        .find(|(unit, _)| bytes >= *unit && bytes.is_multiple_of(*unit))
        .map_or_else(
            || format!("{bytes} bytes"),
            |(unit, name)| format!("{} {name}", bytes / unit),
        )
}

/// A file opened by [`open_limited`]: reading past its limit fails with
/// [`io::ErrorKind::FileTooLarge`].
#[derive(Debug)]
pub struct Limited {
    file: io::Take<std::fs::File>,
    limit: u64,
    read: u64,
}

impl Read for Limited {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let count = self.file.read(buf)?;
        self.read += count as u64;
        if self.read > self.limit {
            return Err(io::Error::new(
                io::ErrorKind::FileTooLarge,
                ReadError::TooLarge { limit: self.limit },
            ));
        }
        Ok(count)
    }
}

/// Opens `path` to read at most `limit` bytes. A regular file larger than that is refused at
/// once; a pipe is read up to one byte past the limit; devices (`/dev/zero`), directories and
/// sockets are refused.
pub fn open_limited(path: &std::path::Path, limit: u64) -> Result<Limited, ReadError> {
    let file = std::fs::File::open(path).map_err(ReadError::Io)?;
    let kind = file.metadata().map_err(ReadError::Io)?;
    #[cfg(unix)]
    let pipe = std::os::unix::fs::FileTypeExt::is_fifo(&kind.file_type());
    #[cfg(not(unix))]
    let pipe = false;
    if !kind.is_file() && !pipe {
        return Err(ReadError::NotAFile);
    }
    if kind.len() > limit {
        return Err(ReadError::TooLarge { limit });
    }
    Ok(Limited {
        file: file.take(limit.saturating_add(1)),
        limit,
        read: 0,
    })
}

/// The bytes of `path`, at most `limit` of them (see [`open_limited`]).
pub fn read_limited(path: &std::path::Path, limit: u64) -> Result<Vec<u8>, ReadError> {
    let mut file = open_limited(path, limit)?;
    let mut bytes = Vec::new();
    match file.read_to_end(&mut bytes) {
        Ok(_) => Ok(bytes),
        Err(error) if error.kind() == io::ErrorKind::FileTooLarge => {
            Err(ReadError::TooLarge { limit })
        }
        Err(error) => Err(ReadError::Io(error)),
    }
}

/// The text of a YAML file: at most [`YAML_LIMIT`] bytes of UTF-8.
pub fn read_yaml(path: &std::path::Path) -> Result<String, ReadError> {
    String::from_utf8(read_limited(path, YAML_LIMIT)?).map_err(|error| ReadError::NotText {
        offset: error.utf8_error().valid_up_to(),
    })
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

/// What the parser gives for each event.
type Parsed<'t> = Result<(Event<'t>, rlsp_yaml_parser::Span), rlsp_yaml_parser::Error>;

/// From this size on (1 MiB, some 6,000 registers) a text is parsed on a second thread while
/// its tree is built; below it the thread would cost more than it saves.
const PARSE_ALONGSIDE_FROM: usize = 1 << 20;

/// Events handed from the parser's thread to the builder at a time, and batches it may run
/// ahead by.
const BATCH: usize = 1024;
const BATCHES_AHEAD: usize = 8;

/// A container being filled: where it starts, and where its children start in
/// [`Builder::children`].
struct Open {
    span: Span,
    mapping: bool,
    first_child: usize,
}

#[derive(Default)]
struct Builder {
    stack: Vec<Open>,
    /// The finished children of every open container, innermost last: each container takes
    /// its own in one allocation of the right size when it ends.
    children: Vec<Node>,
    documents: Vec<Node>,
    /// The text of every scalar so far: the nodes hold ranges of it.
    scalars: String,
    /// Where the nodes find `scalars` once the parse ends.
    shared: Arc<OnceLock<String>>,
    /// Turns the parser's byte offsets into lines and columns.
    places: Places,
    /// The first anchor or alias, which ends the parse.
    problem: Option<SyntaxError>,
}

/// Lines and columns of byte offsets. The parser's events come in order, so the line is
/// found by a cursor moving forward; columns count characters, and the ASCII start of each
/// line (most of a spec) is counted by its length.
#[derive(Default)]
struct Places {
    /// Where each line starts.
    line_starts: Vec<usize>,
    /// Where each line's first non-ASCII byte is (or its end).
    ascii_until: Vec<usize>,
    /// The line (from 0) of the last offset placed.
    line: usize,
}

impl Places {
    fn new(text: &str) -> Self {
        let line_starts: Vec<usize> = std::iter::once(0)
            .chain(text.match_indices('\n').map(|(at, _)| at + 1))
            .collect();
        let bytes = text.as_bytes();
        let ascii_until = line_starts
            .iter()
            .enumerate()
            .map(|(line, &start)| {
                let end = line_starts
                    .get(line + 1)
                    .map_or(bytes.len(), |&next| next - 1);
                let line = &bytes[start..end];
                start
                    + if line.is_ascii() {
                        line.len()
                    } else {
                        line.iter().take_while(|b| b.is_ascii()).count()
                    }
            })
            .collect();
        Self {
            line_starts,
            ascii_until,
            line: 0,
        }
    }

    /// The span of `text[start..end]`: where it starts, and its width in characters on its
    /// first line.
    fn span(&mut self, text: &str, start: usize, end: usize) -> Span {
        let bytes = text.as_bytes();
        let start = floor_char_boundary(text, start.min(text.len()));
        let before = |line: usize| self.line_starts[line] <= start;
        if !before(self.line) {
            self.line = self.line_starts.partition_point(|&at| at <= start) - 1;
        }
        while self.line + 1 < self.line_starts.len() && before(self.line + 1) {
            self.line += 1;
        }
        let line_start = self.line_starts[self.line];
        let line_end = self
            .line_starts
            .get(self.line + 1)
            .map_or(bytes.len(), |&next| next - 1);
        let ascii_until = self.ascii_until[self.line];
        let column = if start <= ascii_until {
            start - line_start
        } else {
            ascii_until - line_start + characters(&bytes[ascii_until..start])
        };
        let stop = end.clamp(start, line_end);
        let written = &bytes[start..stop];
        let mut width = if stop <= ascii_until {
            written.len()
        } else {
            characters(written)
        };
        if written.last() == Some(&b'\r') {
            width -= 1;
        }
        Span {
            line: self.line + 1,
            column: column + 1,
            width: width.max(1),
        }
    }
}

/// How many characters the UTF-8 `bytes` hold: every byte but the continuation bytes
/// (`0b10xx_xxxx`) starts one.
fn characters(bytes: &[u8]) -> usize {
    bytes.iter().filter(|&&byte| (byte as i8) >= -0x40).count()
}

/// `at`, or the start of the character holding it.
fn floor_char_boundary(text: &str, mut at: usize) -> usize {
    while !text.is_char_boundary(at) {
        at -= 1;
    }
    at
}

impl Builder {
    /// Builds the tree of `text`, parsed on a second thread when the text is large enough for
    /// the two to overlap; stops at the first syntax error, anchor or alias.
    fn parse(&mut self, text: &str) -> Option<SyntaxError> {
        if text.len() < PARSE_ALONGSIDE_FROM {
            return self.build(text, rlsp_yaml_parser::parse_events(text));
        }
        std::thread::scope(|scope| {
            let (send, batches) = mpsc::sync_channel::<Vec<Parsed<'_>>>(BATCHES_AHEAD);
            scope.spawn(move || {
                let mut events = rlsp_yaml_parser::parse_events(text);
                loop {
                    let batch: Vec<_> = events.by_ref().take(BATCH).collect();
                    let last = batch.len() < BATCH || batch.last().is_some_and(Result::is_err);
                    // The builder hangs up once it has stopped at a problem.
                    if send.send(batch).is_err() || last {
                        break;
                    }
                }
            });
            self.build(text, batches.into_iter().flatten())
        })
    }

    /// Builds the tree from `events`, event by event, so that the first anchor or alias
    /// stops the parse before anything is copied.
    fn build<'t>(
        &mut self,
        text: &'t str,
        events: impl IntoIterator<Item = Parsed<'t>>,
    ) -> Option<SyntaxError> {
        for parsed in events {
            match parsed {
                Ok((Event::StreamEnd, _)) => break,
                Ok((event, bytes)) => self.on_event(text, event, bytes),
                Err(error) => {
                    return Some(SyntaxError {
                        rule: YAML_RULE,
                        message: error.message,
                        help: NOT_YAML,
                        line: error.pos.line,
                        column: error.pos.column + 1,
                    })
                }
            }
            if let Some(refused) = self.problem.take() {
                return Some(refused);
            }
        }
        None
    }

    /// Adds a finished node to its parent (or ends the document).
    fn push(&mut self, node: Node) {
        if self.stack.is_empty() {
            self.documents.push(node);
        } else {
            self.children.push(node);
        }
    }

    /// Ends the innermost container: it takes its children (keys and values in turn, for a
    /// mapping).
    fn close(&mut self) {
        let Some(open) = self.stack.pop() else {
            return;
        };
        let children = self.children.drain(open.first_child..);
        let value = if open.mapping {
            let mut entries = Vec::with_capacity(children.len() / 2);
            let mut children = children;
            while let (Some(key), Some(value)) = (children.next(), children.next()) {
                entries.push((key, value));
            }
            Value::Mapping(entries)
        } else {
            Value::Sequence(children.collect())
        };
        self.push(Node {
            span: open.span,
            value,
        });
    }

    /// Notes the first anchor or alias, named and placed where it is written: the spec
    /// language has neither, and expanding aliases lets a few hundred bytes make a tree of
    /// gigabytes.
    fn refuse(&mut self, text: &str, sigil: &str, name: &str, at: rlsp_yaml_parser::Span) {
        if self.problem.is_none() {
            let span = self.places.span(text, at.start as usize, at.end as usize);
            self.problem = Some(refusal(span, sigil, name));
        }
    }

    fn on_event(&mut self, text: &str, event: Event<'_>, at: rlsp_yaml_parser::Span) {
        let anchor = match &event {
            Event::Scalar { meta, .. }
            | Event::MappingStart { meta, .. }
            | Event::SequenceStart { meta, .. } => meta.as_deref(),
            _ => None,
        };
        if let Some((name, place)) = anchor.and_then(|meta| meta.anchor.zip(meta.anchor_loc)) {
            return self.refuse(text, "&", name, place);
        }
        match event {
            Event::Scalar { value, style, .. } => {
                let span = self.places.span(text, at.start as usize, at.end as usize);
                let start = self.scalars.len();
                self.scalars.push_str(&value);
                let text = Text {
                    scalars: Arc::clone(&self.shared),
                    start,
                    end: self.scalars.len(),
                };
                let plain = matches!(style, ScalarStyle::Plain);
                self.push(Node {
                    span,
                    value: Value::Scalar { text, plain },
                });
            }
            Event::MappingStart { .. } | Event::SequenceStart { .. } => {
                let mut span = self.places.span(text, at.start as usize, at.end as usize);
                span.width = 1;
                self.stack.push(Open {
                    span,
                    mapping: matches!(event, Event::MappingStart { .. }),
                    first_child: self.children.len(),
                });
            }
            Event::MappingEnd | Event::SequenceEnd => self.close(),
            Event::Alias { name } => self.refuse(text, "*", name, at),
            _ => {}
        }
    }
}

/// The refusal of an anchor (`sigil` `&`) or alias (`*`) named `name` at `span`.
fn refusal(span: Span, sigil: &str, name: &str) -> SyntaxError {
    let what = if sigil == "*" { "alias" } else { "anchor" };
    SyntaxError {
        rule: ALIAS_RULE,
        message: format!("YAML {what} `{sigil}{name}`: specs use no anchors or aliases"),
        help: "write the value out where it is needed: aliases are refused so that a small file \
               cannot expand into a huge tree",
        line: span.line,
        column: span.column,
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
