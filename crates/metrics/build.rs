//! The Rust and target this crate is built with, for `optobus_build_info`; and whether
//! promtool is installed, for the tests that check the exposition with it (see
//! optobus-testkit): without it they are listed as ignored, with the reason.

use std::process::Command;

fn main() {
    let rustc = std::env::var_os("RUSTC").unwrap_or_else(|| "rustc".into());
    // `rustc 1.95.0 (59807616e 2026-04-14)`: the second word.
    let version = Command::new(rustc)
        .arg("--version")
        .output()
        .ok()
        .and_then(|output| {
            let text = String::from_utf8(output.stdout).ok()?;
            Some(text.split_whitespace().nth(1)?.to_owned())
        })
        .unwrap_or_else(|| "unknown".to_owned());
    println!("cargo::rustc-env=OPTOBUS_RUSTC_VERSION={version}");
    let target = std::env::var("TARGET").unwrap_or_else(|_| "unknown".to_owned());
    println!("cargo::rustc-env=OPTOBUS_TARGET={target}");
    optobus_testkit::build::peers(&[optobus_testkit::build::PROMTOOL]);
}
