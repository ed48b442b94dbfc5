//! Checks across a bus file's items: unique names, ports and slaves, and line formats the
//! devices' manuals list. Run once the items are read; each problem points at its place.

use std::collections::HashMap;

use optobus_codec::LineFormat;
use optobus_device::DeviceInfo;
use optobus_spec::source::Span;
use optobus_spec::Diagnostic;

use super::read::{Parsed, Seen};
use super::Port;

/// Every cross-item problem of `parsed`, among every line and device as far as each read
/// (a device with a misspelt model still takes its slave); fills in each serial line's format
/// from its devices' factory format where the file gives none.
pub(super) fn check(parsed: &mut Parsed) -> Vec<Diagnostic> {
    let mut problems = Vec::new();
    let Seen { lines, devices } = &parsed.seen;
    unique(
        lines
            .iter()
            .filter_map(|l| Some((l.name.as_deref()?, l.name_span))),
        "duplicate-line",
        |name| format!("two lines are called `{name}`"),
        &mut problems,
    );
    unique(
        lines.iter().filter_map(|l| match &l.port {
            Some(port) if *port != Port::Simulated => Some((port.address(), l.port_span)),
            _ => None,
        }),
        "duplicate-port",
        |port| format!("two lines use the port `{port}`"),
        &mut problems,
    );
    let gateways: Vec<(String, Span)> = lines
        .iter()
        .filter_map(|l| l.gateway.map(|(listen, span)| (listen.to_string(), span)))
        .collect();
    unique(
        gateways
            .iter()
            .map(|(address, span)| (address.as_str(), *span)),
        "duplicate-gateway",
        |address| format!("two gateways listen on {address}"),
        &mut problems,
    );
    unique(
        devices
            .iter()
            .filter_map(|d| Some((d.name.as_deref()?, d.name_span))),
        "duplicate-device",
        |name| format!("two devices are called `{name}`"),
        &mut problems,
    );
    let slaves: Vec<(String, Span)> = devices
        .iter()
        .filter_map(|d| Some((format!("{}\u{0}{}", d.line?, d.slave?), d.slave_span)))
        .collect();
    unique(
        slaves.iter().map(|(key, span)| (key.as_str(), *span)),
        "duplicate-slave",
        |key| {
            let (line, slave) = key.split_once('\u{0}').unwrap_or((key, ""));
            let line = line
                .parse::<usize>()
                .ok()
                .and_then(|i| lines.get(i))
                .and_then(|l| l.name.as_deref())
                .unwrap_or("?");
            format!("two devices on line `{line}` are slave {slave}")
        },
        &mut problems,
    );
    for device in devices {
        let Some(line) = device.line.and_then(|i| lines.get(i)) else {
            continue;
        };
        // The measurements' virtual unit answers its unit id itself: a device there could
        // never be reached through the gateway.
        if let (Some((unit, span)), Some(slave)) = (line.measurements_unit, device.slave) {
            if unit == slave {
                problems.push(
                    Diagnostic::at_span(
                        "measurements-unit-clash",
                        span,
                        format!(
                            "the gateway of line `{}` answers unit {unit} with the measurements, \
                             but device `{}` is slave {unit}",
                            line.name.as_deref().unwrap_or("?"),
                            device.name.as_deref().unwrap_or("?"),
                        ),
                    )
                    .also_at(device.slave_span, "the device's slave")
                    .help("give `measurements_unit` a unit id no device of the line has (default 255)"),
                );
            }
        }
        if let (Some(span), Some(port)) = (device.faults, &line.port) {
            if *port != Port::Simulated {
                problems.push(
                    Diagnostic::at_span(
                        "faults-off-simulation",
                        span,
                        format!(
                            "`faults` are injected by a simulator: line `{}` is real",
                            line.name.as_deref().unwrap_or("?")
                        ),
                    )
                    .help("give `faults` to devices on a `simulated: true` line"),
                );
            }
        }
    }
    formats(parsed, &mut problems);
    problems
}

