//! A register map must fit the device: the model is required off the simulator, `identify`
//! finds it from each spec's fingerprint, and a reply that does not fit hints at `--model`.

mod common;

use common::{ok, optobus, outcome, refused, words, Served, FAILED, REFUSED};

/// The built-in models as users type them, in the order the tool lists them.
const MODELS: &str = "p-series, rangefinder, ccs, lc-rs, ccf";

#[test]
fn addressing_a_device_without_a_model_is_refused_with_the_list_of_models() {
    let tcp = Served::start(&["p-series", "--tcp", "127.0.0.1:0"]);
    let pty = Served::start(&["p-series", "--pty"]);
    for (option, at) in [("--tcp", &tcp.at), ("--serial", &pty.at)] {
        for line in [
            "read distance_1",
            "dump",
            "set light_power 42",
            "raw read holding 0",
        ] {
            let mut args = words(line);
            args.extend([option, at.as_str()]);
            let stderr = refused(&args, REFUSED, &format!("which model is at {option} {at}?"));
            assert!(stderr.contains(&format!("--model ({MODELS})")), "{stderr}");
            assert!(stderr.contains("OPTOBUS_MODEL"), "{stderr}");
            assert!(stderr.contains("optobus identify"), "{stderr}");
        }
        // --model, --spec or the user's default say which map to read with.
        let values = common::json(&["--model", "p-series", "read", "laser_enabled", option, at]);
        assert_eq!(values["laser_enabled"], false);
        let output = optobus()
            .env("OPTOBUS_MODEL", "p-series")
            .args(["read", "laser_enabled", "--json", option, at])
            .output()
            .expect("run optobus");
        assert!(output.status.success(), "{output:?}");
        let values: serde_json::Value = serde_json::from_slice(&output.stdout).expect("JSON");
        assert_eq!(values["laser_enabled"], false);
    }
    // A default that names no model is refused as --model would be, saying where it came from.
    let output = optobus()
        .env("OPTOBUS_MODEL", "nosuch")
        .args(["read", "laser", "--tcp", &tcp.at])
        .output()
        .expect("run optobus");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(REFUSED), "{stderr}");
    assert!(
        stderr.starts_with("optobus: OPTOBUS_MODEL: unknown model `nosuch`"),
        "{stderr}"
    );
}

#[test]
fn the_built_in_simulator_keeps_its_p_series_default() {
    let (code, stdout, stderr) = outcome(&["read", "laser_enabled"]);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(stdout.trim(), "laser_enabled  false");
    assert!(
        stderr.contains("using the built-in p-series simulator"),
        "{stderr}"
    );
    // `simulate --tcp` serves rather than reaches a device: the default applies there too.
    let served = Served::start(&["--tcp", "127.0.0.1:0"]);
    let text = ok(&words(&format!(
        "--model p-series read laser_enabled --tcp {}",
        served.at
    )));
    assert_eq!(text.trim(), "laser_enabled  false");
}

#[test]
fn a_reply_whose_framing_does_not_fit_the_model_hints_at_model() {
    // LC-RS answers the P series' FC04 with its own 7-byte exception frame: over Modbus TCP an
    // MBAP length of 5 where a standard exception has 3.
    let served = Served::start(&["lc-rs", "--tcp", "127.0.0.1:0"]);
    let (code, stdout, stderr) = outcome(&words(&format!(
        "--model p-series read measurements --tcp {}",
        served.at
    )));
    assert_eq!(code, Some(FAILED), "{stderr}");
    assert!(stdout.is_empty(), "no value: {stdout}");
    assert!(
        stderr.starts_with("optobus: malformed reply: MBAP length 5, expected 3"),
        "{stderr}"
    );
    assert!(stderr.contains("(check --model:"), "{stderr}");
    assert!(stderr.contains("`optobus identify`"), "{stderr}");
    // The same over RTU: the 7-byte exception does not decode as a standard one.
    let served = Served::start(&["lc-rs", "--pty"]);
    let (code, _, stderr) = outcome(&words(&format!(
        "--model p-series read measurements --timeout 200ms --serial {}",
        served.at
    )));
    assert_eq!(code, Some(FAILED), "{stderr}");
    assert!(stderr.contains("malformed reply"), "{stderr}");
    assert!(stderr.contains("(check --model:"), "{stderr}");
}

/// `optobus identify` with `args` against `served`: exit code, stdout, stderr.
fn identify(args: &str) -> (Option<i32>, String, String) {
    outcome(&words(&format!("identify --timeout 200ms {args}")))
}

