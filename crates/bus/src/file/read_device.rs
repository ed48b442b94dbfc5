//! Reading a bus file's devices: each device's model or spec, line, slave, faults, polls and
//! what the network may write; the lines are read in `read.rs`.

use std::time::Duration;

use optobus_device::{DeviceInfo, RegisterInfo};
use optobus_inspect::did_you_mean;
use optobus_spec::source::{Node, Value};

use super::read::{DeviceSeen, LineSeen, DEVICE_KEYS, POLL_KEYS};
use super::reading::{parse_duration, quoted, spec_refusal, FileReader, HELP, NOT_A_DURATION};
use super::{DeviceConfig, PollConfig, Writable};

impl FileReader<'_> {
    pub(super) fn device(
        &mut self,
        node: &Node,
        lines: &[LineSeen],
    ) -> Option<(Option<DeviceConfig>, DeviceSeen)> {
        let pairs = self.mapping(node, "a device", DEVICE_KEYS)?;
        let get = |key: &str| {
            pairs
                .iter()
                .find(|(k, _)| k.scalar() == Some(key))
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
                let models = format!("built-in models: {}", self.catalogue.names().join(", "));
                self.error(
                    span,
                    "a device needs a `model` (a built-in one) or a `spec` (a spec file)",
                    models,
                );
                None
            }
        };
        let device = model.as_ref().map(|(device, _)| *device);
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
            None => device.map(|device| device.default_slave),
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
        // Without the model the registers cannot be named, but the rest of each poll is read.
        let polls = match get("poll") {
            Some(v) => self.polls(v, device),
            None => Some(Vec::new()),
        };
        let faults = match get("faults") {
            Some(v) => self.faults(v).map(Some),
            None => Some(None),
        };
        let writable = match (get("writable"), device) {
            (Some(v), Some(device)) => self.writable(v, device),
            (Some(_), None) | (None, _) => Some(Writable::default()),
        };
        let seen = DeviceSeen {
            name: name.clone(),
            name_span: span,
            line,
            slave,
            slave_span: slave_node.map_or(span, |n| n.span),
            model: device,
            faults: get("faults").map(|v| v.span),
        };
        let config = (|| {
            let (device, model) = model?;
            Some(DeviceConfig {
                name: name?,
                device,
                model,
                line: line?,
                slave: slave?,
                timeout: timeout?,
                retries: retries?,
                silence_before: silence_before?,
                silence_after: silence_after?,
                power_up: power_up?,
                polls: polls?,
                faults: faults?,
                writable: writable?,
            })
        })();
        Some((config, seen))
    }

    /// `faults: drop=0.1,seed=7`: the simulator's faults in a simulated device's replies.
    fn faults(&mut self, node: &Node) -> Option<optobus_simulator::Faults> {
        let text = self.text(node, "`faults`")?;
        match text.parse::<optobus_simulator::Faults>() {
            Ok(faults) => Some(faults),
            Err(why) => {
                self.error(
                    node.span,
                    format!("`faults` {why}"),
                    "e.g. `drop=0.1,corrupt=0.05,seed=7`",
                );
                None
            }
        }
    }

    fn model(&mut self, node: &Node) -> Option<(&'static DeviceInfo, String)> {
        let name = self.text(node, "`model`")?;
        match self.catalogue.find(name) {
            Some(device) => Some((device, name.to_owned())),
            None => {
                let names = self.catalogue.names();
                let models = format!(
                    "built-in models: {}; or give a spec file with `spec:`",
                    names.join(", ")
                );
                let help = match did_you_mean(name, names.iter().map(String::as_str)) {
                    Some(near) => format!("{near} {models}"),
                    None => models,
                };
                self.error(
                    node.span,
                    format!("there is no built-in model `{name}`"),
                    help,
                );
                None
            }
        }
    }

    fn spec(&mut self, node: &Node) -> Option<(&'static DeviceInfo, String)> {
        let path = self.text(node, "`spec`")?;
        match self.catalogue.load(&self.base.join(path)) {
            Ok(device) => Some((device, path.to_owned())),
            Err(error) => {
                let why = spec_refusal(&error);
                self.error(node.span, format!("spec `{path}` cannot be used"), why);
                None
            }
        }
    }

    fn line_ref(&mut self, node: &Node, lines: &[LineSeen]) -> Option<usize> {
        let name = self.text(node, "`line`")?;
        let found = lines
            .iter()
            .position(|line| line.name.as_deref() == Some(name));
        if found.is_none() {
            let known: Vec<&str> = lines.iter().filter_map(|l| l.name.as_deref()).collect();
            let lines = format!("lines: {}", quoted(&known));
            let help = match did_you_mean(name, known.iter().copied()) {
                Some(near) => format!("{near} {lines}"),
                None => lines,
            };
            self.error(node.span, format!("there is no line `{name}`"), help);
        }
        found
    }

    /// A device's `poll` list; without the device's model (already reported) every poll is
    /// still read but for the names of what it reads.
    fn polls(
        &mut self,
        node: &Node,
        device: Option<&'static DeviceInfo>,
    ) -> Option<Vec<PollConfig>> {
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

    fn poll(&mut self, node: &Node, device: Option<&'static DeviceInfo>) -> Option<PollConfig> {
        let pairs = self.mapping(node, "a poll", POLL_KEYS)?;
        let get = |key: &str| {
            pairs
                .iter()
                .find(|(k, _)| k.scalar() == Some(key))
                .map(|(_, v)| v)
        };
        let names: Vec<&Node> = match get("read") {
            Some(v) => match &v.value {
                Value::Sequence(items) => items.iter().collect(),
                _ => vec![v],
            },
            None => {
                self.error(node.span, "a poll needs `read`: groups or registers", HELP);
                Vec::new()
            }
        };
        let mut registers: Vec<&'static RegisterInfo> = Vec::new();
        let mut written = Vec::new();
        let mut ok = !names.is_empty() && device.is_some();
        for name_node in names {
            let Some(name) = self.text(name_node, "a name to read") else {
                ok = false;
                continue;
            };
            let Some(device) = device else { continue };
            match resolve(device, name) {
                Ok(found) => {
                    registers.extend(found);
                    written.push(name.to_owned());
                }
                Err(why) => {
                    let known = device
                        .registers
                        .iter()
                        .map(|r| r.member_name().unwrap_or(r.name))
                        .chain(device.groups.iter().map(|g| g.name));
                    let list = format!("`optobus registers {}` lists them", device.model_name());
                    let help = match did_you_mean(name, known) {
                        Some(near) => format!("{near} {list}"),
                        None => list,
                    };
                    self.error(name_node.span, why, help);
                    ok = false;
                }
            }
        }
        let every = match get("every") {
            Some(v) if v.scalar() == Some("fastest") => Some(None),
            Some(v) => self.every(v).map(Some),
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

    /// A poll's period: a duration, or (said in the error) `fastest`.
    fn every(&mut self, node: &Node) -> Option<Duration> {
        let text = self.text(node, "`every`")?;
        match parse_duration(text) {
            Ok(_) => self.duration(node, "`every`", Duration::from_nanos(1)),
            Err(why) => {
                let help = "a period like 100ms, 1.5s or 2m, or `fastest`: as fast as the line \
                            allows (the default)";
                let help = match did_you_mean(text, ["fastest"]) {
                    Some(near) => format!("{near} {help}"),
                    None => help.to_owned(),
                };
                let why = match why {
                    NOT_A_DURATION => "is neither a duration nor `fastest`",
                    other => other,
                };
                self.error(node.span, format!("`every` `{text}` {why}"), help);
                None
            }
        }
    }

    /// `writable: all`, or a list of register, group and command names.
    fn writable(&mut self, node: &Node, device: &'static DeviceInfo) -> Option<Writable> {
        if node.scalar() == Some("all") {
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
                    let list = format!(
                        "`optobus registers {}` lists registers and commands; `all` allows every \
                         register and every command that does not store, restart or reset",
                        device.model_name()
                    );
                    let known = device
                        .registers
                        .iter()
                        .filter(|r| r.access.writable())
                        .map(|r| r.member_name().unwrap_or(r.name))
                        .chain(device.groups.iter().map(|g| g.name))
                        .chain(device.commands.iter().map(|c| c.name));
                    let help = match did_you_mean(name, known) {
                        Some(near) => format!("{near} {list}"),
                        None => list,
                    };
                    self.error(item.span, why, help);
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
