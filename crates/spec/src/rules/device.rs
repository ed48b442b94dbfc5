//! `device`: device facts agree with themselves and with Modbus (slave range, bauds and line
//! format, function codes, read limit, table sizes).

use crate::diagnostic::Diagnostic;
use optobus_codec::LineFormatError;

use crate::model::{Model, RegisterNames, Table};
use crate::source::Path;

/// Rule name.
pub const RULE: &str = "device";

/// Checks device facts.
pub fn check(model: &Model, _: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
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
        let rtu_path = path.key("transports").key("rtu");
        let line = |baud| optobus_codec::LineFormat {
            baud,
            data_bits: rtu.data_bits,
            parity: rtu.parity,
            stop_bits: rtu.stop_bits,
        };
        for (i, baud) in rtu.bauds.iter().enumerate() {
            if line(*baud).check() == Err(LineFormatError::ZeroBaud) {
                out.push(
                    Diagnostic::at(RULE, &rtu_path.key("bauds").index(i), "a baud rate of 0")
                        .label("no line runs at 0 baud"),
                );
            }
        }
        match line(rtu.default_baud).check() {
            Err(LineFormatError::DataBits(bits)) => out.push(
                Diagnostic::at(
                    RULE,
                    &rtu_path.key("data_bits"),
                    format!("{bits} data bits: a serial line carries 5 to 8"),
                )
                .label("out of range")
                .help("Modbus RTU uses 8"),
            ),
            Err(LineFormatError::StopBits(bits)) => out.push(
                Diagnostic::at(
                    RULE,
                    &rtu_path.key("stop_bits"),
                    format!("{bits} stop bits: a serial line has 1 or 2"),
                )
                .label("out of range"),
            ),
            _ => {}
        }
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
    if device.functions.is_empty() {
        out.push(
            Diagnostic::at(
                RULE,
                &path.key("functions"),
                "the device answers no function code",
            )
            .label("empty")
            .help("list the codes the manual names, e.g. `[3, 4, 6]`"),
        );
    }
    for (i, function) in device.functions.iter().enumerate() {
        if device.functions[..i].contains(function) {
            out.push(
                Diagnostic::at(
                    RULE,
                    &path.key("functions").index(i),
                    format!("function code {function} is listed twice"),
                )
                .label("again here"),
            );
        } else if ![3, 4, 6].contains(function) {
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
    for table in [Table::Holding, Table::Input] {
        let size = device.table_size(table);
        if size > u32::from(u16::MAX) {
            out.push(
                Diagnostic::at(
                    RULE,
                    &path.key("tables").key(table.as_str()),
                    format!(
                        "a {} table of {size} registers: Modbus addresses end at 65535",
                        table.as_str()
                    ),
                )
                .label("more registers than 16-bit addresses"),
            );
        }
    }
    if device.tcp.as_ref().is_some_and(|tcp| tcp.port == 0) {
        out.push(
            Diagnostic::at(
                RULE,
                &path.key("transports").key("tcp").key("port"),
                "TCP port 0",
            )
            .label("no server listens on port 0")
            .help("Modbus TCP uses 502"),
        );
    }
    if device.rtu.is_none() && device.tcp.is_none() {
        out.push(
            Diagnostic::at(RULE, &path.key("transports"), "the device has no transport")
                .label("declare `rtu`, `tcp` or both"),
        );
    }
}
