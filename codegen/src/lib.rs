//! The optobus spec compiler.
//!
//! A spec goes through three layers: **parse** ([`source`]: one YAML parse into a tree
//! that keeps positions; `syntax`: the spec's structs read from that tree, every reading
//! error reported at once), **lower and validate** (`lower` builds the [`model::Model`];
//! [`rules`] is a list of small named checks), and **emit** ([`emit`]: Rust source, formatted
//! with prettyplease under feature `pretty`; `json`, feature `json`: the checked model for
//! other tools). Every problem is a [`Diagnostic`] that points at the spec's line and column
//! and is rendered like rustc. [`describe()`] turns a checked model into the runtime
//! description the generated crates carry; [`scaffold`] writes a driver crate.
//!
//! Features: none for a driver's `build.rs` (the fewest dependencies); `cli` (default) builds
//! the `optobus-codegen` binary and turns on `json` and `pretty`.
#![forbid(unsafe_code)]

pub mod describe;
pub mod diagnostic;
pub mod emit;
#[cfg(feature = "json")]
pub mod json;
mod lower;
pub mod model;
pub mod rules;
pub mod scaffold;
pub mod source;
mod syntax;

pub use describe::describe;
pub use diagnostic::{render_all, Diagnostic};
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
        let diagnostic = Diagnostic {
            rule: error.rule,
            message: error.message.clone(),
            primary: diagnostic::Label {
                location: diagnostic::Location::Position {
                    line: error.line,
                    column: error.column,
                },
                text: String::new(),
            },
            secondary: Vec::new(),
            help: Some(error.help.into()),
        };
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

/// For a driver crate's `build.rs`: checks `spec`, writes its generated Rust to
/// `$OUT_DIR/<out_name>.rs` and tells cargo to rerun only when the spec changes. A spec that
/// does not pass is reported like `optobus-codegen check` does, and fails the build.
pub fn build_script(spec: &std::path::Path, out_name: &str) {
    println!("cargo::rerun-if-changed={}", spec.display());
    let model = match check_file(spec) {
        Ok(model) => model,
        Err(rejected) => {
            eprint!("{}", rejected.render());
            println!(
                "cargo::error={} does not pass `optobus-codegen check` (diagnostics above)",
                spec.display()
            );
            return;
        }
    };
    let file_name = spec
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let code = emit::generate(&model, &file_name);
    let Some(out_dir) = std::env::var_os("OUT_DIR") else {
        println!("cargo::error=OUT_DIR is not set: run this from a build script");
        return;
    };
    let out = std::path::Path::new(&out_dir).join(format!("{out_name}.rs"));
    if let Err(error) = std::fs::write(&out, code) {
        println!("cargo::error=cannot write {}: {error}", out.display());
    }
}
