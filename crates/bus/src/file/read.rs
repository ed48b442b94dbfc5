//! Reading a bus file's tree into its structs, every reading error collected with its place.

use std::time::Duration;

use optobus_codec::{LineFormat, Parity};
use optobus_codegen::source::{Node, Span, Value};
use optobus_device::{DeviceInfo, RegisterInfo};

use super::outputs::Outputs;
use super::reader::{has_port, listen_address, quoted, scalar, Reader, HELP};
use super::{
    BusFile, DeviceConfig, GatewayConfig, LineConfig, PollConfig, Port, Writable,
    DEFAULT_GATEWAY_CLIENTS, DEFAULT_GATEWAY_IDLE,
};

/// The Modbus serial-line specification's turnaround delay after a broadcast.
pub(crate) const DEFAULT_BROADCAST_TURNAROUND: Duration = Duration::from_millis(100);

const LINE_KEYS: &[&str] = &[
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
const GATEWAY_KEYS: &[&str] = &["listen", "clients", "queue", "idle", "writes"];
const PORT_KEYS: &[&str] = &["serial", "tcp", "rtu_over_tcp", "simulated"];
const DEVICE_KEYS: &[&str] = &[
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
const POLL_KEYS: &[&str] = &["read", "every", "priority"];
const TOP_KEYS: &[&str] = &["lines", "devices", "outputs"];

/// A bus file read, with the places the cross-checks point at.
pub(super) struct Parsed {
    pub(super) file: BusFile,
    pub(super) places: Places,
}

/// Where things were written, by index of line and device.
#[derive(Default)]
pub(super) struct Places {
    pub(super) lines: Vec<LinePlaces>,
    pub(super) devices: Vec<DevicePlaces>,
}

pub(super) struct LinePlaces {
    pub(super) name: Span,
    pub(super) port: Span,
    /// The format keys given (baud first), or the line's name when none is.
    pub(super) format: Span,
    /// The line allows formats its devices' manuals do not list.
    pub(super) any_format: bool,
    /// The file gave a format (else the devices' factory format is taken).
    pub(super) format_given: bool,
    /// Where the gateway's address is written.
    pub(super) gateway: Option<Span>,
}

pub(super) struct DevicePlaces {
    pub(super) name: Span,
    pub(super) slave: Span,
    pub(super) faults: Option<Span>,
}

impl Reader<'_> {
    /// The whole file.
    pub(super) fn bus(&mut self, root: &Node) -> Option<Parsed> {
        let top = self.mapping(root, "the bus file", TOP_KEYS)?;
        let mut lines = Vec::new();
        let mut line_places = Vec::new();
        let mut devices = Vec::new();
        let mut device_places = Vec::new();
        let lines_node = top.iter().find(|(k, _)| scalar(k) == Some("lines"));
        match lines_node {
            Some((_, node)) => {
                for item in self.list(node, "`lines`").unwrap_or_default() {
                    if let Some((line, places)) = self.line(item) {
                        lines.push(line);
                        line_places.push(places);
                    }
                }
            }
            None => self.error(root.span, "the bus file has no `lines`", HELP),
        }
        let devices_node = top.iter().find(|(k, _)| scalar(k) == Some("devices"));
        match devices_node {
            Some((_, node)) => {
                for item in self.list(node, "`devices`").unwrap_or_default() {
                    if let Some((device, places)) = self.device(item, &lines) {
                        devices.push(device);
                        device_places.push(places);
                    }
                }
            }
            None => self.error(root.span, "the bus file has no `devices`", HELP),
        }
        let outputs = match top.iter().find(|(k, _)| scalar(k) == Some("outputs")) {
            Some((_, outputs)) if !outputs.is_null() => {
                let names: Vec<(&str, Span)> = devices
                    .iter()
                    .zip(&device_places)
                    .map(|(device, places): (&DeviceConfig, &DevicePlaces)| {
                        (device.name.as_str(), places.name)
                    })
                    .collect();
                self.outputs(outputs, &names)
            }
            _ => Outputs::default(),
        };
        Some(Parsed {
            file: BusFile {
                lines,
                devices,
                outputs,
            },
            places: Places {
                lines: line_places,
                devices: device_places,
            },
        })
    }

    fn line(&mut self, node: &Node) -> Option<(LineConfig, LinePlaces)> {
        let pairs = self.mapping(node, "a line", LINE_KEYS)?;
        let get = |key: &str| pairs.iter().find(|(k, _)| scalar(k) == Some(key));
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
            .filter(|(k, _)| scalar(k).is_some_and(|k| PORT_KEYS.contains(&k)))
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
            Some((_, v)) => self.boolean(v, "`any_format`")?,
            None => false,
        };
        let broadcast_turnaround = match get("broadcast_turnaround") {
            Some((_, v)) => self.duration(v, "`broadcast_turnaround`", Duration::ZERO)?,
            None => DEFAULT_BROADCAST_TURNAROUND,
        };
        let gateway = match get("gateway") {
            Some((_, v)) => Some(self.gateway(v)?),
            None => None,
        };
        let (name, (port, port_span)) = (name?, port?);
        if let (Port::Tcp(_), Some((_, span))) = (&port, &gateway) {
            self.error(
                *span,
                format!("line `{name}` is Modbus TCP already: a gateway serves RTU lines"),
                "other masters can reach a Modbus TCP device directly",
            );
            return None;
        }
        if !format_ok {
            return None;
        }
        let format_given = format_span.is_some();
        if matches!(port, Port::Tcp(_)) && format_given {
            self.error(
                format_span.unwrap_or(port_span),
                format!("line `{name}` is Modbus TCP: it has no serial format"),
                "for a serial-to-Ethernet converter that passes RTU frames, use `rtu_over_tcp`",
            );
            return None;
        }
        let name_span = name_node.map_or(node.span, |n| n.span);
        Some((
            LineConfig {
                name,
                format: port.is_rtu().then_some(format),
                port,
                broadcast_turnaround,
                gateway: gateway.as_ref().map(|(g, _)| g.clone()),
            },
            LinePlaces {
                name: name_span,
                port: port_span,
                format: format_span.unwrap_or(name_span),
                any_format,
                format_given,
                gateway: gateway.map(|(_, span)| span),
            },
        ))
    }

    /// `gateway: ADDRESS` or
    /// `gateway: { listen: ADDRESS, clients: N, queue: N, idle: DURATION, writes: BOOL }`.
    fn gateway(&mut self, node: &Node) -> Option<(GatewayConfig, Span)> {
        let (listen_node, pairs) = match &node.value {
            Value::Mapping(_) => {
                let pairs = self.mapping(node, "`gateway`", GATEWAY_KEYS)?;
                let listen = pairs
                    .iter()
                    .find(|(k, _)| scalar(k) == Some("listen"))
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
                .find(|(k, _)| scalar(k) == Some(key))
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
        Some((
            GatewayConfig {
                listen,
                clients: clients?,
                queue: queue?,
                idle: idle?,
                writes: writes?,
            },
            listen_node.span,
        ))
    }

    fn port(&mut self, key: &Node, value: &Node) -> Option<(Port, Span)> {
        let kind = scalar(key)?;
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

    fn device(
        &mut self,
        node: &Node,
        lines: &[LineConfig],
    ) -> Option<(DeviceConfig, DevicePlaces)> {
        let pairs = self.mapping(node, "a device", DEVICE_KEYS)?;
        let get = |key: &str| {
            pairs
                .iter()
                .find(|(k, _)| scalar(k) == Some(key))
                .map(|(_, v)| v)
        };
        let name_node = get("name");
        let name = match name_node {
            Some(v) => self.text(v, "a device's `name`").map(str::to_owned),
            None => {
                self.error(node.span, "a device needs a `name`", "samples carry it");
                None
            }
        };
        let span = name_node.map_or(node.span, |n| n.span);
        let model = match (get("model"), get("spec")) {
            (Some(model), None) => self.model(model),
            (None, Some(spec)) => self.spec(spec),
            (Some(_), Some(spec)) => {
                self.error(
                    spec.span,
                    "a device has a `model` or a `spec`, not both",
                    HELP,
                );
                None
            }
            (None, None) => {
                self.error(
                    span,
                    "a device needs a `model` (a built-in one) or a `spec` (a spec file)",
                    format!("built-in models: {}", self.catalogue.names().join(", ")),
                );
                None
            }
        };
        let line = match get("line") {
            Some(v) => self.line_ref(v, lines),
            None if lines.len() == 1 => Some(0),
            None => {
                self.error(
                    span,
                    "a device needs a `line` when the file has several",
                    HELP,
                );
                None
            }
        };
        let slave_node = get("slave");
        let slave = match slave_node {
            Some(v) => self.number::<u8>(v, "`slave`", (1, 247)),
            None => model.as_ref().map(|(device, _)| device.default_slave),
        };
        let timeout = match get("timeout") {
            Some(v) => self.duration(v, "`timeout`", Duration::from_millis(1)),
            None => Some(optobus_transport::DEFAULT_TIMEOUT),
        };
        let retries = match get("retries") {
            Some(v) => self.number::<u8>(v, "`retries`", (0, 10)),
            None => Some(0),
        };
        let mut wait = |key: &str| match get(key) {
            Some(v) => self.duration(v, &format!("`{key}`"), Duration::ZERO),
            None => Some(Duration::ZERO),
        };
        let silence_before = wait("silence_before");
        let silence_after = wait("silence_after");
        let power_up = wait("power_up");
        let polls = match (get("poll"), model.as_ref()) {
            (Some(v), Some((device, _))) => self.polls(v, device),
            (Some(v), None) => {
                // Read what can be read without the model, so the shape is still checked.
                self.list(v, "`poll`");
                None
            }
            (None, _) => Some(Vec::new()),
        };
        let faults = match get("faults") {
            Some(v) => {
                let text = self.text(v, "`faults`")?;
                match text.parse::<optobus_simulator::Faults>() {
                    Ok(faults) => Some(faults),
                    Err(why) => {
                        self.error(
                            v.span,
                            format!("`faults` {why}"),
                            "e.g. `drop=0.1,corrupt=0.05,seed=7`",
                        );
                        return None;
                    }
                }
            }
            None => None,
        };
        let faults_span = get("faults").map(|v| v.span);
        let writable = match (get("writable"), model.as_ref()) {
            (Some(v), Some((device, _))) => self.writable(v, device),
            (Some(_), None) | (None, _) => Some(Writable::default()),
        };
        let (device, model) = model?;
        Some((
            DeviceConfig {
                name: name?,
                device,
                model,
                line: line?,
                slave: slave?,
                // A value that did not read is reported already (the file is refused); the
                // device still takes part in the checks across devices.
                timeout: timeout.unwrap_or(optobus_transport::DEFAULT_TIMEOUT),
                retries: retries.unwrap_or(0),
                silence_before: silence_before.unwrap_or_default(),
                silence_after: silence_after.unwrap_or_default(),
                power_up: power_up.unwrap_or_default(),
                polls: polls.unwrap_or_default(),
                faults,
                writable: writable.unwrap_or_default(),
            },
            DevicePlaces {
                name: span,
                slave: slave_node.map_or(span, |n| n.span),
                faults: faults_span,
            },
        ))
    }

    fn model(&mut self, node: &Node) -> Option<(&'static DeviceInfo, String)> {
        let name = self.text(node, "`model`")?;
        match self.catalogue.find(name) {
            Some(device) => Some((device, name.to_owned())),
            None => {
                self.error(
                    node.span,
                    format!("there is no built-in model `{name}`"),
                    format!(
                        "built-in models: {}; or give a spec file with `spec:`",
                        self.catalogue.names().join(", ")
                    ),
                );
                None
            }
        }
    }

    fn spec(&mut self, node: &Node) -> Option<(&'static DeviceInfo, String)> {
        let path = self.text(node, "`spec`")?;
        match self.catalogue.load(&self.base.join(path)) {
            Ok(device) => Some((device, path.to_owned())),
            Err(why) => {
                self.error(node.span, format!("spec `{path}` cannot be used"), why);
                None
            }
        }
    }

    fn line_ref(&mut self, node: &Node, lines: &[LineConfig]) -> Option<usize> {
        let name = self.text(node, "`line`")?;
        let found = lines.iter().position(|line| line.name == name);
        if found.is_none() {
            let known: Vec<&str> = lines.iter().map(|l| l.name.as_str()).collect();
            self.error(
                node.span,
                format!("there is no line `{name}`"),
                format!("lines: {}", quoted(&known)),
            );
        }
        found
    }

    fn polls(&mut self, node: &Node, device: &'static DeviceInfo) -> Option<Vec<PollConfig>> {
        let items = self.list(node, "`poll`")?;
        let mut polls = Vec::new();
        let mut ok = true;
        for item in items {
            match self.poll(item, device) {
                Some(poll) => polls.push(poll),
                None => ok = false,
            }
        }
        ok.then_some(polls)
    }

    fn poll(&mut self, node: &Node, device: &'static DeviceInfo) -> Option<PollConfig> {
        let pairs = self.mapping(node, "a poll", POLL_KEYS)?;
        let get = |key: &str| {
            pairs
                .iter()
                .find(|(k, _)| scalar(k) == Some(key))
                .map(|(_, v)| v)
        };
        let names: Vec<&Node> = match get("read") {
            Some(v) => match &v.value {
                Value::Sequence(items) => items.iter().collect(),
                _ => vec![v],
            },
            None => {
                self.error(node.span, "a poll needs `read`: groups or registers", HELP);
                return None;
            }
        };
        let mut registers: Vec<&'static RegisterInfo> = Vec::new();
        let mut written = Vec::new();
        let mut ok = !names.is_empty();
        for name_node in names {
            let Some(name) = self.text(name_node, "a name to read") else {
                ok = false;
                continue;
            };
            match resolve(device, name) {
                Ok(found) => {
                    registers.extend(found);
                    written.push(name.to_owned());
                }
                Err(why) => {
                    self.error(
                        name_node.span,
                        why,
                        format!("`optobus registers {}` lists them", device.model_name()),
                    );
                    ok = false;
                }
            }
        }
        let every = match get("every") {
            Some(v) if scalar(v) == Some("fastest") => Some(None),
            Some(v) => self
                .duration(v, "`every`", Duration::from_nanos(1))
                .map(Some),
            None => Some(None),
        };
        let priority = match get("priority") {
            Some(v) => self.number::<u8>(v, "`priority`", (0, 255)),
            None => Some(0),
        };
        registers.sort_by_key(|r| (r.table, r.address));
        registers.dedup_by_key(|r| (r.table, r.address, r.name));
        if !ok {
            return None;
        }
        Some(PollConfig {
            names: written,
            registers,
            every: every?,
            priority: priority?,
        })
    }

    /// `writable: all`, or a list of register, group and command names.
    fn writable(&mut self, node: &Node, device: &'static DeviceInfo) -> Option<Writable> {
        if scalar(node) == Some("all") {
            return Some(Writable::all(device));
        }
        let items = self.list(node, "`writable`")?;
        let mut listed = Writable::default();
        let mut ok = true;
        for item in items {
            let Some(name) = self.text(item, "a name to write") else {
                ok = false;
                continue;
            };
            match writable(device, name) {
                Ok(found) => listed.add(found),
                Err(why) => {
                    self.error(
                        item.span,
                        why,
                        format!(
                            "`optobus registers {}` lists registers and commands; `all` allows \
                             every register and every command that does not store, restart or \
                             reset",
                            device.model_name()
                        ),
                    );
                    ok = false;
                }
            }
        }
        ok.then_some(listed)
    }
}

/// What one name under `writable` allows: a command, or the writable registers a register or
/// group name stands for; or why it cannot be written from the network.
pub fn writable(device: &'static DeviceInfo, name: &str) -> Result<Writable, String> {
    let model = device.model_name().to_string();
    if let Some(command) = device.command(name) {
        return Ok(Writable {
            registers: Vec::new(),
            commands: vec![command],
        });
    }
    let registers: Vec<&'static RegisterInfo> = match device.group(name) {
        Some(group) => group
            .registers
            .iter()
            .flat_map(|member| device.members(member))
            .filter(|r| r.access.writable())
            .collect(),
        None => device.members(name).collect(),
    };
    if registers.is_empty() {
        return Err(match device.group(name) {
            Some(_) => format!("group `{name}` of {model} has no register that can be written"),
            None => format!("{model} has no register, group or command `{name}`"),
        });
    }
    if let Some(register) = registers.iter().find(|r| !r.access.writable()) {
        return Err(format!("`{}` of {model} cannot be written", register.name));
    }
    let own_address = device.slave_address_register().map(|r| r.name);
    if let Some(register) = registers.iter().find(|r| Some(r.name) == own_address) {
        return Err(format!(
            "`{}` cannot be writable on a bus: the bus addresses the device by it",
            register.name
        ));
    }
    Ok(Writable {
        registers,
        commands: Vec::new(),
    })
}

impl Writable {
    /// Every writable register and every command that does not store, restart or reset, except
    /// the slave address.
    fn all(device: &'static DeviceInfo) -> Self {
        let own_address = device.slave_address_register().map(|r| r.name);
        Self {
            registers: device
                .registers
                .iter()
                .filter(|r| r.access.writable() && Some(r.name) != own_address)
                .filter(|r| device.drastic_commands_on(r).next().is_none())
                .collect(),
            commands: device
                .commands
                .iter()
                .filter(|c| !c.effect.is_drastic())
                .collect(),
        }
    }

    /// Adds what `more` allows.
    fn add(&mut self, more: Self) {
        for register in more.registers {
            if !self.allows_register(register) {
                self.registers.push(register);
            }
        }
        for command in more.commands {
            if !self.allows_command(command) {
                self.commands.push(command);
            }
        }
        self.registers.sort_by_key(|r| (r.table, r.address));
    }
}

/// The registers a group or register name stands for, or why it cannot be polled.
pub fn resolve(
    device: &'static DeviceInfo,
    name: &str,
) -> Result<Vec<&'static RegisterInfo>, String> {
    let model = device.model_name().to_string();
    let registers: Vec<&'static RegisterInfo> = match device.groups.iter().find(|g| g.name == name)
    {
        Some(group) => group
            .registers
            .iter()
            .flat_map(|member| device.members(member))
            .collect(),
        None => device.members(name).collect(),
    };
    if registers.is_empty() {
        return Err(format!("{model} has no register or group `{name}`"));
    }
    if let Some(register) = registers.iter().find(|r| !r.readable()) {
        return Err(format!("`{}` of {model} cannot be read", register.name));
    }
    if let Some(register) = registers.iter().find(|r| !r.read_is_repeatable()) {
        return Err(format!(
            "reading `{}` of {model} changes the device, so it is not polled",
            register.name
        ));
    }
    Ok(registers)
}