#[test]
fn identify_names_the_model_over_tcp_and_rtu_with_the_evidence() {
    // Over Modbus TCP: every model is asked; only the CCF fits.
    let served = Served::start(&["ccf", "--tcp", "127.0.0.1:0"]);
    let (code, stdout, stderr) = identify(&format!("--tcp {}", served.at));
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stdout.starts_with("model: ccf\n"), "{stdout}");
    assert!(stdout.contains("\nccf (slave 1): fits\n"), "{stdout}");
    for other in ["p-series", "rangefinder", "ccs", "lc-rs"] {
        assert!(stdout.contains(&format!("\n{other} (slave ")), "{stdout}");
    }
    assert_eq!(stdout.matches("): ruled out\n").count(), 4, "{stdout}");
    // The CCS reads past its 40 input registers, where a CCF answers.
    assert!(
        stdout.contains("- input 0x0028 (40) lies past the table, yet answered"),
        "{stdout}"
    );
    // JSON: the model, and the evidence per candidate.
    let (code, stdout, _) = identify(&format!("--tcp {} --json", served.at));
    assert_eq!(code, Some(0));
    let found: serde_json::Value = serde_json::from_str(&stdout).expect("JSON");
    assert_eq!(found["model"], "ccf");
    assert_eq!(found["fitting"], serde_json::json!(["ccf"]));
    let candidates = found["candidates"].as_array().expect("candidates");
    assert_eq!(candidates.len(), 5);
    let ccs = &candidates[2];
    assert_eq!(ccs["model"], "ccs");
    assert_eq!(ccs["fits"], false);
    assert!(ccs["evidence"]
        .as_array()
        .expect("evidence")
        .iter()
        .any(|f| f["rules_out"] == true));

    // Over RTU on a pty: the rangefinder at its own factory slave, 25; LC-RS with its
    // counted-word exception frames.
    for (model, slave) in [("rangefinder", 25), ("lc-rs", 1)] {
        let served = Served::start(&[model, "--pty"]);
        let (code, stdout, stderr) = identify(&format!("--serial {}", served.at));
        assert_eq!(code, Some(0), "{stderr}");
        assert!(stdout.starts_with(&format!("model: {model}\n")), "{stdout}");
        assert!(
            stdout.contains(&format!("\n{model} (slave {slave}): fits\n")),
            "{stdout}"
        );
    }
    let served = Served::start(&["lc-rs", "--pty"]);
    let (_, stdout, _) = identify(&format!("--serial {}", served.at));
    assert!(
        stdout.contains("past the table and was refused (0x0001 (register_address_error))"),
        "{stdout}"
    );
}

#[test]
fn identify_names_a_spec_model_and_never_a_wrong_one() {
    let spec = concat!(env!("CARGO_MANIFEST_DIR"), "/../../specs/trials/sgf.yaml");
    let served = Served::start(&["--spec", spec, "--tcp", "127.0.0.1:0"]);
    // With its spec among the candidates: that model.
    let (code, stdout, stderr) = identify(&format!("--spec {spec} --tcp {}", served.at));
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stdout.starts_with("model: sgf\n"), "{stdout}");
    // Without it: none of the built-in models, each ruled out by evidence of its own.
    let (code, stdout, stderr) = identify(&format!("--tcp {}", served.at));
    assert_eq!(code, Some(FAILED), "{stderr}");
    assert!(stdout.starts_with("model: no model fits\n"), "{stdout}");
    assert_eq!(stdout.matches("): ruled out\n").count(), 5, "{stdout}");
    assert!(
        stderr.starts_with(&format!(
            "optobus: no model fits the device at --tcp {}",
            served.at
        )),
        "{stderr}"
    );
    // identify asks a device and believes no model given to it.
    refused(
        &words("identify"),
        REFUSED,
        "identify asks a real device: give --tcp or --serial",
    );
    refused(
        &words(&format!("--model ccf identify --tcp {}", served.at)),
        REFUSED,
        "identify tries every model",
    );
}

#[test]
fn scan_reports_the_model_it_found() {
    // The scan's own --model gives the lists to try; what answers is identified on its own.
    let served = Served::start(&["ccf", "--pty", "--slave", "2"]);
    let line = format!(
        "--model p-series scan --serial {} --bauds 115200 --slaves 1-3 --timeout 200ms",
        served.at
    );
    let (code, stdout, stderr) = outcome(&words(&line));
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(stdout.trim(), "found: slave 2 at 115200 baud: ccf");
    let (code, stdout, stderr) = outcome(&words(&format!("{line} --json")));
    assert_eq!(code, Some(0), "{stderr}");
    let found: serde_json::Value = serde_json::from_str(&stdout).expect("JSON only");
    assert_eq!(
        found,
        serde_json::json!([{"baud": 115200, "slave": 2, "model": "ccf"}])
    );
}
