//! Diagnostics that point into a spec or another YAML file of the project (a bus file),
//! rendered in the style of rustc.

use std::fmt::Write as _;

use crate::source::{Path, SourceFile, Span, SyntaxError};

/// Where a label points.
#[derive(Clone, Debug)]
pub enum Location {
    /// The value at a YAML path.
    Value(Path),
    /// The key naming the value at a YAML path.
    Key(Path),
    /// A place in the tree the reader was looking at.
    Span(Span),
    /// A position reported by the YAML parser.
    Position {
        /// Line, from 1.
        line: usize,
        /// Column, from 1.
        column: usize,
    },
}

/// A message attached to a location.
#[derive(Clone, Debug)]
pub struct Label {
    /// Where.
    pub location: Location,
    /// What to say there (may be empty).
    pub text: String,
}

impl Label {
    /// Where the label points in `source`, as rendered (line and column from 1, width in
    /// characters); `None` for a path the source does not hold.
    pub fn place(&self, source: &SourceFile) -> Option<Span> {
        resolve(source, &self.location)
    }
}

/// One problem in a spec.
#[derive(Clone, Debug)]
pub struct Diagnostic {
    /// The rule that found it (`duplicate-name`, `yaml`, …).
    pub rule: &'static str,
    /// One line saying what is wrong.
    pub message: String,
    /// The offending text.
    pub primary: Label,
    /// Related places ("first defined here").
    pub secondary: Vec<Label>,
    /// How to fix it.
    pub help: Option<String>,
}

/// Text that is not YAML, at the place the parser stopped, whatever the file is.
impl From<&SyntaxError> for Diagnostic {
    fn from(error: &SyntaxError) -> Self {
        Self {
            rule: error.rule,
            message: error.message.clone(),
            primary: Label {
                location: Location::Position {
                    line: error.line,
                    column: error.column,
                },
                text: String::new(),
            },
            secondary: Vec::new(),
            help: Some(error.help.into()),
        }
    }
}

/// A diagnostic as a checking tool reports it in JSON (`optobus bus check --json`): severity,
/// rule, message, file, line, column (from 1; `null` when it has no place), the primary
/// label, help, and the places it refers to besides.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct DiagnosticReport {
    /// Always `error`: every rule refuses the file.
    pub severity: &'static str,
    /// The rule that found it.
    pub rule: &'static str,
    /// One line saying what is wrong.
    pub message: String,
    /// The file, as the user named it.
    pub file: String,
    /// Line, from 1.
    pub line: Option<usize>,
    /// Column, from 1, in characters.
    pub column: Option<usize>,
    /// What the primary label says (may be empty).
    pub label: String,
    /// How to fix it.
    pub help: Option<String>,
    /// The related places the source holds.
    pub related: Vec<RelatedPlace>,
}

/// A related place of a [`DiagnosticReport`].
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct RelatedPlace {
    /// Line, from 1.
    pub line: usize,
    /// Column, from 1, in characters.
    pub column: usize,
    /// What the label says there.
    pub label: String,
}

impl Diagnostic {
    /// This diagnostic placed in `source`, reported as being in `file`.
    pub fn report(&self, source: &SourceFile, file: &str) -> DiagnosticReport {
        let place = self.primary.place(source);
        let related = self
            .secondary
            .iter()
            .filter_map(|label| {
                let place = label.place(source)?;
                Some(RelatedPlace {
                    line: place.line,
                    column: place.column,
                    label: label.text.clone(),
                })
            })
            .collect();
        DiagnosticReport {
            severity: "error",
            rule: self.rule,
            message: self.message.clone(),
            file: file.to_owned(),
            line: place.map(|p| p.line),
            column: place.map(|p| p.column),
            label: self.primary.text.clone(),
            help: self.help.clone(),
            related,
        }
    }

    /// A diagnostic at the value of `path`.
    pub fn at(rule: &'static str, path: &Path, message: impl Into<String>) -> Self {
        Self {
            rule,
            message: message.into(),
            primary: Label {
                location: Location::Value(path.clone()),
                text: String::new(),
            },
            secondary: Vec::new(),
            help: None,
        }
    }

    /// A diagnostic at a place of the tree a reader was looking at.
    pub fn at_span(rule: &'static str, span: Span, message: impl Into<String>) -> Self {
        Self {
            rule,
            message: message.into(),
            primary: Label {
                location: Location::Span(span),
                text: String::new(),
            },
            secondary: Vec::new(),
            help: None,
        }
    }

    /// A diagnostic about a whole file, at its first line and column (an empty file, one
    /// that did not read whole).
    pub fn at_start(rule: &'static str, message: impl Into<String>) -> Self {
        Self {
            rule,
            message: message.into(),
            primary: Label {
                location: Location::Position { line: 1, column: 1 },
                text: String::new(),
            },
            secondary: Vec::new(),
            help: None,
        }
    }

