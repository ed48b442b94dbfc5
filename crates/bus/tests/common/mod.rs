//! What the bus's tests share: a bus file read from text with the models they name.

#![allow(dead_code, unreachable_pub)]

pub mod gateway;

use std::path::Path;

use optobus_bus::{BusFile, Catalogue};

/// `text` read as a bus file naming the P series and the CCS; a mistake in it fails the test
/// with the rendered message.
pub fn file(text: &str) -> BusFile {
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE, &optobus_ccs::DEVICE]);
    BusFile::parse("bus.yaml", text, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()))
}
