//! The optobus spec compiler.
//!
//! A spec goes through three layers: **parse** (`syntax`: serde structs, unknown keys
//! rejected), **lower and validate** (`lower` builds the [`model::Model`]; [`rules`] is a list
//! of small named checks), and **emit** ([`emit`]: Rust source, formatted with prettyplease
//! under feature `pretty`; `json`, feature `json`: the checked model for other tools). Every
//! problem is a [`Diagnostic`] that points at the spec's line and column and is rendered like
//! rustc.
//!
//! Features: none for a driver's `build.rs` (the fewest dependencies); `cli` (default) builds
//! the `optobus-codegen` binary and turns on `json` and `pretty`.
#![forbid(unsafe_code)]

pub mod diagnostic;
pub mod emit;
#[cfg(feature = "json")]
pub mod json;
mod lower;
pub mod model;
pub mod rules;
pub mod source;
mod syntax;

pub use diagnostic::{render_all, Diagnostic};
pub use model::Model;
pub use source::SourceFile;

/// A spec that did not pass: its source and every problem found.
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

/// Parses, lowers and checks a spec given as text; `name` is shown in diagnostics.
pub fn check_source(name: &str, text: &str) -> Result<Model, Box<Rejected>> {
    let source = SourceFile::new(name, text);
    let spec: syntax::SpecFile = match serde_yaml::from_str(text) {
        Ok(spec) => spec,
        Err(error) => {
            let location = match error.location() {
                Some(at) => diagnostic::Location::Position {
                    line: at.line(),
                    column: at.column(),
                },
                None => diagnostic::Location::Value(source::Path::root()),
            };
            let message = error.to_string();
            // serde_yaml appends " at line L column C"; the arrow already says where.
            let message = message
                .split(" at line ")
                .next()
                .unwrap_or(&message)
                .to_owned();
            let diagnostic = Diagnostic {
                rule: "yaml",
                message,
                primary: diagnostic::Label {
                    location,
                    text: String::new(),
                },
                secondary: Vec::new(),
                help: Some("see specs/README.md for the keys and forms a spec takes".into()),
            };
            return Err(Box::new(Rejected {
                source,
                diagnostics: vec![diagnostic],
            }));
        }
    };
    let (model, mut diagnostics) = lower::lower(spec, &source);
    diagnostics.extend(rules::check(&model));
    if diagnostics.is_empty() {
        Ok(model)
    } else {
        Err(Box::new(Rejected {
            source,
            diagnostics,
        }))
    }
}

/// Reads and checks a spec file.
pub fn check_file(path: &std::path::Path) -> Result<Model, Box<Rejected>> {
    let name = path.display().to_string();
    match std::fs::read_to_string(path) {
        Ok(text) => check_source(&name, &text),
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
