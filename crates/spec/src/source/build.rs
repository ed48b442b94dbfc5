//! One parse of a text into the tree of [`Node`]s: the parser's events (on a second thread for
//! a large text) built into containers, each node placed at its line and column, and the parse
//! stopped at the first anchor or alias.

use std::sync::{mpsc, Arc, OnceLock};

use rlsp_yaml_parser::{Event, ScalarStyle};

use super::{FileKind, Node, Span, SyntaxError, Text, Value, ALIAS_RULE, YAML_RULE};

/// What one parse of a text gives.
pub(super) struct Parse {
    /// The documents' roots, in order.
    pub(super) documents: Vec<Node>,
    /// The text of every scalar, which the nodes hold ranges of.
    pub(super) scalars: Arc<OnceLock<String>>,
    /// Where each line of the text starts.
    pub(super) line_starts: Vec<usize>,
    /// Where the parse stopped, if it did not reach the end.
    pub(super) syntax_error: Option<SyntaxError>,
}

/// Parses `text`: stops at the first syntax error, anchor or alias.
pub(super) fn parse(text: &str, kind: FileKind) -> Parse {
    let mut builder = Builder {
        kind: Some(kind),
        ..Builder::default()
    };
    // The scalars of a spec take about a third of its text.
    builder.scalars.reserve(text.len() / 2);
    builder.places = Places::new(text);
    let syntax_error = builder.parse(text);
    let _ = builder.shared.set(builder.scalars);
    Parse {
        documents: builder.documents,
        scalars: builder.shared,
        line_starts: builder.places.line_starts,
        syntax_error,
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
    /// The kind of file, for the words of its errors (a spec unless told).
    kind: Option<FileKind>,
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
    fn kind(&self) -> FileKind {
        self.kind.unwrap_or(FileKind::SPEC)
    }

    /// Builds the tree of `text`, parsed on a second thread when the text is large enough for
    /// the two to overlap; stops at the first syntax error, anchor or alias.
    fn parse(&mut self, text: &str) -> Option<SyntaxError> {
        if text.len() < PARSE_ALONGSIDE_FROM {
            return self.build(text, rlsp_yaml_parser::parse_events(text));
        }
        std::thread::scope(|scope| {
            let (send, batches) = mpsc::sync_channel::<Vec<Parsed<'_>>>(BATCHES_AHEAD);
            let parser = std::thread::Builder::new()
                .name("yaml-parse".into())
                .spawn_scoped(scope, move || {
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
            match parser {
                Ok(_) => self.build(text, batches.into_iter().flatten()),
                // No thread to be had: the parse runs here.
                Err(_) => self.build(text, rlsp_yaml_parser::parse_events(text)),
            }
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
                        help: self.kind().not_yaml,
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
            self.problem = Some(refusal(span, sigil, name, self.kind()));
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
fn refusal(span: Span, sigil: &str, name: &str, kind: FileKind) -> SyntaxError {
    let what = if sigil == "*" { "alias" } else { "anchor" };
    SyntaxError {
        rule: ALIAS_RULE,
        message: format!(
            "YAML {what} `{sigil}{name}`: {} use no anchors or aliases",
            kind.plural
        ),
        help: "write the value out where it is needed: aliases are refused so that a small file \
               cannot expand into a huge tree",
        line: span.line,
        column: span.column,
    }
}
