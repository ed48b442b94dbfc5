//! Every family crate is what `optobus-codegen new` writes for its spec (`UPDATE_SNAPSHOTS=1`
//! rewrites them from the templates), and `new` never overwrites a crate.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn specs() -> Vec<PathBuf> {
    let mut specs: Vec<PathBuf> = std::fs::read_dir(root().join("specs"))
        .expect("specs/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "yaml"))
        .collect();
    specs.sort();
    specs
}

fn model(spec: &Path) -> optobus_spec::Model {
    optobus_spec::check_file(spec).unwrap_or_else(|r| panic!("{}", r.render()))
}

#[test]
fn family_crates_are_what_the_scaffold_writes() {
    let bless = std::env::var_os("UPDATE_SNAPSHOTS").is_some();
    let mut compared = 0;
    for spec in specs() {
        let model = model(&spec);
        let dir = root().join(optobus_codegen::scaffold::crate_dir(&model));
        for (file, expected) in optobus_codegen::scaffold::files(&model) {
            let path = dir.join(file);
            let actual = std::fs::read_to_string(&path).unwrap_or_default();
            // Every family crate is exactly the scaffold: its quirks live in the spec.
            let same = actual == expected;
            if bless && !same {
                std::fs::create_dir_all(path.parent().expect("a folder")).expect("mkdir");
                std::fs::write(&path, &expected).expect("write");
                continue;
            }
            assert!(
                same,
                "{} differs from the scaffold (UPDATE_SNAPSHOTS=1 rewrites it):\n--- expected\n{expected}\n+++ actual\n{actual}",
                path.display()
            );
            compared += 1;
        }
    }
    assert!(bless || compared >= 4, "no family crate compared");
}

#[test]
fn family_crates_link_their_spec_and_the_licences() {
    for spec in specs() {
        let model = model(&spec);
        let dir = root().join(optobus_codegen::scaffold::crate_dir(&model));
        for (file, target) in optobus_codegen::scaffold::links(&model) {
            let path = dir.join(&file);
            let found = std::fs::read_link(&path).unwrap_or_default();
            assert_eq!(found, Path::new(&target), "{}", path.display());
            assert!(path.is_file(), "{} leads nowhere", path.display());
        }
    }
}

