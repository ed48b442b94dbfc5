//! `duplicate-name`: names are unique per kind (registers, enums, commands, groups, repeats);
//! `name-format`: names are snake_case.

use foldhash::{HashMap, HashMapExt};

use crate::diagnostic::Diagnostic;
use crate::model::{Kind, Model, RegisterNames};
use crate::source::Path;

/// Rule name of the uniqueness check.
pub const RULE: &str = "duplicate-name";
/// Rule name of the format check.
pub const FORMAT_RULE: &str = "name-format";

/// Reports every name of `items` given before; each item is a name and the path of what it
/// names (with the `name` key when `keyed`), joined only for a report.
fn unique<'a>(
    kind: &str,
    keyed: bool,
    items: impl Iterator<Item = (&'a str, &'a Path)>,
    out: &mut Vec<Diagnostic>,
) {
    let mut seen: HashMap<&str, &Path> = HashMap::new();
    let repeated = items.filter_map(|(name, path)| match seen.get(name) {
        Some(first) => Some((name, *first, path)),
        None => {
            seen.insert(name, path);
            None
        }
    });
    report(kind, keyed, repeated, out);
}

/// Reports each name given again: the name, where it was first given, and where again.
fn report<'a>(
    kind: &str,
    keyed: bool,
    repeated: impl Iterator<Item = (&'a str, &'a Path, &'a Path)>,
    out: &mut Vec<Diagnostic>,
) {
    let at = |path: &Path| {
        if keyed {
            path.key("name")
        } else {
            path.clone()
        }
    };
    for (name, first, again) in repeated {
        out.push(
            Diagnostic::at(
                RULE,
                &at(again),
                format!("{kind} `{name}` is defined twice"),
            )
            .label("defined again here")
            .also(&at(first), "first defined here")
            .help(format!(
                "rename one of them{}",
                if kind == "register" {
                    ", or declare the second with `alias_of:` if both views are meant"
                } else {
                    ""
                }
            )),
        );
    }
}

/// Checks uniqueness.
pub fn check(model: &Model, names: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    // The registers by name hold the first of each name: any other is a repeat.
    let registers = model.registers.iter().filter_map(|r| {
        let first = names
            .register(&r.name)
            .filter(|first| !std::ptr::eq(*first, r))?;
        Some((r.name.as_str(), &first.path, &r.path))
    });
    report("register", true, registers, out);
    let enums = model.enums.iter().filter(|e| e.shared);
    unique(
        "enum",
        false,
        enums.map(|e| (e.name.as_str(), &e.path)),
        out,
    );
    let commands = model.commands.iter().map(|c| (c.name.as_str(), &c.path));
    unique("command", true, commands, out);
    let groups = model.groups.iter().map(|g| (g.name.as_str(), &g.path));
    unique("group", true, groups, out);
    let repeats = model.repeats.iter().map(|r| (r.name.as_str(), &r.path));
    unique("repeat", true, repeats, out);
}

/// Keywords no Rust name may be, not even as `r#…`.
const RESERVED: [&str; 3] = ["self", "super", "crate"];

/// True for `snake_case` starting with a letter.
pub fn is_snake_case(name: &str) -> bool {
    name.starts_with(|c: char| c.is_ascii_lowercase())
        && name
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
        && !name.contains("__")
        && !name.ends_with('_')
}

/// Where a name is written: a path of the model and the key and index that lead from it to
/// the name, joined into one path only for a report.
type Place<'a> = (&'a Path, Option<&'static str>, Option<usize>);

/// A name with the place of its `name` key.
fn keyed<'a>(name: &'a str, path: &'a Path) -> (&'a str, Place<'a>) {
    (name, (path, Some("name"), None))
}

/// Checks that every name becomes a clean Rust identifier.
pub fn check_format(model: &Model, _: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    let root = Path::root();
    let mut names: Vec<(&str, Place<'_>)> = Vec::new();
    names.push((&model.family, (&root, Some("family"), None)));
    names.extend(super::declared(model).map(|r| {
        keyed(
            r.repeat
                .as_ref()
                .map_or(r.name.as_str(), |c| c.base.as_str()),
            &r.path,
        )
    }));
    for register in super::declared(model) {
        match &register.kind {
            Kind::Packed(fields) | Kind::Record(fields) => {
                names.extend(fields.iter().map(|f| keyed(&f.name, &f.path)));
            }
            Kind::Version(parts) => {
                names.extend(
                    parts
                        .iter()
                        .enumerate()
                        .map(|(i, p)| (p.as_str(), (&register.path, Some("parts"), Some(i)))),
                );
            }
            _ => {}
        }
    }
    for e in &model.enums {
        if e.shared {
            names.push((&e.name, (&e.path, None, None)));
        }
        names.extend(e.codes.iter().map(|c| keyed(&c.name, &c.path)));
    }
    names.extend(model.commands.iter().map(|c| keyed(&c.name, &c.path)));
    names.extend(model.groups.iter().map(|g| keyed(&g.name, &g.path)));
    names.extend(model.repeats.iter().map(|r| keyed(&r.name, &r.path)));
    let joined = |(path, key, index): Place<'_>| {
        let path = key.map_or_else(|| path.clone(), |key| path.key(key));
        match index {
            Some(index) => path.index(index),
            None => path,
        }
    };
    for (name, place) in names {
        if RESERVED.contains(&name) {
            out.push(
                Diagnostic::at(
                    FORMAT_RULE,
                    &joined(place),
                    format!("`{name}` is a Rust path keyword"),
                )
                .label("cannot name a generated item")
                .help("choose a more telling name"),
            );
        } else if !is_snake_case(name) {
            out.push(
                Diagnostic::at(
                    FORMAT_RULE,
                    &joined(place),
                    format!("`{name}` is not snake_case"),
                )
                .label("expected lowercase letters, digits and single underscores")
                .help("start with a letter, e.g. `us_100` rather than `100us`"),
            );
        }
    }
}
