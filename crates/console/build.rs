//! Whether Chromium and chromedriver are installed, for the browser test (see
//! optobus-testkit): without them it is listed as ignored, with the reason.

use optobus_testkit::build::{peers, CHROMEDRIVER, CHROMIUM};

fn main() {
    peers(&[CHROMIUM, CHROMEDRIVER]);
}
