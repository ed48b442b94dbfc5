//! The optobus Rust emitter, above the spec front end (`optobus-spec`).
//!
//! A spec checked by [`optobus_spec`] is written as Rust ([`emit`]: formatted with
//! prettyplease under feature `pretty`), as JSON for other tools (`json`, feature `json`), or
//! as a whole driver crate ([`scaffold`]). [`build_script`] does the check and the writing for
//! a driver crate's `build.rs`.
//!
//! Features: none for a driver's `build.rs` (the fewest dependencies); `cli` (default) builds
//! the `optobus-codegen` binary and turns on `json` and `pretty`.
#![forbid(unsafe_code)]

pub mod emit;
#[cfg(feature = "json")]
pub mod json;
pub mod scaffold;

use optobus_spec::check_file;

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
