//! Embeds every spec of `specs/` in the tool: its built-in models are described from these
//! texts at startup, through the same code as `--spec`. A spec added to `specs/` is a model of
//! the next build with no edit here.

use std::fmt::Write as _;
use std::path::Path;

fn main() {
    // Which peer programs the interoperability tests can use: without one, its tests are
    // listed as ignored with the reason (see optobus-testkit).
    use optobus_testkit::build::{MBPOLL, MOSQUITTO, MOSQUITTO_PUB, PROMTOOL, PYMODBUS, SOCAT};
    optobus_testkit::build::peers(&[MBPOLL, SOCAT, MOSQUITTO, MOSQUITTO_PUB, PROMTOOL, PYMODBUS]);
    // A link to the workspace's `specs/`, so that the package carries the specs.
    let specs = Path::new(env!("CARGO_MANIFEST_DIR")).join("specs");
    // The directory for a spec added or removed, each file for an edit.
    println!("cargo::rerun-if-changed={}", specs.display());
    let mut paths: Vec<_> = std::fs::read_dir(&specs)
        .expect("specs/ is readable")
        .filter_map(|entry| Some(entry.ok()?.path()))
        .filter(|path| path.extension().is_some_and(|e| e == "yaml"))
        .collect();
    paths.sort();
    let mut out = String::from(
        "/// Every spec of `specs/` at build time: (file name, text).\n\
         pub(crate) const SPECS: &[(&str, &str)] = &[\n",
    );
    for path in paths {
        println!("cargo::rerun-if-changed={}", path.display());
        // A built-in spec passes the checks, or the tool does not build.
        if let Err(rejected) = optobus_spec::check_file(&path) {
            eprint!("{}", rejected.render());
            println!(
                "cargo::error={} does not pass the spec checks",
                path.display()
            );
        }
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .expect("UTF-8 file name");
        let path = path.canonicalize().expect("spec path");
        let _ = writeln!(
            out,
            "    ({name:?}, include_str!({:?})),",
            path.display().to_string()
        );
    }
    out.push_str("];\n");
    let out_dir = std::env::var("OUT_DIR").expect("OUT_DIR");
    std::fs::write(Path::new(&out_dir).join("specs.rs"), out).expect("write specs.rs");
}
