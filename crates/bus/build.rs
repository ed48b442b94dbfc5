//! Whether pymodbus is installed, for the test that reads the gateway with it (see
//! optobus-testkit): without it that test is listed as ignored, with the reason.

use optobus_testkit::build::{peers, PYMODBUS};

fn main() {
    peers(&[PYMODBUS]);
}
