//! `missing-doc`: everything a user sees in the driver's documentation has an English doc, and
//! every register cites the manual (`zh`, `section`).

use crate::diagnostic::Diagnostic;
use crate::model::{Model, RegisterNames};
use crate::source::Path;

/// Rule name.
pub const RULE: &str = "missing-doc";

fn missing(text: Option<&String>) -> bool {
    text.is_none_or(|t| t.trim().is_empty())
}

fn report(what: String, key: &str, path: Path, out: &mut Vec<Diagnostic>) {
    out.push(
        Diagnostic::at(RULE, &path, format!("{what} has no `{key}`"))
            .label(format!("add `{key}:` here"))
            .help(match key {
                "doc" => "one English sentence; it becomes the item's documentation",
                "zh" => "the manual's own name for the register",
                _ => "the manual section the entry comes from",
            }),
    );
}

/// Checks docs.
pub fn check(model: &Model, _: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    for register in super::declared(model) {
        let name = register
            .repeat
            .as_ref()
            .map_or(register.name.as_str(), |c| c.base.as_str());
        for (key, text) in [
            ("doc", &register.doc),
            ("zh", &register.zh),
            ("section", &register.section),
        ] {
            if missing(text.as_ref()) {
                let at = register.path.key("name");
                report(format!("register `{name}`"), key, at, out);
            }
        }
    }
    for def in &model.enums {
        if def.shared && missing(def.doc.as_ref()) {
            report(format!("enum `{}`", def.name), "doc", def.path.clone(), out);
        }
        for code in &def.codes {
            if missing(code.doc.as_ref()) {
                report(
                    format!("code `{}` of `{}`", code.name, def.name),
                    "doc",
                    code.path.key("name"),
                    out,
                );
            }
        }
    }
    let named = model
        .commands
        .iter()
        .map(|c| ("command", &c.name, &c.doc, &c.path))
        .chain(
            model
                .groups
                .iter()
                .map(|g| ("group", &g.name, &g.doc, &g.path)),
        )
        .chain(
            model
                .repeats
                .iter()
                .map(|r| ("repeat", &r.name, &r.doc, &r.path)),
        );
    for (what, name, doc, path) in named {
        if missing(doc.as_ref()) {
            report(format!("{what} `{name}`"), "doc", path.key("name"), out);
        }
    }
}
