//! Seeded random mutations of the five specs: each mutant is either refused with diagnostics
//! that all point at a real line and column of the mutant, or its generated code compiles.
//!
//! The accepted mutants (distinct outputs, up to `OPTOBUS_MUTANTS_COMPILE`, default 40) are
//! compiled together as modules of one temporary crate with one offline `cargo check`, under
//! `#![deny(warnings)]`. Set `OPTOBUS_MUTANTS` for more mutants per spec (default 60) and
//! `OPTOBUS_MUTANTS_SEED` for another seed; a failure prints the seed and the mutation.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

/// SplitMix64: small, seeded, the same everywhere.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }

    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// A `key: value` in the text: byte range of the value, the key, and its line.
struct Slot {
    key: String,
    value: std::ops::Range<usize>,
    line: usize,
}

/// Every scalar `key: value` of the text (block and flow style), comments skipped.
fn slots(text: &str) -> Vec<Slot> {
    let mut out = Vec::new();
    let mut offset = 0;
    for (line_number, line) in text.split_inclusive('\n').enumerate() {
        let code = line.split(" #").next().unwrap_or(line);
        let bytes = code.as_bytes();
        let mut i = 0;
        while i < bytes.len() {
            let starts_key = bytes[i].is_ascii_lowercase()
                && (i == 0 || matches!(bytes[i - 1], b' ' | b'{' | b','));
            if !starts_key {
                i += 1;
                continue;
            }
            let key_end = i + code[i..]
                .find(|c: char| !(c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_'))
                .unwrap_or(code.len() - i);
            if code[key_end..].starts_with(": ") {
                let start = key_end + 2;
                let rest = &code[start..];
                let flow = line.trim_start().starts_with('{')
                    || code[..i].contains('{')
                    || code[..i].contains('[');
                let end = start
                    + if let Some(quoted) = rest.strip_prefix('"') {
                        quoted.find('"').map_or(rest.len(), |e| e + 2)
                    } else if flow {
                        rest.find([',', '}', ']']).unwrap_or(rest.len())
                    } else {
                        rest.trim_end_matches('\n').len()
                    };
                let value = code[start..end].trim_end();
                if !value.is_empty() && !value.starts_with(['[', '{', '|', '>']) {
                    out.push(Slot {
                        key: code[i..key_end].to_owned(),
                        value: offset + start..offset + start + value.len(),
                        line: line_number,
                    });
                }
                i = end.max(i + 1);
            } else {
                i = key_end.max(i + 1);
            }
        }
        offset += line.len();
    }
    out
}

const NUMBERS: &[&str] = &[
    "-1",
    "0",
    "1",
    "2",
    "255",
    "256",
    "65535",
    "65536",
    "0x10001",
    "0x1FFFF",
    "4294967295",
    "4294967296",
    "-2147483649",
    "9223372036854775807",
    "-9223372036854775808",
    "99999999999999999999999",
    "1.5",
    "-0.0",
    "1e-38",
    "1e127",
];
const SCALES: &[&str] = &[
    "1e-38",
    "1e-37",
    "1e-19",
    "1e19",
    "1e20",
    "1e127",
    "1e-128",
    "0",
    "1/0",
    "0/1",
    "1/4294967295",
    "4294967295/1",
    "1e-6",
    "0.5",
    "-1",
];
const TYPES: &[&str] = &[
    "[1, 2]", "{a: 1}", "\"1\"", "true", "~", "\"\"", "-", "[]", "{}",
];
const UNICODE: &[&str] = &[
    "\u{202E}", "\u{2066}", "\u{200B}", "\u{0007}", "\u{FEFF}", "é", "😀", "\u{0301}", "Ω", "\\",
    "\"", "`", "*/", "\u{85}",
];

/// Applies one random mutation; says what it did.
fn mutate(text: &mut String, rng: &mut Rng) -> String {
    let slots = slots(text);
    let slot = rng.pick(&slots);
    let old = text[slot.value.clone()].to_owned();
    let (what, new) = match rng.below(9) {
        0 | 1 => {
            let new = if slot.key == "scale" {
                rng.pick(SCALES)
            } else {
                rng.pick(NUMBERS)
            };
            ("number", (*new).to_owned())
        }
        2 => ("type", (*rng.pick(TYPES)).to_owned()),
        3 => {
            let mark = rng.pick(UNICODE);
            let at = rng.below(2);
            let new = if let Some(quoted) = old.strip_prefix('"') {
                format!("\"{mark}{quoted}")
            } else if at == 0 {
                format!("{old}{mark}")
            } else {
                format!("{mark}{old}")
            };
            ("unicode", new)
        }
        4 => {
            // Another item's name here: a duplicate, or a clash between kinds.
            let names: Vec<&Slot> = slots.iter().filter(|s| s.key == "name").collect();
            let name = if rng.below(4) == 0 {
                (*rng.pick(&["self", "type", "crate", "fn", "r#x", "new", "core", "slave"]))
                    .to_owned()
            } else {
                text[rng.pick(&names).value.clone()].to_owned()
            };
            let target = rng.pick(&names);
            let range = target.value.clone();
            let before = text[range.clone()].to_owned();
            text.replace_range(range, &name);
            return format!("name `{before}` -> `{name}` (line {})", target.line + 1);
        }
        5 => {
            // Delete the key and its value.
            let line_start = text[..slot.value.start].rfind('\n').map_or(0, |i| i + 1);
            let key_start = text[..slot.value.start]
                .rfind(slot.key.as_str())
                .unwrap_or(line_start);
            let end = slot.value.end;
            let end = if text[end..].starts_with(", ") {
                end + 2
            } else {
                end
            };
            text.replace_range(key_start..end, "");
            return format!("deleted `{}` (line {})", slot.key, slot.line + 1);
        }
        6 => {
            let key = rng.pick(&["colour", "adress", "scale", "name", "doc", "words"]);
            let new = format!("{old}, {key}: 3");
            if text[..slot.value.start].rfind('{') > text[..slot.value.start].rfind('\n') {
                ("key", new)
            } else {
                let indent = text[..slot.value.start]
                    .rfind('\n')
                    .map_or(0, |i| slot.value.start - i - 1 - slot.key.len() - 2);
                let indent = " ".repeat(indent);
                let at = text[slot.value.end..]
                    .find('\n')
                    .map_or(text.len(), |i| slot.value.end + i + 1);
                text.insert_str(at, &format!("{indent}{key}: 3\n"));
                return format!("added `{key}` after line {}", slot.line + 1);
            }
        }
        7 => {
            // Empty a whole list section: a spec may have no reserved range, command, group.
            let sections = ["reserved", "commands", "groups", "repeats", "enums"];
            let present: Vec<&str> = sections
                .iter()
                .copied()
                .filter(|s| text.starts_with(&format!("{s}:")) || text.contains(&format!("\n{s}:")))
                .collect();
            if let Some(section) = present.get(rng.below(present.len().max(1))) {
                let start = text.find(&format!("\n{section}:")).map_or(0, |i| i + 1);
                // The section runs to the next top-level key (or the end).
                let end = text[start + 1..]
                    .match_indices('\n')
                    .map(|(i, _)| start + 1 + i + 1)
                    .find(|&i| text[i..].starts_with(|c: char| c.is_ascii_lowercase()))
                    .unwrap_or(text.len());
                let empty = if *section == "enums" { "{}" } else { "[]" };
                text.replace_range(start..end, &format!("{section}: {empty}\n"));
                return format!("emptied `{section}`");
            }
            ("empty", String::new())
        }
        _ => ("empty", String::new()),
    };
    text.replace_range(slot.value.clone(), &new);
    format!(
        "{what}: `{}: {old}` -> `{new}` (line {})",
        slot.key,
        slot.line + 1
    )
}

/// Every `-->` of a rendering names a line and column inside the text.
fn located(rendered: &str, name: &str, text: &str) -> Result<(), String> {
    let lines: Vec<&str> = text.lines().collect();
    let mut arrows = 0;
    for line in rendered.lines() {
        let Some(at) = line.trim_start().strip_prefix("--> ") else {
            continue;
        };
        arrows += 1;
        let position = at
            .strip_prefix(name)
            .and_then(|p| p.strip_prefix(':'))
            .ok_or_else(|| format!("no line and column in `{line}`"))?;
        let (l, c) = position
            .split_once(':')
            .and_then(|(l, c)| Some((l.parse::<usize>().ok()?, c.parse::<usize>().ok()?)))
            .ok_or_else(|| format!("bad position in `{line}`"))?;
        let text_line = lines
            .get(l.wrapping_sub(1))
            .ok_or_else(|| format!("line {l} is outside the file: `{line}`"))?;
        if c == 0 || c > text_line.chars().count() + 1 {
            return Err(format!("column {c} is outside line {l}: `{line}`"));
        }
    }
    if arrows == 0 {
        return Err("no diagnostic".into());
    }
    Ok(())
}

fn env_number(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

#[test]
fn mutated_specs_are_refused_with_a_place_or_compile() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let seed = env_number("OPTOBUS_MUTANTS_SEED", 0x0b7_0b05);
    let per_spec = env_number("OPTOBUS_MUTANTS", 60);
    let compile_limit = env_number("OPTOBUS_MUTANTS_COMPILE", 40) as usize;
    let mut rng = Rng(seed);
    let (mut tried, mut refused) = (0, 0);
    let mut accepted: Vec<(String, String)> = Vec::new();
    let mut outputs = BTreeSet::new();
    let mut failures = Vec::new();
    for family in ["p_series", "rangefinder", "ccs", "lc_rs", "ccf"] {
        let original = std::fs::read_to_string(root.join(format!("specs/{family}.yaml")))
            .expect("spec readable");
        outputs.insert(optobus_codegen::emit::generate(
            &optobus_spec::check_source(family, &original).expect("the spec passes"),
            "spec.yaml",
        ));
        for n in 0..per_spec {
            let mut text = original.clone();
            let changes: Vec<String> = (0..1 + rng.below(2))
                .map(|_| mutate(&mut text, &mut rng))
                .collect();
            let name = format!("{family}-{n}.yaml");
            tried += 1;
            let checked = std::panic::catch_unwind(|| {
                let checked = optobus_spec::check_source(&name, &text);
                let code = checked
                    .as_ref()
                    .ok()
                    .map(|model| optobus_codegen::emit::generate(model, &name));
                (checked, code)
            });
            let Ok((checked, code)) = checked else {
                failures.push(format!(
                    "{name} {changes:?}: the checker or generator panicked"
                ));
                continue;
            };
            match checked {
                Err(rejected) => {
                    refused += 1;
                    if let Err(why) = located(&rejected.render(), &name, &text) {
                        failures.push(format!("{name} {changes:?}: {why}\n{}", rejected.render()));
                    }
                }
                Ok(_) => {
                    let code = code.unwrap_or_default();
                    if outputs.insert(code.clone()) {
                        accepted.push((format!("{name} {changes:?}"), code));
                    }
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "seed {seed:#x}:\n{}",
        failures.join("\n")
    );
    let compiled = accepted.len().min(compile_limit);
    eprintln!(
        "mutants: {tried} tried, {refused} refused, {} accepted with new output, {compiled} compiled",
        accepted.len()
    );
    compile(&root, &accepted[..compiled]).unwrap_or_else(|e| panic!("seed {seed:#x}: {e}"));
}

/// Compiles `mutants` as the modules of one crate; names the mutant that fails.
fn compile(root: &Path, mutants: &[(String, String)]) -> Result<(), String> {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("mutants");
    let src = dir.join("src");
    let _ = std::fs::remove_dir_all(&src);
    std::fs::create_dir_all(&src).map_err(|e| e.to_string())?;
    let root = root.canonicalize().map_err(|e| e.to_string())?;
    // A driver crate's manifest: its `serde` feature on, so that the serde impls compile too.
    let manifest = format!(
        "[package]\nname = \"optobus-mutants\"\nversion = \"0.0.0\"\nedition = \"2021\"\npublish = false\n\n\
         [features]\ndefault = [\"serde\"]\nserde = [\"dep:serde\", \"optobus-driver/serde\"]\n\n\
         [dependencies]\n\
         serde = {{ version = \"1\", features = [\"derive\"], optional = true }}\n\
         optobus-codec = {{ path = \"{0}/crates/codec\" }}\n\
         optobus-device = {{ path = \"{0}/crates/device\" }}\n\
         optobus-driver = {{ path = \"{0}/crates/driver\" }}\n\n[workspace]\n",
        root.display()
    );
    std::fs::write(dir.join("Cargo.toml"), manifest).map_err(|e| e.to_string())?;
    std::fs::copy(root.join("Cargo.lock"), dir.join("Cargo.lock")).map_err(|e| e.to_string())?;
    let mut lib = String::from("//! Accepted mutants.\n#![deny(warnings)]\n");
    for (i, (what, code)) in mutants.iter().enumerate() {
        lib.push_str(&format!("/// {}\npub mod m{i};\n", what.replace('\n', " ")));
        std::fs::write(src.join(format!("m{i}.rs")), code).map_err(|e| e.to_string())?;
    }
    std::fs::write(src.join("lib.rs"), lib).map_err(|e| e.to_string())?;
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let output = Command::new(cargo)
        .args(["check", "--offline", "--quiet", "--message-format=short"])
        .current_dir(&dir)
        .env("CARGO_TARGET_DIR", dir.join("target"))
        .env_remove("RUSTFLAGS")
        .output()
        .map_err(|e| e.to_string())?;
    if output.status.success() {
        return Ok(());
    }
    let stderr = String::from_utf8_lossy(&output.stderr);
    let culprits: BTreeSet<&str> = stderr
        .lines()
        .filter_map(|l| l.strip_prefix("src/m"))
        .filter_map(|l| l.split('.').next()?.parse::<usize>().ok())
        .filter_map(|i| mutants.get(i).map(|(what, _)| what.as_str()))
        .collect();
    Err(format!(
        "accepted mutants do not compile: {culprits:#?}\n{}",
        stderr.lines().take(60).collect::<Vec<_>>().join("\n")
    ))
}
