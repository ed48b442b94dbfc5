//! What the tests of several optobus crates share: whether a peer program they talk to
//! (mbpoll, socat, mosquitto, openssl, promtool, Chromium) is installed, and promtool's check
//! of a metrics exposition.
//!
//! Locally a test whose peer is missing is skipped and says so; `.ci/run` installs every peer
//! and sets [`REQUIRE_PEERS`], so there a missing peer fails the test instead.

use std::process::{Command, Stdio};

/// The environment variable that makes every peer mandatory (set by `.ci/run`).
pub const REQUIRE_PEERS: &str = "OPTOBUS_REQUIRE_INTEROP";

/// Whether `program` runs (started as `program arg`); when it does not, see [`missing`].
/// `package` is the Debian package that brings it.
pub fn peer_installed(program: &str, arg: &str, package: &str) -> bool {
    let found = Command::new(program)
        .arg(arg)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok();
    if !found {
        missing(program, package);
    }
    found
}

/// Reports the peer `what` (from the Debian package `package`) missing: fails the test under
/// [`REQUIRE_PEERS`], else says the test is skipped.
pub fn missing(what: &str, package: &str) {
    assert!(
        std::env::var_os(REQUIRE_PEERS).is_none(),
        "{what} is not installed (Debian package `{package}`)"
    );
    eprintln!("skipped: {what} is not installed (Debian package `{package}`)");
}

/// Asserts that Prometheus's `promtool check metrics` accepts the exposition `text`; skipped
/// (see [`missing`]) without promtool.
pub fn assert_promtool_accepts(text: &str) {
    use std::io::Write;
    if !peer_installed("promtool", "--version", "prometheus") {
        return;
    }
    let mut check = Command::new("promtool")
        .args(["check", "metrics"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("promtool starts");
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
