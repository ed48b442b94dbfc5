//! `repeat-stride`: copies of a repeat block do not overlap each other, and a block has a
//! positive count.

use crate::diagnostic::Diagnostic;
use crate::model::{Model, RegisterNames};

/// Rule name.
pub const RULE: &str = "repeat-stride";

/// Checks repeat arithmetic.
pub fn check(model: &Model, _: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    for repeat in &model.repeats {
        if repeat.count < 2 {
            out.push(
                Diagnostic::at(
                    RULE,
                    &repeat.path.key("count"),
                    format!(
                        "repeat `{}` has {} copies; a block repeats at least twice",
                        repeat.name, repeat.count
                    ),
                )
                .label("count too small"),
            );
        }
    }
    for register in model
        .registers
        .iter()
        .filter(|r| r.repeat.as_ref().is_some_and(|c| c.number == 1))
    {
        let Some(copy) = &register.repeat else {
            continue;
        };
        let Some(stride) = copy.stride else { continue };
        let extent = model.extent(register);
        if stride < extent {
            out.push(
                Diagnostic::at(
                    RULE,
                    &register.path.key("address"),
                    format!(
                        "copies of `{}` overlap: it takes {extent} addresses but the stride is {stride}",
                        copy.base
                    ),
                )
                .label("repeated with this stride")
                .help("the stride must be at least the register's extent"),
            );
        }
    }
}
