//! Generates the driver from `specs/lc_rs.yaml`; editing the spec rebuilds this crate only.

fn main() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    optobus_codegen::build_script(&root.join("../../specs/lc_rs.yaml"), "lc_rs");
}
