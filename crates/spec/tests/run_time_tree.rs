//! The crates that read specs and bus files at run time link the front end only: the Rust
//! emitter's `quote`, `proc-macro2` and `syn` stay build-time dependencies of the driver crates.

use std::path::Path;
use std::process::Command;

/// The names of the packages `package` links at run time: `cargo tree -e normal,no-proc-macro`
/// (no build or dev dependencies, nothing behind a proc macro).
fn run_time_packages(package: &str) -> Vec<String> {
    let workspace = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let output = Command::new(env!("CARGO"))
        .current_dir(&workspace)
        .args([
            "tree",
            "--offline",
            "--locked",
            "-e",
            "normal,no-proc-macro",
        ])
        .args(["--prefix", "none", "--format", "{p}", "-p", package])
        .output()
        .expect("cargo runs");
    assert!(
        output.status.success(),
        "cargo tree failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let text = String::from_utf8(output.stdout).expect("UTF-8");
    let names = text
        .lines()
        .filter_map(|line| line.split_whitespace().next());
    names.map(str::to_owned).collect()
}

#[test]
fn the_tool_and_the_bus_link_no_emitter_at_run_time() {
    for package in [
        "optobus-cli",
        "optobus-bus",
        "optobus-console",
        "optobus-spec",
    ] {
        let linked = run_time_packages(package);
        assert!(
            linked.iter().any(|name| name == "optobus-spec"),
            "{package}: {linked:?}"
        );
        for emitter in ["quote", "proc-macro2", "syn", "optobus-codegen"] {
            assert!(
                !linked.iter().any(|name| name == emitter),
                "{package} links {emitter} at run time"
            );
        }
    }
}
