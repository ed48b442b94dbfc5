//! Whether mosquitto and openssl are installed, for the tests with a real broker (see
//! optobus-testkit): without them they are listed as ignored, with the reason.

use optobus_testkit::build::{peers, MOSQUITTO, OPENSSL};

fn main() {
    peers(&[MOSQUITTO, OPENSSL]);
}
