//! Running the `optobus` binary in tests, and a simulator served by it in the background.

#![allow(dead_code, unreachable_pub)]

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Output, Stdio};

/// The built binary.
pub fn optobus() -> Command {
    let mut command = Command::new(assert_cmd::cargo::cargo_bin!("optobus"));
    command.env("NO_COLOR", "1");
    command
}

/// Runs `optobus args…` to completion.
pub fn run(args: &[&str]) -> Output {
    optobus().args(args).output().expect("run optobus")
}

/// Stdout of a successful run (fails the test with stderr otherwise).
pub fn ok(args: &[&str]) -> String {
    let output = run(args);
    assert!(
        output.status.success(),
        "optobus {args:?} failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// Stderr of a failing run (fails the test if it succeeded).
pub fn fails(args: &[&str]) -> String {
    let output = run(args);
    assert!(
        !output.status.success(),
        "optobus {args:?} should have failed: {}",
        String::from_utf8_lossy(&output.stdout)
    );
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// JSON stdout of a successful run.
pub fn json(args: &[&str]) -> serde_json::Value {
    let mut with_json = args.to_vec();
    with_json.push("--json");
    serde_json::from_str(&ok(&with_json)).expect("valid JSON")
}

/// `optobus simulate …` running in the background; stopped when dropped.
pub struct Served {
    child: Child,
    /// What it printed first: the TCP address or the pty path.
    pub at: String,
}

impl Served {
    pub fn start(args: &[&str]) -> Self {
        let mut child = optobus()
            .arg("simulate")
            .args(args)
            .args(["--duration", "60s"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("start optobus simulate");
        let mut line = String::new();
        let stdout = child.stdout.take().expect("stdout");
        BufReader::new(stdout)
            .read_line(&mut line)
            .expect("where it serves");
        Self {
            child,
            at: line.trim().to_owned(),
        }
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
