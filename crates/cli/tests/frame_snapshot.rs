//! What `optobus frame` prints for every frame of the five manuals (decoded alone, and a reply
//! with its request), and for a read of every register and group, text and JSON, against a
//! snapshot: refactoring the frame tools must not change a byte of it.
//! `UPDATE_SNAPSHOTS=1` rewrites the snapshot after an intended change.

mod common;

use std::fmt::Write;
use std::path::PathBuf;

use optobus_tests::golden::{self, Direction, Transport};

const FAMILIES: [&str; 5] = ["p_series", "rangefinder", "ccs", "lc_rs", "ccf"];

fn hex(bytes: &[u8]) -> String {
    bytes
        .iter()
        .map(|b| format!("{b:02X}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// `optobus ARGS` as the snapshot shows it: the command, exit status, stdout and stderr.
fn record(out: &mut String, args: &[&str]) {
    let output = common::run(args);
    let _ = writeln!(out, "$ optobus {}", args.join(" "));
    let _ = writeln!(out, "status: {}", output.status.code().unwrap_or(-1));
    out.push_str(&String::from_utf8_lossy(&output.stdout));
    let stderr = String::from_utf8_lossy(&output.stderr);
    if !stderr.is_empty() {
        let _ = writeln!(out, "stderr: {}", stderr.trim_end());
    }
    out.push('\n');
}

fn decodes(family: &str) -> String {
    let model = family.replace('_', "-");
    let file = golden::load(family).expect("golden file");
    let mut out = String::new();
    let mut request: Option<(Transport, String)> = None;
    for entry in &file.frames {
        let bytes = hex(&entry.bytes.0);
        let mut args = vec!["frame", "decode", model.as_str()];
        if entry.transport == Transport::Tcp {
            args.push("--mbap");
        }
        for json in [false, true] {
            let mut alone = args.clone();
            alone.push(&bytes);
            if json {
                alone.push("--json");
            }
            record(&mut out, &alone);
        }
        match entry.direction {
            Direction::Request => request = Some((entry.transport, bytes.clone())),
            Direction::Response => {
                if let Some((transport, asked)) = request.take() {
                    if transport == entry.transport {
                        let mut pair = args.clone();
                        pair.push(&asked);
                        pair.push(&bytes);
                        record(&mut out, &pair);
                    }
                }
            }
        }
    }
    out
}

fn encodes(family: &str) -> String {
    let model = family.replace('_', "-");
    let names = common::json(&["registers", model.as_str()]);
    let mut out = String::new();
    let groups = names["groups"].as_array().cloned().unwrap_or_default();
    for group in &groups {
        let name = group["name"].as_str().unwrap_or_default();
        record(&mut out, &["frame", "encode", &model, "read", name]);
        record(
            &mut out,
            &["frame", "encode", &model, "read", name, "--json"],
        );
    }
    for register in names["registers"].as_array().cloned().unwrap_or_default() {
        let name = register["name"].as_str().unwrap_or_default();
        record(&mut out, &["frame", "encode", &model, "read", name]);
    }
    out
}

#[test]
fn frame_output_for_the_manuals_frames_is_unchanged() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/snapshots");
    let update = std::env::var_os("UPDATE_SNAPSHOTS").is_some();
    let mut changed = Vec::new();
    for family in FAMILIES {
        let text = decodes(family) + &encodes(family);
        let path = dir.join(format!("frame_{family}.txt"));
        if update {
            std::fs::write(&path, &text).expect("write snapshot");
            continue;
        }
        let expected = std::fs::read_to_string(&path).unwrap_or_default();
        if expected != text {
            let line = expected
                .lines()
                .zip(text.lines())
                .position(|(a, b)| a != b)
                .unwrap_or(0);
            changed.push(format!("{family} (first difference at line {})", line + 1));
        }
    }
    assert!(
        changed.is_empty(),
        "frame output changed for {changed:?}; UPDATE_SNAPSHOTS=1 if intended"
    );
}
