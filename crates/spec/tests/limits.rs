//! Hostile spec files: each is answered at once with a located error or a result, never by
//! exhausting the machine. How fast is measured by `benches/check.rs`, not here.

#[path = "support/large_spec.rs"]
mod large_spec;

use std::path::PathBuf;

use optobus_spec::source::{read_limited, ReadError, ALIAS_RULE, YAML_LIMIT};

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
    let rejected = optobus_spec::check_source("bomb.yaml", &bomb).expect_err("refused");
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
    let rejected = optobus_spec::check_source("alias.yaml", text).expect_err("refused");
    assert!(
        rejected.render().contains("--> alias.yaml:3:9"),
        "{}",
        rejected.render()
    );
}

#[cfg(unix)]
#[test]
fn dev_zero_is_refused_as_no_file() {
    let rejected = optobus_spec::check_file("/dev/zero".as_ref()).expect_err("refused");
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
    let rejected = optobus_spec::check_file(&path);
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
    let model = optobus_spec::check_source("large.yaml", &spec)
        .unwrap_or_else(|rejected| panic!("{}", rejected.render()));
    assert_eq!(model.registers.len(), 100_000);
    assert_eq!(model.groups.len(), 2 * 500);
    // One inline enum per fifth register but the aliases, the shared `mode` besides.
    assert_eq!(model.enums.len(), 1 + 20_000);
}

#[test]
fn nesting_deeper_than_the_parser_allows_is_refused_where_it_goes_too_deep() {
    let text = format!("family: {}", "[".repeat(100_000));
    // The parser allows 511 levels: the 512th bracket, after `family: `, is refused.
    let rejected = optobus_spec::check_source("deep.yaml", &text).expect_err("refused");
    let rendered = rejected.render();
    assert!(
        rendered.starts_with(
            "error[yaml]: collection nesting depth exceeds limit\n --> deep.yaml:1:520\n"
        ),
        "{rendered}"
    );
}

/// `large_spec(registers)` with the line of register `holding_{index}` changed by `change`;
/// also the line's number.
fn large_spec_changed_at(
    registers: usize,
    index: usize,
    change: impl Fn(&str) -> String,
) -> (String, usize) {
    let spec = large_spec::large_spec(registers);
    let marker = format!("{{name: holding_{index}, ");
    let at = spec.find(&marker).expect("the register is there");
    let line_start = spec[..at].rfind('\n').map_or(0, |newline| newline + 1);
    let line_end = at + spec[at..].find('\n').expect("a whole line");
    let line = spec[..line_start].matches('\n').count() + 1;
    let changed = format!(
        "{}{}{}",
        &spec[..line_start],
        change(&spec[line_start..line_end]),
        &spec[line_end..]
    );
    (changed, line)
}

#[test]
fn a_large_spec_is_parsed_alongside_and_places_what_it_refuses_as_a_small_one() {
    // Well past the size from which the parse runs on its own thread.
    let registers = 20_000;
    assert!(large_spec::large_spec(registers).len() > 2 << 20);
    let (alias, line) = large_spec_changed_at(registers, 9_000, |line| {
        line.replace("doc: Register 9000.", "doc: *register")
    });
    let rejected = optobus_spec::check_source("alias.yaml", &alias).expect_err("refused");
    let column = alias
        .lines()
        .nth(line - 1)
        .and_then(|text| text.find("*register"))
        .expect("written")
        + 1;
    let rendered = rejected.render();
    assert!(
        rendered.starts_with(
            "error[yaml-alias]: YAML alias `*register`: specs use no anchors or aliases\n"
        ) && rendered.contains(&format!("--> alias.yaml:{line}:{column}\n")),
        "expected line {line}, column {column}:\n{rendered}"
    );
    assert_eq!(rejected.diagnostics.len(), 1, "{rendered}");
    assert!(
        rejected.source.root.is_none(),
        "nothing is built past the alias"
    );

    // A column counts characters: the Chinese name before the mistake is three, not nine.
    let (broken, line) = large_spec_changed_at(registers, 9_000, |line| {
        line.replace("section: \"1\"}", "section: \"1\"} }")
    });
    let rejected = optobus_spec::check_source("broken.yaml", &broken).expect_err("refused");
    let rendered = rejected.render();
    let text = broken.lines().nth(line - 1).expect("the line");
    let column = text[..text.rfind(" }").expect("written") + 1]
        .chars()
        .count()
        + 1;
    assert!(
        rendered.starts_with("error[yaml]: ")
            && rendered.contains(&format!(" --> broken.yaml:{line}:{column}\n")),
        "line {line}, column {column}:\n{rendered}"
    );
}
