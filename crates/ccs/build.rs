//! Generates the driver from `specs/ccs.yaml`; editing the spec rebuilds this crate only.

fn main() {
    let spec = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../specs/ccs.yaml");
    optobus_codegen::build_script(&spec, "ccs");
}
