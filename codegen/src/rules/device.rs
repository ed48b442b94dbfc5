//! `device`: device facts agree with themselves and with Modbus (slave range, bauds, function
//! codes, read limit).

use crate::diagnostic::Diagnostic;
use crate::model::Model;
use crate::source::Path;

/// Rule name.
pub const RULE: &str = "device";

/// Checks device facts.
pub fn check(model: &Model, out: &mut Vec<Diagnostic>) {
    let device = &model.device;
    let path = Path::root().key("device");
    if !(device.min_slave..=device.max_slave).contains(&device.default_slave)
        || device.max_slave > 247
    {
        out.push(
            Diagnostic::at(
                RULE,
                &path.key("slave").key("default"),
                format!(
                    "default slave {} is outside {}..={} (Modbus allows 1..=247)",
                    device.default_slave, device.min_slave, device.max_slave
                ),
            )
            .label("default slave address"),
        );
    }
    if let Some(rtu) = &device.rtu {
        if !rtu.bauds.contains(&rtu.default_baud) {
            out.push(
                Diagnostic::at(
                    RULE,
                    &path.key("transports").key("rtu").key("default_baud"),
                    format!(
                        "default baud {} is not among the allowed bauds",
                        rtu.default_baud
                    ),
                )
                .label("not in `bauds`"),
            );
        }
    }
    if device.max_read_words == 0 || device.max_read_words > optobus_codec::MAX_READ_WORDS {
        out.push(
            Diagnostic::at(
                RULE,
                &path.key("max_read_words"),
                format!("a read takes 1 to 125 words, not {}", device.max_read_words),
            )
            .label("out of range"),
        );
    }
    for (i, function) in device.functions.iter().enumerate() {
        if ![3, 4, 6].contains(function) {
            out.push(
                Diagnostic::at(
                    RULE,
                    &path.key("functions").index(i),
                    format!("function code {function} is not one optobus implements"),
                )
                .label("expected 3, 4 or 6"),
            );
        }
    }
    if device.rtu.is_none() && device.tcp.is_none() {
        out.push(
            Diagnostic::at(RULE, &path.key("transports"), "the device has no transport")
                .label("declare `rtu`, `tcp` or both"),
        );
    }
}
