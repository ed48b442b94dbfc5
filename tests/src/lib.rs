//! Shared fixtures for optobus's cross-crate tests.
//!
//! [`golden`] loads the example frames printed in the vendor manuals (`tests/golden/*.yaml`,
//! format in `tests/golden/FORMAT.md`), so that every suite can replay real bytes.
#![forbid(unsafe_code)]

pub mod golden;
