//! `optobus-codegen`: check specs, dump their checked model, or generate Rust.
//!
//! ```text
//! optobus-codegen check specs/*.yaml          diagnostics; exit 1 on any error
//! optobus-codegen dump --json specs/x.yaml    the checked model as JSON
//! optobus-codegen generate specs/x.yaml [-o out.rs]
//! optobus-codegen new specs/x.yaml            the driver crate crates/x/ (never overwrites)
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

const USAGE: &str = "usage:
  optobus-codegen check <spec.yaml>...
  optobus-codegen dump --json <spec.yaml>
  optobus-codegen generate <spec.yaml> [-o <out.rs>]
  optobus-codegen new <specs/family.yaml>";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("check") if args.len() > 1 => check(&args[1..]),
        Some("dump") => match &args[1..] {
            [flag, path] if flag == "--json" => dump(path),
            _ => usage(),
        },
        Some("generate") => match &args[1..] {
            [path] => generate(path, None),
            [path, flag, out] if flag == "-o" || flag == "--out" => {
                generate(path, Some(out.into()))
            }
            _ => usage(),
        },
        Some("new") => match &args[1..] {
            [path] => new(path),
            _ => usage(),
        },
        _ => usage(),
    }
}

fn usage() -> ExitCode {
    eprintln!("{USAGE}");
    ExitCode::from(2)
}

fn check(paths: &[String]) -> ExitCode {
    let mut failed = false;
    for (i, path) in paths.iter().enumerate() {
        match optobus_spec::check_file(path.as_ref()) {
            Ok(model) => {
                eprintln!(
                    "ok: {path}: {} registers, {} enums, {} commands, {} groups",
                    model.registers.len(),
                    model.enums.len(),
                    model.commands.len(),
                    model.groups.len()
                );
                // The process ends after the last file: freeing its model one allocation at
                // a time would take a quarter of the check of 100,000 registers.
                if i + 1 == paths.len() {
                    std::mem::forget(model);
                }
            }
            Err(rejected) => {
                failed = true;
                eprint!("{}", rejected.render());
            }
        }
    }
    if failed {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    }
}

fn dump(path: &str) -> ExitCode {
    match optobus_spec::check_file(path.as_ref()) {
        Ok(model) => {
            let text = serde_json::to_string_pretty(&optobus_codegen::json::dump(&model))
                .unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"));
            println!("{text}");
            ExitCode::SUCCESS
        }
        Err(rejected) => {
            eprint!("{}", rejected.render());
            ExitCode::from(1)
        }
    }
}

fn generate(path: &str, out: Option<PathBuf>) -> ExitCode {
    let model = match optobus_spec::check_file(path.as_ref()) {
        Ok(model) => model,
        Err(rejected) => {
            eprint!("{}", rejected.render());
            return ExitCode::from(1);
        }
    };
    let spec_name = std::path::Path::new(path)
        .file_name()
        .map_or_else(|| path.to_owned(), |n| n.to_string_lossy().into_owned());
    let code = optobus_codegen::emit::generate(&model, &spec_name);
    match out {
        Some(out) => match std::fs::write(&out, code) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("error: cannot write {}: {e}", out.display());
                ExitCode::from(1)
            }
        },
        None => {
            print!("{code}");
            ExitCode::SUCCESS
        }
    }
}

/// Checks the spec and writes its driver crate next to `specs/`: `<root>/crates/<family>/`.
fn new(path: &str) -> ExitCode {
    let spec = std::path::Path::new(path);
    let model = match optobus_spec::check_file(spec) {
        Ok(model) => model,
        Err(rejected) => {
            eprint!("{}", rejected.render());
            return ExitCode::from(1);
        }
    };
    // The crate's build.rs reads `../../specs/<family>.yaml`: the spec must be that file.
    let expected = format!("{}.yaml", model.family);
    let folder = spec.parent().and_then(|p| p.file_name());
    if spec.file_name().is_none_or(|n| *n != *expected) || folder.is_none_or(|f| f != "specs") {
        eprintln!(
            "error: the spec of family `{}` must be specs/{expected}",
            model.family
        );
        return ExitCode::from(1);
    }
    let root = spec
        .parent()
        .and_then(std::path::Path::parent)
        .unwrap_or(std::path::Path::new(""));
    match optobus_codegen::scaffold::write(&model, root) {
        Ok(dir) => {
            eprintln!(
                "created {}: cargo build -p optobus-{}",
                dir.display(),
                model.family.replace('_', "-")
            );
            ExitCode::SUCCESS
        }
        Err(error) => {
            eprintln!("error: {error}");
            ExitCode::from(1)
        }
    }
}
