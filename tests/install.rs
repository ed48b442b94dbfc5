//! Issue 30, point 1: the Rust version we declare holds for users. Resolving the workspace
//! without `Cargo.lock` (what `cargo install --path crates/cli` and a fresh clone do) must pick
//! no package that needs a newer Rust than the workspace's `rust-version`, and neither may our
//! dependency requirements alone, which is all a downstream crate on the older resolver gets.
//!
//! Each test copies the workspace's manifests (with empty stand-ins for their targets) to a
//! folder of its own and lets cargo resolve there, so it reads the crates.io index: these tests
//! need the registry, as any build without a lock file does.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

/// The workspace root (this package is its `tests/` member).
fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ sits in the workspace")
        .to_path_buf()
}

/// The cargo that runs this test.
fn cargo() -> Command {
    Command::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()))
}

/// `cargo metadata` in `dir` with `args`: its JSON, and what cargo said on stderr.
fn metadata(dir: &Path, args: &[&str]) -> (Value, String) {
    let output = cargo()
        .args(["metadata", "--format-version", "1"])
        .args(args)
        .current_dir(dir)
        .output()
        .expect("cargo runs");
    let said = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(
        output.status.success(),
        "cargo metadata in {dir:?}:\n{said}"
    );
    let json = serde_json::from_slice(&output.stdout).expect("cargo metadata prints JSON");
    (json, said)
}

/// A Rust version (`1.88`, `1.88.0`) as numbers to compare.
fn rust_version(text: &str) -> (u64, u64, u64) {
    let mut parts = text.split('.').map(|part| {
        part.parse::<u64>()
            .unwrap_or_else(|_| panic!("rust-version {text:?}"))
    });
    let mut next = || parts.next().unwrap_or(0);
    (next(), next(), next())
}

/// A copy of the workspace's manifest set in a fresh folder named `name`: the root manifest
/// (its `resolver` replaced by `resolver`, when given), `.cargo/config.toml` if there is one,
/// every member's manifest and an empty file for each of its targets. No `Cargo.lock`.
fn manifest_copy(name: &str, resolver: Option<&str>) -> PathBuf {
    let root = workspace_root();
    let copy = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    if copy.exists() {
        std::fs::remove_dir_all(&copy).expect("an old copy goes");
    }
    std::fs::create_dir_all(&copy).unwrap();
    let mut manifest = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    if let Some(resolver) = resolver {
        let line = manifest
            .lines()
            .find(|line| line.starts_with("resolver ="))
            .expect("the workspace names its resolver")
            .to_owned();
        manifest = manifest.replace(&line, &format!("resolver = \"{resolver}\""));
    }
    std::fs::write(copy.join("Cargo.toml"), manifest).unwrap();
    let config = root.join(".cargo/config.toml");
    if config.exists() {
        std::fs::create_dir_all(copy.join(".cargo")).unwrap();
        std::fs::copy(&config, copy.join(".cargo/config.toml")).unwrap();
    }
    let (members, _) = metadata(&root, &["--no-deps", "--offline"]);
    for package in members["packages"].as_array().expect("packages") {
        let place = |path: &Value| {
            let path = Path::new(path.as_str().expect("a path"));
            copy.join(
                path.strip_prefix(&root)
                    .expect("a member sits in the workspace"),
            )
        };
        let manifest = place(&package["manifest_path"]);
        std::fs::create_dir_all(manifest.parent().unwrap()).unwrap();
        std::fs::copy(package["manifest_path"].as_str().unwrap(), &manifest).unwrap();
        for target in package["targets"].as_array().expect("targets") {
            let source = place(&target["src_path"]);
            std::fs::create_dir_all(source.parent().unwrap()).unwrap();
            std::fs::write(source, "").unwrap();
        }
    }
    copy
}

/// Resolves the copy `dir` without a lock file; the packages picked that need a newer Rust
/// than the workspace declares (`name version needs Rust X`), and what cargo said.
fn newer_than_declared(dir: &Path) -> (String, Vec<String>, String) {
    assert!(!dir.join("Cargo.lock").exists());
    let (resolved, said) = metadata(dir, &[]);
    let packages = resolved["packages"].as_array().expect("packages");
    let ours = |package: &&Value| package["source"].is_null();
    let declared = packages
        .iter()
        .filter(ours)
        .map(|package| {
            package["rust_version"]
                .as_str()
                .expect("every member declares it")
        })
        .max_by_key(|version| rust_version(version))
        .expect("members")
        .to_owned();
    let newer = packages
        .iter()
        .filter(|package| !ours(package))
        .filter_map(|package| {
            let needs = package["rust_version"].as_str()?;
            (rust_version(needs) > rust_version(&declared)).then(|| {
                format!(
                    "{} {} needs Rust {needs}",
                    package["name"].as_str().unwrap(),
                    package["version"].as_str().unwrap()
                )
            })
        })
        .collect();
    (declared, newer, said)
}

#[test]
fn install_without_the_lock_file_picks_nothing_newer_than_the_declared_rust() {
    let copy = manifest_copy("install-resolution", None);
    let (declared, newer, said) = newer_than_declared(&copy);
    assert!(
        newer.is_empty(),
        "resolved without Cargo.lock, as `cargo install --path crates/cli` does, for Rust \
         {declared}:\n{}\ncargo said:\n{said}",
        newer.join("\n")
    );
    assert!(
        said.contains(&format!("Rust {declared} compatible versions")),
        "cargo resolved for the declared Rust {declared}:\n{said}"
    );
}

#[test]
fn install_requirements_alone_pick_nothing_newer_than_the_declared_rust() {
    // The resolver of a downstream crate on edition 2021 takes the newest version each of our
    // requirements allows, whatever its Rust: the requirements themselves must be bounded.
    let copy = manifest_copy("install-requirements", Some("2"));
    let (declared, newer, said) = newer_than_declared(&copy);
    assert!(
        newer.is_empty(),
        "the newest versions our requirements allow, for Rust {declared}:\n{}\ncargo said:\n{said}",
        newer.join("\n")
    );
}
