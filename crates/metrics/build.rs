//! Whether promtool is installed, for the tests that check the exposition with it (see
//! optobus-testkit): without it they are listed as ignored, with the reason.

fn main() {
    optobus_testkit::build::peers(&[optobus_testkit::build::PROMTOOL]);
}