#[test]
fn new_writes_a_crate_once_and_never_overwrites() {
    let spec = root().join("codegen/tests/fixtures/mini.yaml");
    let model = model(&spec);
    let scratch = std::env::temp_dir().join(format!("optobus-scaffold-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&scratch);
    let dir = optobus_codegen::scaffold::write(&model, &scratch).expect("first write");
    assert_eq!(
        dir,
        scratch.join("crates").join(model.family.replace('_', "-"))
    );
    let lib = std::fs::read_to_string(dir.join("src/lib.rs")).expect("lib.rs");
    assert!(lib.contains(&format!(
        "include!(concat!(env!(\"OUT_DIR\"), \"/{}.rs\"));",
        model.family
    )));
    assert!(lib.contains("Simulator::new(&DEVICE)"), "{lib}");
    for file in ["Cargo.toml", "build.rs", "README.md"] {
        assert!(dir.join(file).is_file(), "{file}");
    }
    for (file, target) in optobus_codegen::scaffold::links(&model) {
        assert_eq!(
            std::fs::read_link(dir.join(&file)).ok(),
            Some(target.into()),
            "{file}"
        );
    }
    let error = optobus_codegen::scaffold::write(&model, &scratch).unwrap_err();
    assert!(error.to_string().contains("never overwrites"), "{error}");
    let _ = std::fs::remove_dir_all(&scratch);
}

/// The first `[dependencies]` block in `text`: (crate name, the rest of its line).
fn dependencies(text: &str) -> Vec<(String, String)> {
    text.lines()
        .map(|line| line.trim_start_matches("//!").trim())
        .skip_while(|line| *line != "[dependencies]")
        .skip(1)
        .take_while(|line| !line.starts_with("```"))
        .filter_map(|line| {
            let (name, rest) = line.split_once('=')?;
            Some((name.trim().to_owned(), rest.trim().to_owned()))
        })
        .collect()
}

/// The first Rust code block (a fence without a language) of `//!` docs.
fn rust_block(docs: &str) -> String {
    let mut block = Vec::new();
    let mut fence: Option<&str> = None;
    for line in docs
        .lines()
        .filter_map(|l| l.strip_prefix("//!"))
        .map(str::trim)
    {
        match (fence, line.strip_prefix("```")) {
            (None, Some(info)) => fence = Some(info),
            (Some(""), Some(_)) => break,
            (Some(_), Some(_)) => fence = None,
            (Some(""), None) => block.push(line),
            _ => {}
        }
    }
    block.join("\n")
}

/// The crates a piece of Rust names at the start of a path (`tokio` in `#[tokio::main]`),
/// but for the standard library's.
fn crate_roots(code: &str) -> Vec<String> {
    let mut roots = Vec::new();
    let bytes = code.as_bytes();
    for (at, _) in code.match_indices("::") {
        let start = code[..at]
            .rfind(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .map_or(0, |i| i + 1);
        let name = &code[start..at];
        let inside_a_path = start >= 2 && &bytes[start - 2..start] == b"::";
        let lower = name.starts_with(|c: char| c.is_ascii_lowercase());
        if lower
            && !inside_a_path
            && !["std", "core", "alloc", "self", "super", "crate"].contains(&name)
        {
            roots.push(name.replace('_', "-"));
        }
    }
    roots.sort();
    roots.dedup();
    roots
}

/// `features = ["rt", "macros"]` of a dependency line.
fn features(line: &str) -> Vec<String> {
    line.split_once("features")
        .and_then(|(_, rest)| rest.split_once('[')?.1.split_once(']'))
        .map(|(list, _)| {
            list.split(',')
                .map(|f| f.trim().trim_matches('"').to_owned())
                .filter(|f| !f.is_empty())
                .collect()
        })
        .unwrap_or_default()
}

#[test]
fn point_3_every_family_names_the_dependencies_its_example_needs() {
    let mut checked = 0;
    for spec in specs() {
        let model = model(&spec);
        let files: std::collections::HashMap<_, _> = optobus_codegen::scaffold::files(&model)
            .into_iter()
            .collect();
        let (lib, readme, manifest) = (
            &files["src/lib.rs"],
            &files["README.md"],
            &files["Cargo.toml"],
        );
        // The doc example: the Rust block of the crate's first page.
        let example = rust_block(lib);
        assert!(example.contains("optobus_simulator"), "{example}");
        // Listed the same in the crate's docs and its README.
        let listed = dependencies(lib);
        assert_eq!(listed, dependencies(readme), "{}", spec.display());
        let names: Vec<&str> = listed.iter().map(|(name, _)| name.as_str()).collect();
        let roots = crate_roots(&example);
        let crate_name = optobus_codegen::scaffold::crate_dir(&model);
        let crate_name = format!(
            "optobus-{}",
            crate_name.file_name().unwrap().to_string_lossy()
        );
        assert_eq!(
            roots,
            [crate_name, "optobus-simulator".into(), "tokio".into()]
        );
        for root in roots {
            assert!(
                names.contains(&root.as_str()),
                "{}: the example uses `{root}`, the list names {names:?}",
                spec.display()
            );
        }
        // The features the doc test is built with (the crate's dev-dependencies) are listed.
        let tokio = listed
            .iter()
            .find(|(name, _)| name == "tokio")
            .map(|(_, line)| features(line));
        let built_with = dependencies(&manifest.replace("[dev-dependencies]", "[dependencies]"))
            .into_iter()
            .find(|(name, _)| name == "tokio")
            .map(|(_, line)| features(&line))
            .expect("tokio among the dev-dependencies");
        for feature in built_with {
            assert!(
                tokio
                    .as_ref()
                    .is_some_and(|listed| listed.contains(&feature)),
                "{}: tokio feature `{feature}` missing",
                spec.display()
            );
        }
        // And what to use for a real sensor.
        for text in [lib, readme] {
            assert!(
                text.contains(r#"features = ["serial"]"#) && text.contains("tcp_config(&DEVICE)"),
                "{}",
                spec.display()
            );
        }
        checked += 1;
    }
    assert!(checked >= 5, "{checked} families");
}
