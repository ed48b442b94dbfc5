//! Generates the driver from `specs/lc_rs.yaml`; editing the spec rebuilds this crate only.

fn main() {
    let spec = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../specs/lc_rs.yaml");
    optobus_codegen::build_script(&spec, "lc_rs");
}
