//! Shared fixtures for optobus's cross-crate tests.
//!
//! [`golden`] loads the example frames printed in the vendor manuals (`tests/golden/*.yaml`,
//! format in `tests/golden/FORMAT.md`), so that every suite can replay real bytes. [`specs`]
//! gives each spec's runtime description; [`generated`] has each spec's generated code and the
//! macros that make a suite's per-family cases ([`family_cases!`], [`golden_cases!`]).
#![forbid(unsafe_code)]

pub mod e2e;
pub mod fault_run;
pub mod golden;
pub mod wire;

/// The code generated from every spec in `specs/` (found by `build.rs`), and from the `mini`
/// test spec, each compiled as public library code under `#![deny(missing_docs, warnings)]`.
pub mod generated {
    include!(concat!(env!("OUT_DIR"), "/families.rs"));
}

/// The specs in `specs/`, read while the tests run.
pub mod specs {
    use std::path::{Path, PathBuf};

    use optobus_device::DeviceInfo;

    /// `specs/<family>.yaml`.
    pub fn path(family: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("specs")
            .join(format!("{family}.yaml"))
    }

    /// The checked model of `specs/<family>.yaml`; a spec that does not pass fails the test
    /// with its diagnostics.
    pub fn model(family: &str) -> optobus_spec::Model {
        optobus_spec::check_file(&path(family)).unwrap_or_else(|r| panic!("{}", r.render()))
    }

    /// The runtime description of `specs/<family>.yaml`, as a tool loading the file builds it.
    pub fn describe(family: &str) -> &'static DeviceInfo {
        optobus_spec::describe(&model(family))
    }
}
