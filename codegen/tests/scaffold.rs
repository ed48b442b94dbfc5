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

fn model(spec: &Path) -> optobus_codegen::Model {
    optobus_codegen::check_file(spec).unwrap_or_else(|r| panic!("{}", r.render()))
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