/// Reports every second (third, …) occurrence of a key, pointing back at the first.
fn unique<'a>(
    keys: impl Iterator<Item = (&'a str, Span)>,
    rule: &'static str,
    message: impl Fn(&str) -> String,
    problems: &mut Vec<Diagnostic>,
) {
    let mut first: HashMap<&str, Span> = HashMap::new();
    for (key, span) in keys {
        match first.get(key) {
            Some(&earlier) => problems.push(
                Diagnostic::at_span(rule, span, message(key))
                    .label("again here")
                    .also_at(earlier, "first here")
                    .help("each must be unique"),
            ),
            None => {
                first.insert(key, span);
            }
        }
    }
}

/// The format `device`'s manual gives at the factory, if it speaks RTU.
fn factory(device: &DeviceInfo) -> Option<LineFormat> {
    device.rtu.map(|rtu| LineFormat {
        baud: rtu.default_baud,
        parity: rtu.parity,
        data_bits: rtu.data_bits,
        stop_bits: rtu.stop_bits,
    })
}

/// Whether `device`'s manual lists `format`: one of its baud rates, its character format.
fn lists(device: &DeviceInfo, format: LineFormat) -> bool {
    device.rtu.is_some_and(|rtu| {
        rtu.bauds.contains(&format.baud)
            && rtu.parity == format.parity
            && rtu.data_bits == format.data_bits
            && rtu.stop_bits == format.stop_bits
    })
}

/// The line formats against the devices' manuals, for every line that read whole; a device
/// whose model did not read is left out.
fn formats(parsed: &mut Parsed, problems: &mut Vec<Diagnostic>) {
    let Seen { lines, devices } = &parsed.seen;
    for (index, (line, place)) in parsed.lines.iter_mut().zip(lines).enumerate() {
        let Some(line) = line else { continue };
        let Some(format) = line.format else { continue };
        let devices: Vec<&DeviceInfo> = devices
            .iter()
            .filter(|d| d.line == Some(index))
            .filter_map(|d| d.model)
            .collect();
        if let Some(device) = devices.iter().find(|d| d.rtu.is_none()) {
            problems.push(
                Diagnostic::at_span(
                    "line-format",
                    place.port_span,
                    format!(
                        "line `{}` carries RTU frames, which {} does not speak",
                        line.name,
                        name(device)
                    ),
                )
                .help("put it on a `tcp` line"),
            );
            continue;
        }
        if !place.format_given {
            let mut factories: Vec<(LineFormat, &DeviceInfo)> = devices
                .iter()
                .filter_map(|d| factory(d).map(|f| (f, *d)))
                .collect();
            factories.dedup_by_key(|(f, _)| *f);
            match factories.as_slice() {
                [] => {}
                [(format, _)] => line.format = Some(*format),
                several => problems.push(Diagnostic::at_span("line-format", place.name_span, format!(
                        "the devices on line `{}` have different factory formats: {}",
                        line.name,
                        several
                            .iter()
                            .map(|(f, d)| format!("{} {f}", name(d)))
                            .collect::<Vec<_>>()
                            .join(", ")
                    )).help("give the line's `baud`, `parity`, `data_bits` and `stop_bits` as the devices are set")),
            }
            continue;
        }
        if place.any_format {
            continue;
        }
        for device in devices.iter().filter(|d| !lists(d, format)) {
            let rtu = device.rtu.expect("devices without RTU were reported above");
            problems.push(
                Diagnostic::at_span(
                    "line-format",
                    place.format,
                    format!(
                        "line `{}` runs {format}, which the {} manual does not list",
                        line.name,
                        name(device)
                    ),
                )
                .help(format!(
                    "{} takes {} baud, {}; `any_format: true` allows others",
                    name(device),
                    rtu.bauds
                        .iter()
                        .map(u32::to_string)
                        .collect::<Vec<_>>()
                        .join(", "),
                    factory(device).map_or(String::new(), character_format)
                )),
            );
        }
    }
}

/// `8N1` of a format.
fn character_format(format: LineFormat) -> String {
    let full = format.to_string();
    full.rsplit(' ').next().unwrap_or(&full).to_owned()
}

/// The model's name as users type it.
fn name(device: &DeviceInfo) -> String {
    device.model_name().to_string()
}
