//! Generates the driver from `specs/p_series.yaml`; editing the spec rebuilds this crate only.

fn main() {
    // A link to the workspace's `specs/p_series.yaml`, so that the package carries its spec.
    let spec = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("specs/p_series.yaml");
    optobus_codegen::build_script(&spec, "p_series");
}
