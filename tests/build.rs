//! Generates the Rust of every spec into OUT_DIR, so that `generated_code.rs` can compile it
//! under `#![deny(missing_docs, warnings)]` (until each family has its own driver crate).

use std::path::{Path, PathBuf};

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let specs = ["p_series", "rangefinder", "ccs", "lc_rs", "ccf"]
        .map(|family| (family, root.join("specs").join(format!("{family}.yaml"))));
    let mini = ("mini", root.join("codegen/tests/fixtures/mini.yaml"));
    for (name, spec) in specs.into_iter().chain([mini]) {
        println!("cargo::rerun-if-changed={}", spec.display());
        let model = match optobus_codegen::check_file(&spec) {
            Ok(model) => model,
            Err(rejected) => {
                eprint!("{}", rejected.render());
                panic!("{} does not pass `optobus-codegen check`", spec.display());
            }
        };
        let file_name = spec
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let code = optobus_codegen::emit::generate(&model, &file_name);
        std::fs::write(out.join(format!("{name}.rs")), code).expect("write generated code");
    }
}
