//! Runtime of the generated optobus drivers.
#![forbid(unsafe_code)]
