//! Reading a bus file's tree into its structs, every reading error collected with its place.

use std::time::Duration;

use optobus_codec::{LineFormat, Parity};
use optobus_device::DeviceInfo;
use optobus_spec::source::{Node, Span, Value};

use super::measurements::Measurements;
use super::outputs::ReadOutputs;

use super::reading::{has_port, listen_address, FileReader, HELP};
use super::{
    BusFile, DeviceConfig, GatewayConfig, LineConfig, Port, DEFAULT_GATEWAY_CLIENTS,
    DEFAULT_GATEWAY_IDLE, DEFAULT_MEASUREMENTS_UNIT,
};

/// The Modbus serial-line specification's turnaround delay after a broadcast.
pub(crate) const DEFAULT_BROADCAST_TURNAROUND: Duration = Duration::from_millis(100);

pub(super) const LINE_KEYS: &[&str] = &[
    "name",
    "serial",
    "tcp",
    "rtu_over_tcp",
    "simulated",
    "baud",
    "parity",
    "data_bits",
    "stop_bits",
    "any_format",
    "broadcast_turnaround",
    "gateway",
];
pub(super) const GATEWAY_KEYS: &[&str] = &[
    "listen",
    "clients",
    "queue",
    "idle",
    "writes",
    "measurements_unit",
];
pub(super) const PORT_KEYS: &[&str] = &["serial", "tcp", "rtu_over_tcp", "simulated"];
pub(super) const DEVICE_KEYS: &[&str] = &[
    "name",
    "model",
    "spec",
    "line",
    "slave",
    "timeout",
    "retries",
    "silence_before",
    "silence_after",
    "power_up",
    "poll",
    "faults",
    "writable",
];
pub(super) const POLL_KEYS: &[&str] = &["read", "every", "priority"];
pub(super) const TOP_KEYS: &[&str] = &["lines", "devices", "measurements", "outputs"];

/// A bus file read: every line and device whole where it read whole, and what the checks
/// across items see of each, whole or not.
pub(super) struct Parsed {
    /// The lines, in file order; `None` where a line did not read whole (and said why).
    pub(super) lines: Vec<Option<LineConfig>>,
    /// The devices, in file order; `None` where a device did not read whole.
    pub(super) devices: Vec<Option<DeviceConfig>>,
    /// `None` where the measurements did not read (and said why).
    pub(super) measurements: Option<Measurements>,
    pub(super) seen: Seen,
}

impl Parsed {
    /// The bus file, when every line and device read whole.
    pub(super) fn file(self) -> Option<BusFile> {
        Some(BusFile {
            lines: self.lines.into_iter().collect::<Option<_>>()?,
            devices: self.devices.into_iter().collect::<Option<_>>()?,
            measurements: self.measurements?,
        })
    }
}

/// What the checks across items see of every line and device, by index in [`Parsed`]: what
/// could be read of each, and where it was written. A device whose model is misspelt still
/// has its name, line and slave checked against the others.
#[derive(Default)]
pub(super) struct Seen {
    pub(super) lines: Vec<LineSeen>,
    pub(super) devices: Vec<DeviceSeen>,
}

pub(super) struct LineSeen {
    /// Its name, if it reads.
    pub(super) name: Option<String>,
    pub(super) name_span: Span,
    /// Its port, if it reads.
    pub(super) port: Option<Port>,
    pub(super) port_span: Span,
    /// The format keys given (baud first), or the line's name when none is.
    pub(super) format: Span,
    /// The line allows formats its devices' manuals do not list.
    pub(super) any_format: bool,
    /// The file gave a format (else the devices' factory format is taken).
    pub(super) format_given: bool,
    /// Its gateway's address and where it is written, if it reads.
    pub(super) gateway: Option<(std::net::SocketAddr, Span)>,
    /// Its gateway's measurements unit id and where it is given (or the gateway, for the
    /// default), if it reads.
    pub(super) measurements_unit: Option<(u8, Span)>,
}

