//! Generates the driver from `specs/ccf.yaml`; editing the spec rebuilds this crate only.

fn main() {
    // A link to the workspace's `specs/ccf.yaml`, so that the package carries its spec.
    let spec = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("specs/ccf.yaml");
    optobus_codegen::build_script(&spec, "ccf");
}
