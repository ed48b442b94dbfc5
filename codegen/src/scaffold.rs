//! `optobus-codegen new specs/<family>.yaml`: the driver crate of a checked spec, from the one
//! set of templates in `codegen/templates/` (every family crate is exactly what they give).

use std::path::{Path, PathBuf};

use crate::emit::camel;
use optobus_spec::model::{Kind, Model};

/// The templates, as `(file in the crate, text)`; `{family}`, `{crate}`, `{lib}`, `{driver}`,
/// `{title}` and `{example}` are filled in.
const TEMPLATES: [(&str, &str); 4] = [
    ("Cargo.toml", include_str!("../templates/Cargo.toml.in")),
    ("build.rs", include_str!("../templates/build.rs.in")),
    ("src/lib.rs", include_str!("../templates/lib.rs.in")),
    ("README.md", include_str!("../templates/README.md.in")),
];

/// The links a driver crate holds, as `(path inside the crate, target)`: its spec (so that the
/// package carries it while `specs/` stays the one place to edit) and the licence texts.
pub fn links(model: &Model) -> Vec<(String, String)> {
    let family = &model.family;
    vec![
        (
            format!("specs/{family}.yaml"),
            format!("../../../specs/{family}.yaml"),
        ),
        ("LICENSE-MIT".into(), "../../LICENSE-MIT".into()),
        ("LICENSE-APACHE".into(), "../../LICENSE-APACHE".into()),
    ]
}

/// `crates/<family-with-dashes>`, relative to the workspace root.
pub fn crate_dir(model: &Model) -> PathBuf {
    Path::new("crates").join(model.family.replace('_', "-"))
}

/// The files of the driver crate of `model`: (path inside the crate, content).
pub fn files(model: &Model) -> Vec<(&'static str, String)> {
    let family = model.family.as_str();
    let dashed = family.replace('_', "-");
    let values = [
        ("{family}", family.to_owned()),
        ("{crate}", format!("optobus-{dashed}")),
        ("{lib}", format!("optobus_{family}")),
        ("{driver}", camel(family)),
        ("{title}", model.title.clone()),
        ("{model}", dashed.clone()),
        ("{example}", example(model)),
    ];
    TEMPLATES
        .iter()
        .map(|(file, template)| {
            let text = values
                .iter()
                .fold((*template).to_owned(), |text, (key, value)| {
                    text.replace(key, value)
                });
            (*file, text)
        })
        .collect()
}

/// The doc example's last lines: read the first group that needs no copy number and turns no
/// buffer page, or else wait until the device answers.
fn example(model: &Model) -> String {
    let plain = model.groups.iter().find(|group| {
        group.registers.iter().all(|(name, _)| {
            model
                .register(name)
                .is_some_and(|r| r.read_side_effect.is_none() && !matches!(r.kind, Kind::Record(_)))
        })
    });
    let lines = match plain {
        Some(group) => vec![
            format!("let readings = sensor.read_{}().await?;", group.name),
            "println!(\"{readings:?}\");".to_owned(),
        ],
        None => vec!["sensor.wait_ready().await?;".to_owned()],
    };
    lines.iter().map(|line| format!("//! {line}\n")).collect()
}

/// Why [`write()`] wrote nothing.
#[derive(Debug)]
pub enum ScaffoldError {
    /// The crate's directory exists: a scaffold never overwrites.
    Exists(PathBuf),
    /// A file could not be written.
    Io(PathBuf, std::io::Error),
}

impl std::fmt::Display for ScaffoldError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Exists(dir) => write!(f, "{} exists; a scaffold never overwrites", dir.display()),
            Self::Io(path, error) => write!(f, "cannot write {}: {error}", path.display()),
        }
    }
}

/// Writes the driver crate of `model` under `root` (the workspace root) and returns its
/// directory; refuses when the directory exists.
pub fn write(model: &Model, root: &Path) -> Result<PathBuf, ScaffoldError> {
    let dir = root.join(crate_dir(model));
    if dir.exists() {
        return Err(ScaffoldError::Exists(dir));
    }
    for (file, text) in files(model) {
        let path = dir.join(file);
        let written = path
            .parent()
            .map_or(Ok(()), std::fs::create_dir_all)
            .and_then(|()| std::fs::write(&path, text));
        written.map_err(|e| ScaffoldError::Io(path, e))?;
    }
    for (file, target) in links(model) {
        let path = dir.join(&file);
        let linked = path
            .parent()
            .map_or(Ok(()), std::fs::create_dir_all)
            .and_then(|()| link(&target, &path));
        linked.map_err(|e| ScaffoldError::Io(path, e))?;
    }
    Ok(dir)
}

#[cfg(unix)]
fn link(target: &str, path: &Path) -> std::io::Result<()> {
    std::os::unix::fs::symlink(target, path)
}

/// Where links are not to be had, a copy (to be refreshed by hand when the spec changes).
#[cfg(not(unix))]
fn link(target: &str, path: &Path) -> std::io::Result<()> {
    let source = path.parent().unwrap_or(path).join(target);
    std::fs::copy(source, path).map(|_| ())
}
