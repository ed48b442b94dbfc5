//! Where things are in a spec file: a map from each YAML path (`registers[3].address`) to the
//! line and column of its value and key, built from the YAML event stream.
//!
//! serde reads the spec into types but forgets positions; this map lets a semantic rule point
//! at the offending text exactly as a syntax error would.

use std::collections::HashMap;
use std::fmt;

use yaml_rust2::parser::{Event, MarkedEventReceiver, Parser};
use yaml_rust2::scanner::{Marker, TScalarStyle};

/// One step of a path into the YAML tree.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Segment {
    /// A mapping key.
    Key(String),
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
    pub fn key(&self, key: &str) -> Self {
        let mut next = self.clone();
        next.0.push(Segment::Key(key.to_owned()));
        next
    }

    /// This path extended by an index.
    pub fn index(&self, index: usize) -> Self {
        let mut next = self.clone();
        next.0.push(Segment::Index(index));
        next
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

/// What the map knows about one node.
#[derive(Clone, Debug)]
struct Node {
    value: Span,
    key: Option<Span>,
    text: Option<String>,
}

/// A spec file's text and the positions of its nodes.
#[derive(Debug)]
pub struct SourceFile {
    /// The name to show in diagnostics (the path as given).
    pub name: String,
    /// The whole text.
    pub text: String,
    nodes: HashMap<Path, Node>,
}

impl SourceFile {
    /// Indexes `text`. A YAML syntax error leaves the map partial; serde reports it.
    pub fn new(name: impl Into<String>, text: impl Into<String>) -> Self {
        let text = text.into();
        let mut builder = Builder::default();
        let mut parser = Parser::new_from_str(&text);
        let _ = parser.load(&mut builder, false);
        Self {
            name: name.into(),
            text,
            nodes: builder.nodes,
        }
    }

    /// The span of the value at `path`, or of the nearest ancestor that has one.
    pub fn span(&self, path: &Path) -> Option<Span> {
        let mut path = path.clone();
        loop {
            if let Some(node) = self.nodes.get(&path) {
                return Some(node.value);
            }
            path.0.pop()?;
        }
    }

    /// The span of the key naming the value at `path`.
    pub fn key_span(&self, path: &Path) -> Option<Span> {
        self.nodes.get(path).and_then(|node| node.key)
    }

    /// The scalar's text exactly as written (for values YAML would otherwise reinterpret,
    /// such as `1e-6`).
    pub fn scalar(&self, path: &Path) -> Option<&str> {
        self.nodes.get(path).and_then(|node| node.text.as_deref())
    }

    /// Line `line` (1-based) without its newline.
    pub fn line(&self, line: usize) -> Option<&str> {
        self.text.lines().nth(line.checked_sub(1)?)
    }
}

enum Frame {
    Mapping {
        path: Path,
        pending_key: Option<(String, Span)>,
    },
    Sequence {
        path: Path,
        next: usize,
    },
}

#[derive(Default)]
struct Builder {
    stack: Vec<Frame>,
    nodes: HashMap<Path, Node>,
}

fn span_at(mark: Marker, width: usize) -> Span {
    Span {
        line: mark.line(),
        column: mark.col() + 1,
        width: width.max(1),
    }
}

impl Builder {
    /// Where the next value goes, and the key naming it; advances the parent.
    fn next_value_path(&mut self) -> (Path, Option<Span>) {
        match self.stack.last_mut() {
            None => (Path::root(), None),
            Some(Frame::Mapping { path, pending_key }) => match pending_key.take() {
                Some((key, key_span)) => (path.key(&key), Some(key_span)),
                None => (path.key("?"), None),
            },
            Some(Frame::Sequence { path, next }) => {
                *next += 1;
                (path.index(*next - 1), None)
            }
        }
    }

    fn expecting_key(&self) -> bool {
        matches!(
            self.stack.last(),
            Some(Frame::Mapping {
                pending_key: None,
                ..
            })
        )
    }
}

impl MarkedEventReceiver for Builder {
    fn on_event(&mut self, event: Event, mark: Marker) {
        match event {
            Event::Scalar(text, style, ..) => {
                let quoted = matches!(
                    style,
                    TScalarStyle::SingleQuoted | TScalarStyle::DoubleQuoted
                );
                let width = text.chars().count() + if quoted { 2 } else { 0 };
                if self.expecting_key() {
                    if let Some(Frame::Mapping { pending_key, .. }) = self.stack.last_mut() {
                        *pending_key = Some((text, span_at(mark, width)));
                    }
                    return;
                }
                let (path, key) = self.next_value_path();
                self.nodes.insert(
                    path,
                    Node {
                        value: span_at(mark, width),
                        key,
                        text: Some(text),
                    },
                );
            }
            Event::MappingStart(..) | Event::SequenceStart(..) => {
                let (path, key) = self.next_value_path();
                self.nodes.insert(
                    path.clone(),
                    Node {
                        value: span_at(mark, 1),
                        key,
                        text: None,
                    },
                );
                self.stack
                    .push(if matches!(event, Event::MappingStart(..)) {
                        Frame::Mapping {
                            path,
                            pending_key: None,
                        }
                    } else {
                        Frame::Sequence { path, next: 0 }
                    });
            }
            Event::MappingEnd | Event::SequenceEnd => {
                self.stack.pop();
            }
            _ => {}
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
        // Unknown paths fall back to the nearest ancestor.
        assert_eq!(source.span(&first.key("doc")).map(|s| s.line), Some(3));
    }
}
