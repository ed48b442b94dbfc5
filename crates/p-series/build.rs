//! Generates the driver from `specs/p_series.yaml`; editing the spec rebuilds this crate only.

fn main() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    optobus_codegen::build_script(&root.join("../../specs/p_series.yaml"), "p_series");
}
