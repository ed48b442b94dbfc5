//! Generates the driver from `specs/ccs.yaml`; editing the spec rebuilds this crate only.

fn main() {
    // A link to the workspace's `specs/ccs.yaml`, so that the package carries its spec.
    let spec = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("specs/ccs.yaml");
    optobus_codegen::build_script(&spec, "ccs");
}
