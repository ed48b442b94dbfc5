//! `--spec FILE`: a spec file is a model, with the same checks and the same output as a
//! built-in one; a broken spec is refused with the checker's located diagnostics.

mod common;

use std::path::Path;

use common::{fails, json, ok, outcome, Served, REFUSED};

fn repo_file(path: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(path)
        .display()
        .to_string()
}

#[test]
fn a_spec_file_describes_like_its_built_in_model() {
    let spec = repo_file("specs/ccs.yaml");
    for command in [&["registers"][..], &["models"], &["--json", "registers"]] {
        let built_in = ok(&[&["--model", "ccs"], command].concat());
        let from_file = ok(&[&["--spec", spec.as_str()], command].concat());
        assert_eq!(from_file, built_in, "{command:?}");
    }
    // `read` against the built-in simulator of the file's model.
    let values = json(&["--spec", &spec, "read", "exposure_time"]);
    assert!(values["exposure_time"]["value"].is_string(), "{values}");
}

#[test]
fn a_new_spec_is_read_from_its_own_simulator() {
    // The codegen test spec is a device no built-in model describes.
    let spec = repo_file("codegen/tests/fixtures/mini.yaml");
    let served = Served::start(&["--spec", &spec, "--tcp", "127.0.0.1:0"]);
    let at = served.at.as_str();
    ok(&["--spec", &spec, "set", "light_power", "42.5", "--tcp", at]);
    let values = json(&["--spec", &spec, "read", "light_power", "--tcp", at]);
    assert_eq!(values["light_power"]["value"], "42.5", "{values}");
    let list = ok(&["--spec", &spec, "registers"]);
    assert!(list.contains("statistic_config"), "{list}");
    assert!(!list.contains("distance_1"), "{list}");
}

#[test]
fn a_broken_spec_prints_the_checkers_diagnostics() {
    let spec = repo_file("crates/spec/tests/fixtures/errors/range.yaml");
    for command in [&["registers"][..], &["simulate", "--duration", "1s"]] {
        let (code, stdout, stderr) = outcome(&[&["--spec", spec.as_str()], command].concat());
        assert_eq!(code, Some(REFUSED), "{stderr}");
        assert!(stdout.is_empty(), "{stdout}");
        assert!(
            stderr.contains("error[range]: range of `light_power` has min 1000 > max 5"),
            "{stderr}"
        );
        assert!(stderr.contains("range.yaml:41:12"), "{stderr}");
        assert!(stderr.contains("^ empty range"), "{stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
    let missing = fails(&["--spec", "/nonexistent/spec.yaml", "registers"]);
    assert!(
        missing.contains("cannot read /nonexistent/spec.yaml"),
        "{missing}"
    );
}

#[test]
fn a_trial_spec_of_another_sensor_works_before_any_build() {
    // specs/trials/sgf.yaml: a sixth sensor, from a public register table, not built in.
    let spec = repo_file("specs/trials/sgf.yaml");
    let values = json(&["--spec", &spec, "read", "measurement", "settings"]);
    assert_eq!(values["working_mode"]["name"], "high_precision", "{values}");
    assert_eq!(values["baud_rate"]["name"], "baud_115200", "{values}");
    assert!(values["distance"]["value"].is_string(), "{values}");
    // Its simulator keeps reads to the two words the source reads at most.
    let (code, stdout, stderr) = outcome(&["--spec", &spec, "dump", "--verbose"]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stdout.contains("baud_rate"), "{stdout}");
    assert!(stderr.contains("-> 01 03 00 00 00 02 C4 0B"), "{stderr}");
    assert!(stderr.contains("15 registers in 8 requests"), "{stderr}");
    // Its action registers are written, never read, and a drastic one asks first.
    let stderr = fails(&["--spec", &spec, "read", "reset"]);
    assert!(stderr.contains("action register"), "{stderr}");
    let stderr = fails(&["--spec", &spec, "do", "factory_reset"]);
    assert!(stderr.contains("--yes"), "{stderr}");
}

#[test]
fn a_hostile_spec_file_is_refused_at_once() {
    // "Billion laughs": a few hundred bytes that would expand to 9^12 nodes.
    let bomb = std::env::temp_dir().join(format!("optobus-bomb-{}.yaml", std::process::id()));
    let mut text = String::from("family: bomb\na: &a [lol, lol, lol, lol, lol, lol, lol, lol]\n");
    for (from, to) in ('a'..'l').zip('b'..='l') {
        text.push_str(&format!(
            "{to}: &{to} [{}]\n",
            vec![format!("*{from}"); 9].join(",")
        ));
    }
    std::fs::write(&bomb, text).expect("write");
    let (code, _, stderr) = outcome(&["--spec", &bomb.display().to_string(), "registers"]);
    let _ = std::fs::remove_file(&bomb);
    assert_eq!(code, Some(REFUSED), "{stderr}");
    assert!(
        stderr.contains("error[yaml-alias]: YAML anchor `&a`: specs use no anchors or aliases"),
        "{stderr}"
    );
    assert!(stderr.contains(":2:4"), "{stderr}");
    let stderr = fails(&["--spec", "/dev/zero", "registers"]);
    assert!(
        stderr.contains("cannot read /dev/zero: not a regular file"),
        "{stderr}"
    );
}
