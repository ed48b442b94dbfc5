//! The optobus spec front end: spec files to the checked model and located diagnostics.
//!
//! A spec goes through two layers: **parse** ([`source`]: one bounded file read and one YAML
//! parse into a tree that keeps positions; `syntax`: the spec's structs read from that tree,
//! every reading error reported at once) and **lower and validate** (`lower` builds the
//! [`model::Model`]; [`rules`] is a list of small named checks). Every problem is a
//! [`Diagnostic`] that points at the file's line and column and is rendered like rustc.
//! [`describe()`] turns a checked model into the run-time description the generated crates
//! carry.
//!
//! The positioned tree ([`source::Node`]) and the bounded reader ([`source::read_yaml`],
//! [`source::open_limited`]) are not tied to specs: the bus reads its bus files with them.
//! The Rust emitter is `optobus-codegen`, above this crate; nothing here depends on `quote`,
//! `proc-macro2` or `syn`.
#![forbid(unsafe_code)]

pub mod catalogue;
pub mod describe;
pub mod diagnostic;
mod lower;
pub mod model;
pub mod reading;
pub mod rules;
pub mod source;
mod syntax;

pub use catalogue::{Catalogue, SpecError};
pub use describe::{describe, description, Description};
pub use diagnostic::{render_all, Diagnostic, DiagnosticReport, RelatedPlace};
pub use model::Model;
pub use source::SourceFile;

/// A spec (or another file read through [`SourceFile`], such as a bus file) that did not
/// pass: its source and every problem found.
#[derive(Debug)]
pub struct Rejected {
    /// The spec text (for rendering).
    pub source: SourceFile,
    /// All problems, in rule order.
    pub diagnostics: Vec<Diagnostic>,
}

impl Rejected {
    /// The diagnostics rendered like rustc.
    pub fn render(&self) -> String {
        render_all(&self.diagnostics, &self.source)
    }

    /// Each diagnostic as a checking tool reports it in JSON, placed in `source` and named
    /// as being in `file`.
    pub fn reports(&self, file: &str) -> Vec<DiagnosticReport> {
        let source = &self.source;
        self.diagnostics
            .iter()
            .map(|diagnostic| diagnostic.report(source, file))
            .collect()
    }
}

impl std::fmt::Display for Rejected {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.render().trim_end())
    }
}

impl std::error::Error for Rejected {}

/// Parses, lowers and checks a spec given as text; `name` is shown in diagnostics.
pub fn check_source(name: &str, text: &str) -> Result<Model, Box<Rejected>> {
    check_text(name, text.to_owned())
}

/// [`check_source`] of a text already owned (a file's, which need not be copied).
fn check_text(name: &str, text: String) -> Result<Model, Box<Rejected>> {
    let source = SourceFile::new(name, text);
    let reject = |source, diagnostics| {
        Err(Box::new(Rejected {
            source,
            diagnostics,
        }))
    };
    if let Some(error) = &source.syntax_error {
        let diagnostic = Diagnostic::from(error);
        return reject(source, vec![diagnostic]);
    }
    let mut diagnostics = rules::text::check(&source);
    let mut reader = syntax::Reader::default();
    let spec = source
        .root
        .as_ref()
        .and_then(|root| syntax::read(root, &mut reader));
    diagnostics.append(&mut reader.diagnostics);
    let Some(spec) = spec else {
        if diagnostics.is_empty() {
            diagnostics.push(Diagnostic::at(
                syntax::RULE,
                &source::Path::root(),
                "the file holds no spec",
            ));
        }
        return reject(source, diagnostics);
    };
    let (model, lowering) = lower::lower(spec);
    diagnostics.extend(lowering);
    diagnostics.extend(rules::check(&model));
    if diagnostics.is_empty() {
        Ok(model)
    } else {
        reject(source, diagnostics)
    }
}

/// Reads and checks a spec file (at most [`source::YAML_LIMIT`] bytes, see
/// [`source::read_yaml`]).
pub fn check_file(path: &std::path::Path) -> Result<Model, Box<Rejected>> {
    let name = path.display().to_string();
    match source::read_yaml(path) {
        Ok(text) => check_text(&name, text),
        Err(error) => Err(Box::new(Rejected {
            source: SourceFile::new(name.clone(), ""),
            diagnostics: vec![Diagnostic::at(
                "io",
                &source::Path::root(),
                format!("cannot read {name}: {error}"),
            )],
        })),
    }
}
