//! Generates the Rust of the `mini` test spec into OUT_DIR, so that `generated_code.rs` can
//! compile it under `#![deny(missing_docs, warnings)]` next to the five driver crates.

use std::path::Path;

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    optobus_codegen::build_script(&root.join("codegen/tests/fixtures/mini.yaml"), "mini");
}