pub(super) struct DeviceSeen {
    /// Its name, if it reads.
    pub(super) name: Option<String>,
    pub(super) name_span: Span,
    /// Its line (an index in [`Seen::lines`]), if it reads.
    pub(super) line: Option<usize>,
    /// Its slave address, given or its model's default, if either reads.
    pub(super) slave: Option<u8>,
    pub(super) slave_span: Span,
    /// Its model, if it reads.
    pub(super) model: Option<&'static DeviceInfo>,
    /// Where its `faults` are written.
    pub(super) faults: Option<Span>,
}

impl FileReader<'_> {
    /// The whole file, its `outputs` read by `outputs` (left unread without one).
    pub(super) fn bus(
        &mut self,
        root: &Node,
        outputs: Option<&mut dyn ReadOutputs>,
    ) -> Option<Parsed> {
        let top = self.mapping(root, "the bus file", TOP_KEYS)?;
        let mut lines = Vec::new();
        let mut devices = Vec::new();
        let mut seen = Seen::default();
        let lines_node = top.iter().find(|(k, _)| k.scalar() == Some("lines"));
        match lines_node {
            Some((_, node)) => {
                for item in self.list(node, "`lines`").unwrap_or_default() {
                    if let Some((line, line_seen)) = self.line(item) {
                        lines.push(line);
                        seen.lines.push(line_seen);
                    }
                }
            }
            None => self.error(root.span, "the bus file has no `lines`", HELP),
        }
        let devices_node = top.iter().find(|(k, _)| k.scalar() == Some("devices"));
        match devices_node {
            Some((_, node)) => {
                for item in self.list(node, "`devices`").unwrap_or_default() {
                    if let Some((device, device_seen)) = self.device(item, &seen.lines) {
                        devices.push(device);
                        seen.devices.push(device_seen);
                    }
                }
            }
            None => self.error(root.span, "the bus file has no `devices`", HELP),
        }
        let measurements = match top.iter().find(|(k, _)| k.scalar() == Some("measurements")) {
            Some((_, node)) if !node.is_null() => {
                let known: Vec<_> = seen
                    .devices
                    .iter()
                    .zip(&devices)
                    .map(|(seen, config)| (seen.name.clone(), config.as_ref(), seen.model))
                    .collect();
                self.measurements(node, &known)
            }
            _ => Some(Measurements::default()),
        };
        let outputs_node = top
            .iter()
            .find(|(k, _)| k.scalar() == Some("outputs"))
            .map(|(_, node)| node)
            .filter(|node| !node.is_null());
        let names: Vec<(&str, Span)> = seen
            .devices
            .iter()
            .filter_map(|d| Some((d.name.as_deref()?, d.name_span)))
            .collect();
        self.outputs(outputs_node, &names, outputs);
        Some(Parsed {
            lines,
            devices,
            measurements,
            seen,
        })
    }

    fn line(&mut self, node: &Node) -> Option<(Option<LineConfig>, LineSeen)> {
        let pairs = self.mapping(node, "a line", LINE_KEYS)?;
        let get = |key: &str| pairs.iter().find(|(k, _)| k.scalar() == Some(key));
        let name_node = get("name").map(|(_, v)| v);
        let name = match name_node {
            Some(v) => self.text(v, "a line's `name`").map(str::to_owned),
            None => {
                self.error(
                    node.span,
                    "a line needs a `name`",
                    "devices name their line",
                );
                None
            }
        };
        let ports: Vec<&(Node, Node)> = pairs
            .iter()
            .filter(|(k, _)| k.scalar().is_some_and(|k| PORT_KEYS.contains(&k)))
            .collect();
        let port = match ports.as_slice() {
            [(key, value)] => self.port(key, value),
            [] => {
                self.error(
                    name_node.map_or(node.span, |n| n.span),
                    "a line needs one of `serial`, `tcp`, `rtu_over_tcp` or `simulated`",
                    "e.g. `serial: /dev/ttyUSB0`, `tcp: 192.168.0.10:502`, `simulated: true`",
                );
                None
            }
            [_, (second, _), ..] => {
                self.error(
                    second.span,
                    "a line has one port: this is its second",
                    "give one of `serial`, `tcp`, `rtu_over_tcp`, `simulated`",
                );
                None
            }
        };
        let mut format = LineFormat::new(115_200);
        let mut format_span = None;
        let mut format_ok = true;
        if let Some((_, v)) = get("baud") {
            format_span = format_span.or(Some(v.span));
            match self.number::<u32>(v, "`baud`", (50, 4_000_000)) {
                Some(baud) => format.baud = baud,
                None => format_ok = false,
            }
        }
        if let Some((_, v)) = get("parity") {
            format_span = format_span.or(Some(v.span));
            match self
                .text(v, "`parity`")
                .map(str::to_ascii_lowercase)
                .as_deref()
            {
                Some("none" | "n") => format.parity = Parity::None,
                Some("odd" | "o") => format.parity = Parity::Odd,
                Some("even" | "e") => format.parity = Parity::Even,
                Some(other) => {
                    self.error(
                        v.span,
                        format!("`parity` must be none, odd or even, not `{other}`"),
                        HELP,
                    );
                    format_ok = false;
                }
                None => format_ok = false,
            }
        }
        if let Some((_, v)) = get("data_bits") {
            format_span = format_span.or(Some(v.span));
            match self.number::<u8>(v, "`data_bits`", (5, 8)) {
                Some(bits) => format.data_bits = bits,
                None => format_ok = false,
            }
        }
        if let Some((_, v)) = get("stop_bits") {
            format_span = format_span.or(Some(v.span));
            match self.number::<u8>(v, "`stop_bits`", (1, 2)) {
                Some(bits) => format.stop_bits = bits,
                None => format_ok = false,
            }
        }
        let any_format = match get("any_format") {
            Some((_, v)) => self.boolean(v, "`any_format`"),
            None => Some(false),
        };
        let broadcast_turnaround = match get("broadcast_turnaround") {
            Some((_, v)) => self.duration(v, "`broadcast_turnaround`", Duration::ZERO),
            None => Some(DEFAULT_BROADCAST_TURNAROUND),
        };
        let gateway = match get("gateway") {
            Some((_, v)) => self.gateway(v).map(Some),
            None => Some(None),
        };
        let name_span = name_node.map_or(node.span, |n| n.span);
        let format_given = format_span.is_some();
        let seen = LineSeen {
            name: name.clone(),
            name_span,
            port: port.as_ref().map(|(port, _)| port.clone()),
            port_span: port.as_ref().map_or(name_span, |(_, span)| *span),
            format: format_span.unwrap_or(name_span),
            any_format: any_format.unwrap_or(true),
            format_given,
            gateway: gateway
                .as_ref()
                .and_then(|g| g.as_ref().map(|(g, span, _)| (g.listen, *span))),
            measurements_unit: gateway.as_ref().and_then(|g| {
                g.as_ref()
                    .map(|(g, _, unit_span)| (g.measurements_unit, *unit_span))
            }),
        };
        let line = (|| {
            let (name, (port, port_span)) = (name?, port?);
            let gateway = gateway?;
            if let (Port::Tcp(_), Some((_, span, _))) = (&port, &gateway) {
                self.error(
                    *span,
                    format!("line `{name}` is Modbus TCP already: a gateway serves RTU lines"),
                    "other masters can reach a Modbus TCP device directly",
                );
                return None;
            }
            if matches!(port, Port::Tcp(_)) && format_given {
                self.error(
                    format_span.unwrap_or(port_span),
                    format!("line `{name}` is Modbus TCP: it has no serial format"),
                    "for a serial-to-Ethernet converter that passes RTU frames, use `rtu_over_tcp`",
                );
                return None;
            }
            if !format_ok {
                return None;
            }
            any_format?;
            Some(LineConfig {
                name,
                format: port.is_rtu().then_some(format),
                port,
                broadcast_turnaround: broadcast_turnaround?,
                gateway: gateway.map(|(g, ..)| g),
            })
        })();
        Some((line, seen))
    }

    /// `gateway: ADDRESS` or
    /// `gateway: { listen: ADDRESS, clients: N, queue: N, idle: DURATION, writes: BOOL,
    /// measurements_unit: N }`; with where `listen` and `measurements_unit` are written (the
    /// gateway's place for the default unit).
    fn gateway(&mut self, node: &Node) -> Option<(GatewayConfig, Span, Span)> {
        let (listen_node, pairs) = match &node.value {
            Value::Mapping(_) => {
                let pairs = self.mapping(node, "`gateway`", GATEWAY_KEYS)?;
                let listen = pairs
                    .iter()
                    .find(|(k, _)| k.scalar() == Some("listen"))
                    .map(|(_, v)| v);
                let Some(listen) = listen else {
                    self.error(
                        node.span,
                        "`gateway` needs `listen`",
                        "e.g. `listen: 127.0.0.1:5020`",
                    );
                    return None;
                };
                (listen, pairs)
            }
            _ => (node, &[][..]),
        };
        let text = self.text(listen_node, "`gateway`")?;
        let Some(listen) = listen_address(text) else {
            self.error(
                listen_node.span,
                format!("`{text}` is no address to listen on"),
                "give a port (listens on 127.0.0.1) or IP:PORT, e.g. 127.0.0.1:5020",
            );
            return None;
        };
        let get = |key: &str| {
            pairs
                .iter()
                .find(|(k, _)| k.scalar() == Some(key))
                .map(|(_, v)| v)
        };
        let clients = match get("clients") {
            Some(v) => self.number::<usize>(v, "`clients`", (1, 1024)),
            None => Some(DEFAULT_GATEWAY_CLIENTS),
        };
        let queue = match get("queue") {
            Some(v) => self.number::<usize>(v, "`queue`", (1, 1024)),
            None => clients,
        };
        let idle = match get("idle") {
            Some(v) => self.duration(v, "`idle`", Duration::from_nanos(1)),
            None => Some(DEFAULT_GATEWAY_IDLE),
        };
        let writes = match get("writes") {
            Some(v) => self.boolean(v, "`writes`"),
            None => Some(false),
        };
        // Unit 0 broadcasts: no client could read it.
        let (measurements_unit, unit_span) = match get("measurements_unit") {
            Some(v) => (
                self.number::<u8>(v, "`measurements_unit`", (1, 255)),
                v.span,
            ),
            None => (Some(DEFAULT_MEASUREMENTS_UNIT), node.span),
        };
        Some((
            GatewayConfig {
                listen,
                clients: clients?,
                queue: queue?,
                idle: idle?,
                writes: writes?,
                measurements_unit: measurements_unit?,
            },
            listen_node.span,
            unit_span,
        ))
    }

    fn port(&mut self, key: &Node, value: &Node) -> Option<(Port, Span)> {
        let kind = key.scalar()?;
        let port = match kind {
            "simulated" => {
                if !self.boolean(value, "`simulated`")? {
                    self.error(
                        value.span,
                        "`simulated: false` names no port",
                        "give `serial`, `tcp` or `rtu_over_tcp` instead",
                    );
                    return None;
                }
                Port::Simulated
            }
            _ => {
                let address = self.text(value, &format!("`{kind}`"))?.trim().to_owned();
                if address.is_empty() {
                    self.error(value.span, format!("`{kind}` is empty"), HELP);
                    return None;
                }
                match kind {
                    "serial" => Port::Serial(address),
                    other => {
                        if !has_port(&address) {
                            self.error(
                                value.span,
                                format!("`{other}` needs host:port, not `{address}`"),
                                "e.g. 192.168.0.10:502",
                            );
                            return None;
                        }
                        if other == "tcp" {
                            Port::Tcp(address)
                        } else {
                            Port::RtuOverTcp(address)
                        }
                    }
                }
            }
        };
        Some((port, value.span))
    }
}
