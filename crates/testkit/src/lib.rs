//! What the tests of several optobus crates share: which peer programs they talk to (mbpoll,
//! socat, mosquitto, openssl, promtool, Chromium, pymodbus) are installed, decided when the
//! tests are built, promtool's check of a metrics exposition, a mosquitto started on a
//! configuration, the load average benches print beside their figures, the bus files several
//! crates' tests run ([`bus_files`]), and (feature `http`) what the tests of the HTTP
//! listeners share.
//!
//! A crate whose tests need peers calls [`build::peers`] from its build script, which sets the
//! cfg `peer_<name>` for each peer found. Each such test carries
//! `#[cfg_attr(not(peer_mosquitto), ignore = "mosquitto is not installed (Debian package mosquitto)")]`,
//! so without its peer `cargo test` lists it as ignored with that reason, never as passed.
//! `.ci/run` installs every peer and sets [`REQUIRE_PEERS`]: there a missing peer fails the
//! build instead.

pub mod build;
pub mod bus_files;
#[cfg(feature = "http")]
pub mod http;

use std::path::Path;
use std::process::{Child, Command, Stdio};

/// The environment variable that makes every peer mandatory (set by `.ci/run`).
pub const REQUIRE_PEERS: &str = "OPTOBUS_REQUIRE_INTEROP";

/// Starts mosquitto with the configuration file `config`, its output discarded (a test that
/// wants its log names a `log_dest file` in the configuration). A test calling it carries
/// `#[cfg_attr(not(peer_mosquitto), ignore = …)]`.
pub fn spawn_mosquitto(config: &Path) -> Child {
    Command::new("mosquitto")
        .arg("-c")
        .arg(config)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("mosquitto starts (Debian package mosquitto)")
}

/// Asserts that Prometheus's `promtool check metrics` accepts the exposition `text`. A test
/// calling it carries `#[cfg_attr(not(peer_promtool), ignore = …)]`.
pub fn assert_promtool_accepts(text: &str) {
    use std::io::Write;
    let mut check = Command::new("promtool")
        .args(["check", "metrics"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("promtool starts (Debian package prometheus)");
    if let Some(mut input) = check.stdin.take() {
        input
            .write_all(text.as_bytes())
            .expect("promtool reads the text");
    }
    let output = check.wait_with_output().expect("promtool ends");
    assert!(
        output.status.success(),
        "promtool check metrics:\n{}{}\n{text}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
}

/// The machine's load average over the last minute (`/proc/loadavg`), or `?` where there is
/// none: benches print it beside their figures, which a busy machine moves.
pub fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(str::to_owned))
        .unwrap_or_else(|| "?".to_owned())
}
