//! Shared fixtures for optobus's cross-crate tests.
//!
//! [`golden`] loads the example frames printed in the vendor manuals (`tests/golden/*.yaml`,
//! format in `tests/golden/FORMAT.md`), so that every suite can replay real bytes.
#![forbid(unsafe_code)]

pub mod e2e;
pub mod fault_run;
pub mod golden;

/// The code generated from every spec: the five driver crates, and the `mini` test spec
/// compiled as public library code under `#![deny(missing_docs, warnings)]`.
pub mod generated {
    pub use optobus_ccf as ccf;
    pub use optobus_ccs as ccs;
    pub use optobus_lc_rs as lc_rs;
    pub use optobus_p_series as p_series;
    pub use optobus_rangefinder as rangefinder;

    /// Generated from `codegen/tests/fixtures/mini.yaml`.
    pub mod mini {
        #![deny(missing_docs, warnings)]
        include!(concat!(env!("OUT_DIR"), "/mini.rs"));
    }
}
