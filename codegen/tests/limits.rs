//! Hostile spec files: each is answered at once with a located error or a result, never by
//! exhausting the machine. How fast is measured by `benches/check.rs`, not here.

#[path = "support/large_spec.rs"]
mod large_spec;

use std::path::PathBuf;

use optobus_codegen::source::{read_limited, ReadError, ALIAS_RULE, YAML_LIMIT};

/// A file in the temporary directory, unique to this test process.
fn scratch(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("optobus-limits-{}-{name}", std::process::id()))
}

/// "Billion laughs": twelve levels of nine aliases each, 9^12 leaves once expanded.
fn alias_bomb() -> String {
    let mut text =
        String::from("family: bomb\na: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n");
    let names: Vec<char> = ('a'..='l').collect();
    for pair in names.windows(2) {
        let aliases = vec![format!("*{}", pair[0]); 9].join(",");
        text.push_str(&format!("{}: &{} [{aliases}]\n", pair[1], pair[1]));
    }
    text
}

#[test]
fn an_alias_bomb_is_refused_at_its_first_anchor() {
    let bomb = alias_bomb();
    assert!(bomb.len() < 500, "{}", bomb.len());
    let rejected = optobus_codegen::check_source("bomb.yaml", &bomb).expect_err("refused");
    let rules: Vec<&str> = rejected.diagnostics.iter().map(|d| d.rule).collect();
    assert_eq!(rules, [ALIAS_RULE]);
    let rendered = rejected.render();
    let expected = "error[yaml-alias]: YAML anchor `&a`: specs use no anchors or aliases
 --> bomb.yaml:2:4
  |
2 | a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]
  |    ^^
";
    assert!(rendered.starts_with(expected), "{rendered}");
    // Nothing was built from the file.
    assert!(rejected.source.root.is_none(), "{rendered}");
}

#[test]
fn an_alias_is_refused_where_it_is_written() {
    let text = "family: x\ntitle: [1, 2]\nmanual: *unknown\n";
    let rejected = optobus_codegen::check_source("alias.yaml", text).expect_err("refused");
    assert!(
        rejected.render().contains("--> alias.yaml:3:9"),
        "{}",
        rejected.render()
    );
}

#[cfg(unix)]
#[test]
fn dev_zero_is_refused_as_no_file() {
    let rejected = optobus_codegen::check_file("/dev/zero".as_ref()).expect_err("refused");
    assert_eq!(
        rejected.diagnostics[0].message,
        "cannot read /dev/zero: not a regular file (a device, directory or socket)"
    );
}

#[test]
fn an_oversized_spec_is_refused_with_the_limit() {
    let path = scratch("oversized.yaml");
    // Sparse: one byte over the limit costs no disk.
    let file = std::fs::File::create(&path).expect("create");
    file.set_len(YAML_LIMIT + 1).expect("grow");
    let rejected = optobus_codegen::check_file(&path);
    let _ = std::fs::remove_file(&path);
    let rejected = rejected.expect_err("refused");
    assert_eq!(
        rejected.diagnostics[0].message,
        format!(
            "cannot read {}: larger than the limit of 16 MiB",
            path.display()
        )
    );
}

#[cfg(unix)]
#[test]
fn a_pipe_is_read_up_to_its_limit_and_no_further() {
    let path = scratch("pipe");
    let made = std::process::Command::new("mkfifo").arg(&path).status();
    if !made.is_ok_and(|status| status.success()) {
        eprintln!("skipped: mkfifo is not available");
        return;
    }
    let writer = {
        let path = path.clone();
        std::thread::spawn(move || {
            use std::io::Write as _;
            let mut pipe = std::fs::OpenOptions::new()
                .write(true)
                .open(path)
                .expect("open");
            // The reader stops after 1001 bytes; the rest may find the pipe closed.
            let _ = pipe.write_all(&[b'x'; 100_000]);
        })
    };
    let read = read_limited(&path, 1000);
    writer.join().expect("writer");
    let _ = std::fs::remove_file(&path);
    assert!(
        matches!(read, Err(ReadError::TooLarge { limit: 1000 })),
        "{read:?}"
    );
}

#[test]
fn a_spec_of_100000_registers_checks() {
    let spec = large_spec::large_spec(100_000);
    let model = optobus_codegen::check_source("large.yaml", &spec)
        .unwrap_or_else(|rejected| panic!("{}", rejected.render()));
    assert_eq!(model.registers.len(), 100_000);
    assert_eq!(model.groups.len(), 2 * 500);
    // One inline enum per fifth register but the aliases, the shared `mode` besides.
    assert_eq!(model.enums.len(), 1 + 20_000);
}
