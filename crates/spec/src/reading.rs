//! The positioned reading kit every YAML file of the project is read with (specs and bus
//! files): a mapping's keys checked against those its reader knows, each problem with the
//! node it is at. Each reader words its own messages; the kit finds the problems.

use foldhash::{HashMap, HashMapExt};

use crate::source::{Node, Span};

/// A problem with one key of a mapping.
#[derive(Clone, Copy, Debug)]
pub enum KeyProblem<'n> {
    /// The key is not text (null, a list, a mapping).
    NotText {
        /// The key.
        key: &'n Node,
    },
    /// The key is text its reader does not know, given for the first time.
    Unknown {
        /// Its text.
        name: &'n str,
        /// The key.
        key: &'n Node,
    },
    /// The key was given before in the same mapping.
    Repeated {
        /// Its text.
        name: &'n str,
        /// The key, again.
        key: &'n Node,
        /// Where it was first given.
        first: Span,
        /// Whether its reader knows it (a reader may word an unknown key given twice as
        /// unknown).
        known: bool,
    },
}

/// The entries of a mapping by the keys its reader knows: one slot per known key (in the
/// order of `known`), holding the key and the value where it was first given.
pub type Slots<'n> = Vec<Option<(&'n Node, &'n Node)>>;

/// Checks the keys of a mapping's `entries` against `known`, in source order: every key that
/// is not text, unknown or repeated goes to `report`. Returns the first entry of each known
/// key. Linear in the entries (an unknown key is looked up in a hash map, made only when one
/// is found).
pub fn check_keys<'n>(
    entries: &'n [(Node, Node)],
    known: &[&str],
    mut report: impl FnMut(KeyProblem<'n>),
) -> Slots<'n> {
    let mut slots: Slots<'n> = vec![None; known.len()];
    let mut unknown: Option<HashMap<&'n str, Span>> = None;
    for (key, value) in entries {
        let Some(name) = key.scalar() else {
            report(KeyProblem::NotText { key });
            continue;
        };
        match known.iter().position(|known| *known == name) {
            Some(slot) => match slots[slot] {
                Some((first, _)) => report(KeyProblem::Repeated {
                    name,
                    key,
                    first: first.span,
                    known: true,
                }),
                None => slots[slot] = Some((key, value)),
            },
            None => {
                let seen = unknown.get_or_insert_with(HashMap::new);
                match seen.get(name) {
                    Some(&first) => report(KeyProblem::Repeated {
                        name,
                        key,
                        first,
                        known: false,
                    }),
                    None => {
                        seen.insert(name, key.span);
                        report(KeyProblem::Unknown { name, key });
                    }
                }
            }
        }
    }
    slots
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::SourceFile;

    /// What `check_keys` reports for a mapping, as `(problem, name, line)`, and the lines of
    /// the entries it keeps.
    fn checked(text: &str, known: &[&str]) -> (Vec<(&'static str, String, usize)>, Vec<usize>) {
        let source = SourceFile::new("test.yaml", text);
        let root = source.root.as_ref().expect("a tree");
        let mut problems = Vec::new();
        let slots = check_keys(root.entries().expect("a mapping"), known, |problem| {
            problems.push(match problem {
                KeyProblem::NotText { key } => ("not text", String::new(), key.span.line),
                KeyProblem::Unknown { name, key } => ("unknown", name.into(), key.span.line),
                KeyProblem::Repeated {
                    name,
                    key,
                    first,
                    known,
                } => (
                    if known {
                        "repeated"
                    } else {
                        "repeated unknown"
                    },
                    format!("{name} first at {}", first.line),
                    key.span.line,
                ),
            });
        });
        let kept = slots
            .iter()
            .flatten()
            .map(|(key, _)| key.span.line)
            .collect();
        (problems, kept)
    }

    /// The one key check of specs and bus files: every problem once, at its key, in file
    /// order; the first of a repeated key is the one kept.
    #[test]
    fn every_key_problem_is_found_once_at_its_key() {
        let text = "a: 1\nb: 2\nzz: 3\na: 4\n~: 5\nzz: 6\na: 7\n";
        let (problems, kept) = checked(text, &["a", "b", "c"]);
        assert_eq!(
            problems,
            [
                ("unknown", "zz".into(), 3),
                ("repeated", "a first at 1".into(), 4),
                ("not text", String::new(), 5),
                ("repeated unknown", "zz first at 3".into(), 6),
                ("repeated", "a first at 1".into(), 7),
            ]
        );
        assert_eq!(kept, [1, 2]);
    }

    /// Linear in the keys: a mapping of 100,000 distinct unknown keys is checked with one
    /// report each (a check comparing each key with those before would take minutes).
    #[test]
    fn a_hundred_thousand_unknown_keys_are_each_reported_once() {
        let text: String = (0..100_000).map(|i| format!("k{i}: 0\n")).collect();
        let (problems, kept) = checked(&text, &["a"]);
        assert_eq!(problems.len(), 100_000);
        assert!(problems.iter().all(|(problem, _, _)| *problem == "unknown"));
        assert!(kept.is_empty());
    }
}
