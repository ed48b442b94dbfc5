//! Generates the driver from `specs/rangefinder.yaml`; editing the spec rebuilds this crate only.

fn main() {
    let spec =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../specs/rangefinder.yaml");
    optobus_codegen::build_script(&spec, "rangefinder");
}
