//! Generates the driver from `specs/p_series.yaml`; editing the spec rebuilds this crate only.

fn main() {
    let spec = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../specs/p_series.yaml");
    optobus_codegen::build_script(&spec, "p_series");
}
