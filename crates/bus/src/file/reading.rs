//! The reading kit of the bus file: a reader that collects every problem with its place, and
//! what it reads values with (mappings with known keys, lists, text, numbers, durations,
//! addresses). What the bus file means is read with it in `read.rs`; it is public so that the
//! crates of the outputs read their sections of `outputs:` with it, in the same words.

use std::ops::{Deref, DerefMut};
use std::path::Path;
use std::time::Duration;

use jiff::SignedDuration;
use optobus_inspect::did_you_mean;
use optobus_spec::reading::{check_keys, KeyProblem};
use optobus_spec::source::FileKind;
use optobus_spec::SpecError;

use super::MAX_DURATION;
use optobus_spec::Catalogue;

/// The positioned tree the kit reads and the problems it reports, for the outputs' readers.
pub use optobus_spec::source::{Node, Span, Value};
pub use optobus_spec::Diagnostic;

/// Rule name of reading errors.
pub const RULE: &str = "bus-file";
/// The help of a reading error that has none of its own.
pub const HELP: &str =
    "the bus file schema lists the keys a bus file takes (`optobus bus schema` prints it)";

/// What the bus file's syntax errors call it.
pub(super) const BUS_FILE: FileKind = FileKind {
    a: "a bus file",
    plural: "bus files",
    not_yaml: "the bus file is not valid YAML",
};

/// Why a text is not a duration at all (as opposed to one out of bounds).
pub(super) const NOT_A_DURATION: &str = "is not a duration";

/// Reads part of a bus file's tree, collecting every problem with its place (as a
/// [`Diagnostic`] of rule [`RULE`]).
pub struct Reader<'a> {
    pub(super) base: &'a Path,
    pub(super) diagnostics: Vec<Diagnostic>,
}

/// The reader of the bus file's own parts: the kit and the models its devices name.
pub(super) struct FileReader<'a> {
    pub(super) kit: Reader<'a>,
    pub(super) catalogue: &'a Catalogue,
}

impl<'a> Deref for FileReader<'a> {
    type Target = Reader<'a>;

    fn deref(&self) -> &Self::Target {
        &self.kit
    }
}

impl DerefMut for FileReader<'_> {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.kit
    }
}

/// The diagnostic for an empty file.
pub(super) fn empty() -> Diagnostic {
    Diagnostic::at_start(RULE, "the bus file is empty").help(
        "a bus file has `lines` and `devices`; the bus file schema lists its keys \
         (`optobus bus schema` prints it)",
    )
}

/// The diagnostic for a file some item of which did not read, without a word why.
pub(super) fn incomplete() -> Diagnostic {
    Diagnostic::at_start(RULE, "the bus file did not read whole").help(HELP)
}

impl<'a> FileReader<'a> {
    pub(super) fn new(base: &'a Path, catalogue: &'a Catalogue) -> Self {
        Self {
            kit: Reader::new(base),
            catalogue,
        }
    }
}

impl<'a> Reader<'a> {
    /// A reader of a bus file in the folder `base` (paths the file gives are relative to it).
    pub fn new(base: &'a Path) -> Self {
        Self {
            base,
            diagnostics: Vec::new(),
        }
    }

