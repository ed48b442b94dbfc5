//! `write-order`: a write order only makes sense on a writable register of two words written
//! as two single-register writes.

use crate::diagnostic::Diagnostic;
use crate::model::{LongWrites, Model, RegisterNames};

/// Rule name.
pub const RULE: &str = "write-order";

/// Checks write orders.
pub fn check(model: &Model, _: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    for register in super::declared(model) {
        if register.write_order.is_none() {
            continue;
        }
        let problem = if !register.access.writable() {
            Some("it is read-only")
        } else if register.words.0 != 2 {
            Some("it is not a two-word value")
        } else if model.protocol.long_writes == LongWrites::Wide {
            Some("this device writes 32-bit values in one 4-byte FC06")
        } else {
            None
        };
        if let Some(problem) = problem {
            out.push(
                Diagnostic::at(
                    RULE,
                    &register.path.key("write_order"),
                    format!("`{}` has a write order, but {problem}", register.name),
                )
                .label("write order not applicable")
                .help("remove `write_order`, or fix the register's access or type"),
            );
        }
    }
}
