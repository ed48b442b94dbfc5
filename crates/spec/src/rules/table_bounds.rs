//! `address-bounds`: registers and reserved ranges lie inside their table.

use crate::diagnostic::Diagnostic;
use crate::model::{Model, RegisterNames};

/// Rule name.
pub const RULE: &str = "address-bounds";

/// Checks bounds.
pub fn check(model: &Model, _: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    for register in &model.registers {
        let size = model.device.table_size(register.table);
        let end = register.address.0.saturating_add(model.extent(register));
        if end > size || register.address.0 > u32::from(u16::MAX) {
            let copy = register
                .repeat
                .as_ref()
                .map(|c| format!(" (copy {} of the repeat block)", c.number))
                .unwrap_or_default();
            let (name, table, start) =
                (&register.name, register.table.as_str(), register.address.0);
            let message = format!(
                "`{name}`{copy} occupies {table} addresses {start}..{end}, beyond the {table} table of {size}"
            );
            out.push(
                Diagnostic::at(RULE, &register.path.key("address"), message)
                    .label("out of the table")
                    .help("check the address, the word count, or `device.tables`"),
            );
        }
    }
    for reserved in &model.reserved {
        let size = model.device.table_size(reserved.table);
        if reserved.from > reserved.to || reserved.to >= size {
            out.push(
                Diagnostic::at(
                    RULE,
                    &reserved.path.key("to"),
                    format!(
                        "reserved range {}..={} is empty or beyond the {} table of {size}",
                        reserved.from,
                        reserved.to,
                        reserved.table.as_str()
                    ),
                )
                .label("bad range"),
            );
        }
    }
}