    /// Sets the primary label's text.
    pub fn label(mut self, text: impl Into<String>) -> Self {
        self.primary.text = text.into();
        self
    }

    /// Adds a secondary label at the value of `path`.
    pub fn also(mut self, path: &Path, text: impl Into<String>) -> Self {
        self.secondary.push(Label {
            location: Location::Value(path.clone()),
            text: text.into(),
        });
        self
    }

    /// Adds a secondary label at a place of the tree.
    pub fn also_at(mut self, span: Span, text: impl Into<String>) -> Self {
        self.secondary.push(Label {
            location: Location::Span(span),
            text: text.into(),
        });
        self
    }

    /// Adds a help line.
    pub fn help(mut self, text: impl Into<String>) -> Self {
        self.help = Some(text.into());
        self
    }

    /// Renders the diagnostic against its source, like rustc.
    pub fn render(&self, source: &SourceFile) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "error[{}]: {}", self.rule, self.message);
        let primary = resolve(source, &self.primary.location);
        let secondary: Vec<(Option<Span>, &str)> = self
            .secondary
            .iter()
            .map(|label| (resolve(source, &label.location), label.text.as_str()))
            .collect();
        let gutter = std::iter::once(primary)
            .chain(secondary.iter().map(|(span, _)| *span))
            .flatten()
            .map(|span| span.line.to_string().len())
            .max()
            .unwrap_or(1);
        let pad = " ".repeat(gutter);
        match primary {
            Some(span) => {
                let _ = writeln!(
                    out,
                    "{pad}--> {}:{}:{}",
                    source.name, span.line, span.column
                );
                snippet(&mut out, source, span, '^', &self.primary.text, gutter);
            }
            None => {
                let _ = writeln!(out, "{pad}--> {}", source.name);
            }
        }
        for (span, text) in secondary {
            if let Some(span) = span {
                let _ = writeln!(
                    out,
                    "{pad}::: {}:{}:{}",
                    source.name, span.line, span.column
                );
                snippet(&mut out, source, span, '-', text, gutter);
            }
        }
        if let Some(help) = &self.help {
            let _ = writeln!(out, "{pad} = help: {help}");
        }
        out
    }
}

fn resolve(source: &SourceFile, location: &Location) -> Option<Span> {
    match location {
        Location::Value(path) => source.span(path),
        Location::Key(path) => source.key_span(path).or_else(|| source.span(path)),
        Location::Span(span) => Some(*span),
        Location::Position { line, column } => {
            // Underline the token the parser stopped at; it may stop at the blank before it.
            let text = source.line(*line).unwrap_or_default();
            let rest = text.chars().skip(column.saturating_sub(1));
            let blanks = rest.clone().take_while(|c| *c == ' ').count();
            let token = rest
                .skip(blanks)
                .take_while(|c| !c.is_whitespace() && !matches!(c, ':' | ',' | '}' | ']'))
                .count();
            let at_token = blanks
                < text
                    .chars()
                    .count()
                    .saturating_sub(column.saturating_sub(1));
            Some(Span {
                line: *line,
                column: if at_token { column + blanks } else { *column },
                width: token.max(1),
            })
        }
    }
}

fn snippet(
    out: &mut String,
    source: &SourceFile,
    span: Span,
    mark: char,
    text: &str,
    gutter: usize,
) {
    let pad = " ".repeat(gutter);
    let line = source.line(span.line).unwrap_or("");
    let line_len = line.chars().count();
    let start = span.column.saturating_sub(1).min(line_len);
    let width = span.width.min(line_len.saturating_sub(start)).max(1);
    let _ = writeln!(out, "{pad} |");
    let _ = writeln!(out, "{:>gutter$} | {line}", span.line);
    let prefix: String = line
        .chars()
        .take(start)
        .map(|c| if c == '\t' { '\t' } else { ' ' })
        .collect();
    let marks: String = std::iter::repeat_n(mark, width).collect();
    let text = if text.is_empty() {
        String::new()
    } else {
        format!(" {text}")
    };
    let _ = writeln!(out, "{pad} | {prefix}{marks}{text}");
}

/// Renders every diagnostic, followed by a count.
pub fn render_all(diagnostics: &[Diagnostic], source: &SourceFile) -> String {
    let mut out = String::new();
    for diagnostic in diagnostics {
        out.push_str(&diagnostic.render(source));
        out.push('\n');
    }
    let count = diagnostics.len();
    let _ = writeln!(
        out,
        "error: {} has {count} error{}",
        source.name,
        if count == 1 { "" } else { "s" }
    );
    out
}
