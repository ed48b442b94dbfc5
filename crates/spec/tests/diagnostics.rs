//! Every validation rule has a failing fixture in `tests/fixtures/errors/`, and its rendered
//! diagnostics are snapshot-tested against the `.stderr` file next to it.
//!
//! After an intended change to a message, refresh the snapshots with
//! `UPDATE_SNAPSHOTS=1 cargo test -p optobus-spec --test diagnostics` and review the diff.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn fixtures() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/errors");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("fixtures directory")
        .map(|entry| entry.expect("entry").path())
        .filter(|path| path.extension().is_some_and(|e| e == "yaml"))
        .collect();
    files.sort();
    files
}

/// Renders a fixture's diagnostics with a stable file name.
fn render(path: &Path) -> (String, Vec<&'static str>) {
    let name = format!(
        "fixtures/errors/{}",
        path.file_name().expect("file name").to_string_lossy()
    );
    let text = std::fs::read_to_string(path).expect("fixture readable");
    match optobus_spec::check_source(&name, &text) {
        Ok(_) => panic!("{name} should fail but passes every rule"),
        Err(rejected) => (
            rejected.render(),
            rejected.diagnostics.iter().map(|d| d.rule).collect(),
        ),
    }
}

#[test]
fn every_fixture_matches_its_snapshot() {
    let update = std::env::var_os("UPDATE_SNAPSHOTS").is_some();
    let mut mismatches = Vec::new();
    for path in fixtures() {
        let (rendered, _) = render(&path);
        let snapshot = path.with_extension("stderr");
        if update {
            std::fs::write(&snapshot, &rendered).expect("write snapshot");
            continue;
        }
        match std::fs::read_to_string(&snapshot) {
            Ok(expected) if expected == rendered => {}
            Ok(expected) => mismatches.push(format!(
                "{}:\n--- expected\n{expected}\n+++ actual\n{rendered}",
                snapshot.display()
            )),
            Err(_) => mismatches.push(format!(
                "{} is missing; run with UPDATE_SNAPSHOTS=1",
                snapshot.display()
            )),
        }
    }
    assert!(mismatches.is_empty(), "{}", mismatches.join("\n"));
}

#[test]
fn every_rule_has_a_failing_fixture() {
    let mut fired = BTreeSet::new();
    for path in fixtures() {
        let (_, rules) = render(&path);
        fired.extend(rules);
    }
    let missing: Vec<&str> = optobus_spec::rules::RULES
        .iter()
        .map(|rule| rule.name)
        .filter(|name| !fired.contains(name))
        .collect();
    assert!(
        missing.is_empty(),
        "rules without a failing fixture: {missing:?}"
    );
    for rule in [
        "yaml",
        optobus_spec::source::ALIAS_RULE,
        optobus_spec::rules::text::RULE,
    ] {
        assert!(fired.contains(rule), "no fixture exercises `{rule}`");
    }
}

#[test]
fn all_errors_are_reported_not_just_the_first() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/errors/many_errors.yaml");
    let (_, rules) = render(&path);
    let distinct: BTreeSet<_> = rules.iter().collect();
    assert!(
        distinct.len() >= 3,
        "expected three different rules, got {rules:?}"
    );
}

#[test]
fn diagnostics_point_at_the_offending_text() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/errors/sentinel.yaml");
    let (rendered, _) = render(&path);
    // The caret line sits under the sentinel's value, as wide as the value.
    let lines: Vec<&str> = rendered.lines().collect();
    let source_line = lines
        .iter()
        .position(|l| l.contains("sentinel: 0x1FFFFFFFF"))
        .expect("source line shown");
    let carets = lines[source_line + 1];
    let column = lines[source_line].find("0x1FFFFFFFF").expect("value");
    assert_eq!(carets.find('^'), Some(column));
    assert_eq!(carets.matches('^').count(), "0x1FFFFFFFF".len());
}

#[test]
fn reading_errors_come_with_rule_errors_and_without_follow_ons() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/errors/yaml_many.yaml");
    let (rendered, rules) = render(&path);
    let distinct: BTreeSet<_> = rules.iter().collect();
    assert!(
        distinct.contains(&"yaml") && distinct.contains(&"name-format"),
        "{rules:?}"
    );
    assert_eq!(
        rules.iter().filter(|r| **r == "yaml").count(),
        7,
        "{rendered}"
    );
    // `light_power` could not be read: the group naming it is not reported again.
    assert!(
        !rendered.contains("unknown register `light_power`"),
        "{rendered}"
    );
}

#[test]
fn a_rejected_files_reports_are_typed_json_with_places_and_related_labels() {
    use optobus_spec::diagnostic::{Label, Location};
    use optobus_spec::{Diagnostic, Rejected, SourceFile};

    let mut diagnostic = Diagnostic::at_start("duplicate-name", "`a` is named twice");
    diagnostic.primary.location = Location::Position { line: 2, column: 3 };
    diagnostic.primary.text = "second".to_owned();
    diagnostic.help = Some("rename one".to_owned());
    diagnostic.secondary.push(Label {
        location: Location::Position { line: 1, column: 1 },
        text: "first defined here".to_owned(),
    });
    let rejected = Rejected {
        source: SourceFile::new("bus.yaml", "a: 1\n  a: 2\n"),
        diagnostics: vec![diagnostic],
    };
    let json = serde_json::to_string(&rejected.reports("shown.yaml")).unwrap();
    assert_eq!(
        json,
        r#"[{"severity":"error","rule":"duplicate-name","message":"`a` is named twice","file":"shown.yaml","line":2,"column":3,"label":"second","help":"rename one","related":[{"line":1,"column":1,"label":"first defined here"}]}]"#
    );
}
