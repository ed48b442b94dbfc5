//! Whether mosquitto and promtool are installed, for the test of MQTT's counts on /metrics
//! (see optobus-testkit): without them it is listed as ignored, with the reason.

fn main() {
    use optobus_testkit::build::{peers, MOSQUITTO, PROMTOOL};
    peers(&[MOSQUITTO, PROMTOOL]);
}
