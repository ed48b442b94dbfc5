//! The demo bus: a sensor of every built-in model on one simulated RS-485 line at 115200
//! baud, polled by the bus, with a Modbus TCP gateway onto the line on 127.0.0.1:5020 so that
//! other tools (mbpoll, a PLC, pymodbus) can read the same sensors meanwhile.

use optobus_bus::{BusFile, Catalogue, Rejected};

/// The demo's bus file (YAML).
pub const DEMO: &str = include_str!("../demo.yaml");

/// The demo's bus, its models taken from `catalogue` (which must know every built-in one).
pub fn bus(catalogue: &Catalogue) -> Result<BusFile, Box<Rejected>> {
    BusFile::parse("demo.yaml", DEMO, ".".as_ref(), catalogue)
}
