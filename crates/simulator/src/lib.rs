//! Virtual optobus devices, driven by a family's generated `DEVICE` description.
#![forbid(unsafe_code)]
