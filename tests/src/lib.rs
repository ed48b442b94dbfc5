//! Shared fixtures for optobus's cross-crate tests.
//!
//! [`golden`] loads the example frames printed in the vendor manuals (`tests/golden/*.yaml`,
//! format in `tests/golden/FORMAT.md`), so that every suite can replay real bytes.
#![forbid(unsafe_code)]

pub mod golden;

/// The generator's output for every spec, compiled as public library code under
/// `#![deny(missing_docs, warnings)]` (until each family has its own driver crate).
pub mod generated {
    macro_rules! generated {
        ($($family:ident),*) => {$(
            #[doc = concat!("Generated from `", stringify!($family), ".yaml`.")]
            pub mod $family {
                #![deny(missing_docs, warnings)]
                include!(concat!(env!("OUT_DIR"), "/", stringify!($family), ".rs"));
            }
        )*};
    }

    generated!(p_series, rangefinder, ccs, lc_rs, ccf, mini);
}
