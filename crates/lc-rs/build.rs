//! Generates the driver from `specs/lc_rs.yaml`; editing the spec rebuilds this crate only.

fn main() {
    // A link to the workspace's `specs/lc_rs.yaml`, so that the package carries its spec.
    let spec = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("specs/lc_rs.yaml");
    optobus_codegen::build_script(&spec, "lc_rs");
}