    /// The bus file's folder.
    pub fn base(&self) -> &'a Path {
        self.base
    }

    /// The problems reported so far, in the order they were.
    pub fn diagnostics(&self) -> &[Diagnostic] {
        &self.diagnostics
    }

    /// Reports a problem at `span`, with a help line.
    pub fn error(&mut self, span: Span, message: impl Into<String>, help: impl Into<String>) {
        self.diagnostics
            .push(Diagnostic::at_span(RULE, span, message).help(help));
    }

    /// Reports `diagnostic` as it is.
    pub fn report(&mut self, diagnostic: Diagnostic) {
        self.diagnostics.push(diagnostic);
    }

    /// The entries of `node`, checked against `allowed` keys (each unknown or repeated key
    /// reported), or an error saying `what` must be a mapping.
    pub fn mapping<'n>(
        &mut self,
        node: &'n Node,
        what: &str,
        allowed: &[&str],
    ) -> Option<&'n [(Node, Node)]> {
        let Some(pairs) = node.entries() else {
            self.error(
                node.span,
                format!("{what} must be a mapping, not {}", node.kind()),
                HELP,
            );
            return None;
        };
        check_keys(pairs, allowed, |problem| match problem {
            KeyProblem::NotText { key } => {
                self.error(key.span, format!("{what} has a key that is not text"), HELP);
            }
            // A key given twice is repeated, whether it is known or not.
            KeyProblem::Repeated {
                name, key, first, ..
            } => self.diagnostics.push(
                Diagnostic::at_span(RULE, key.span, format!("{what} has `{name}` twice"))
                    .label("repeated key")
                    .also_at(first, "first given here")
                    .help("give each key once"),
            ),
            KeyProblem::Unknown { name, key } => {
                let keys = format!("its keys are {}", quoted(allowed));
                let help = match did_you_mean(name, allowed.iter().copied()) {
                    Some(near) => format!("{near} {keys}"),
                    None => keys,
                };
                self.error(key.span, format!("{what} has no key `{name}`"), help);
            }
        });
        Some(pairs)
    }

    /// The items of a list, or an error.
    pub fn list<'n>(&mut self, node: &'n Node, what: &str) -> Option<&'n [Node]> {
        let items = node.items();
        if items.is_none() {
            self.error(
                node.span,
                format!("{what} must be a list, not {}", node.kind()),
                HELP,
            );
        }
        items
    }

    /// The text of a scalar, or an error.
    pub fn text<'n>(&mut self, node: &'n Node, what: &str) -> Option<&'n str> {
        let text = node.scalar();
        if text.is_none() {
            self.error(
                node.span,
                format!("{what} must be text, not {}", node.kind()),
                HELP,
            );
        }
        text
    }

    /// A whole number (decimal or `0x` hex) within `range`, or an error.
    pub fn number<T: TryFrom<u64>>(
        &mut self,
        node: &Node,
        what: &str,
        range: (u64, u64),
    ) -> Option<T> {
        let text = self.text(node, what)?;
        let value = parse_integer(text).filter(|v| (range.0..=range.1).contains(v));
        match value.and_then(|v| T::try_from(v).ok()) {
            Some(value) => Some(value),
            None => {
                self.error(
                    node.span,
                    format!(
                        "{what} must be a whole number from {} to {}, not `{text}`",
                        range.0, range.1
                    ),
                    HELP,
                );
                None
            }
        }
    }

    /// `true` or `false`, or an error.
    pub fn boolean(&mut self, node: &Node, what: &str) -> Option<bool> {
        match node.scalar() {
            Some("true") => Some(true),
            Some("false") => Some(false),
            _ => {
                self.error(node.span, format!("{what} must be true or false"), HELP);
                None
            }
        }
    }

    /// A duration like `200ms`, `1.5s`, `1s 500ms`, within `min ..= MAX_DURATION`.
    pub fn duration(&mut self, node: &Node, what: &str, min: Duration) -> Option<Duration> {
        let text = self.text(node, what)?;
        match parse_duration(text) {
            Ok(duration) if duration < min => {
                self.error(
                    node.span,
                    format!(
                        "{what} must be more than {}",
                        show(min.saturating_sub(Duration::from_nanos(1)))
                    ),
                    "e.g. 100ms, 1.5s, 2m",
                );
                None
            }
            Ok(duration) if duration > MAX_DURATION => {
                self.error(
                    node.span,
                    format!("{what} `{text}` is too long: at most 24h"),
                    "e.g. 100ms, 1.5s, 2m",
                );
                None
            }
            Ok(duration) => Some(duration),
            Err(why) => {
                self.error(
                    node.span,
                    format!("{what} `{text}` {why}"),
                    "e.g. 100ms, 1.5s, 2m",
                );
                None
            }
        }
    }
}

/// Why a spec file a device names cannot be used, as the bus file's diagnostics say it.
pub(super) fn spec_refusal(error: &SpecError) -> String {
    match error {
        SpecError::Rejected(rejected) => format!(
            "it does not pass the spec checks:\n{}",
            rejected.render().trim_end()
        ),
        SpecError::Read { .. } => error.to_string(),
    }
}

/// `a`, `b` and `c` in backquotes.
pub(super) fn quoted(names: &[&str]) -> String {
    names
        .iter()
        .map(|n| format!("`{n}`"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A port alone (on 127.0.0.1), `localhost:PORT`, or `IP:PORT`.
pub fn listen_address(text: &str) -> Option<std::net::SocketAddr> {
    let text = text.trim();
    if let Ok(port) = text.parse::<u16>() {
        return Some(std::net::SocketAddr::from(([127, 0, 0, 1], port)));
    }
    if let Some(port) = text.strip_prefix("localhost:") {
        return Some(std::net::SocketAddr::from((
            [127, 0, 0, 1],
            port.parse().ok()?,
        )));
    }
    text.parse().ok()
}

/// Whether `address` ends in `:PORT` after a host (a port from 1 to 65535).
pub fn has_port(address: &str) -> bool {
    address
        .rsplit_once(':')
        .is_some_and(|(host, port)| !host.is_empty() && port.parse::<u16>().is_ok_and(|p| p > 0))
}

fn parse_integer(text: &str) -> Option<u64> {
    let text = text.trim();
    match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => u64::from_str_radix(hex, 16).ok(),
        None => text.parse().ok(),
    }
}

/// A friendly duration (`200ms`, `1.5s`, `1s 500ms`, `2m`); a bare number is refused, since a
/// unit cannot be guessed safely.
pub(crate) fn parse_duration(text: &str) -> Result<Duration, &'static str> {
    let text = text.trim();
    if !text.is_empty() && text.bytes().all(|b| b.is_ascii_digit() || b == b'.') {
        return Err("needs a unit (ms, s, m, h)");
    }
    let signed: SignedDuration = text.parse().map_err(|_| NOT_A_DURATION)?;
    if signed.is_negative() {
        return Err("cannot be negative");
    }
    Duration::try_from(signed).map_err(|_| "is too long: at most 24h")
}

/// A duration as people write it.
pub(crate) fn show(duration: Duration) -> String {
    let signed = SignedDuration::try_from(duration).unwrap_or(SignedDuration::MAX);
    format!("{signed:#}")
}
