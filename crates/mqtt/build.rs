//! Whether mosquitto, openssl and Jinja2 are installed, for the tests with a real broker and
//! Home Assistant's templates (see
//! optobus-testkit): without them they are listed as ignored, with the reason.

use optobus_testkit::build::{peers, JINJA2, MOSQUITTO, OPENSSL};

fn main() {
    peers(&[MOSQUITTO, OPENSSL, JINJA2]);
}
