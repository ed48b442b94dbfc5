//! `optobus run BUS.yaml`: a bus of sensors polled on schedule, shown live (a block per
//! device), as JSON lines (`--json`), and recorded to a CSV per device (`--record DIR`).
//! `--demo` runs a built-in bus of simulated sensors with a gateway for other tools.

use std::collections::BTreeMap;
use std::io::{IsTerminal, Write};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use clap::Args;
use optobus_bus::{BusFile, Event, Follower, GatewayMoveError, Health, MeasurementEvent, Sample};
use optobus_device::RegisterInfo;
use optobus_inspect::Value;
use optobus_service::outlet::{Outlet, Sink};
use optobus_service::recording::local_time;
use optobus_service::{
    HttpConfig, MetricsConfig, MqttConfig, Options, OutputsConfig, Service, ServiceFile,
    DRAIN_AT_END,
};

use crate::error::CliError;
use crate::inputs;
use crate::log::note;
use crate::models;
use crate::render::{counted, redraw, screen, time_of_day, values_text};

/// How often the terminal view is redrawn.
const REDRAW_EVERY: Duration = Duration::from_millis(250);

/// Lines stdout may fall behind by (seconds of a busy bus) before its oldest are dropped.
const STDOUT_LINES: usize = 4096;

#[derive(Debug, Args)]
pub(crate) struct RunArgs {
    /// The bus file (YAML): `optobus bus schema` prints every key it takes, `optobus bus check
    /// FILE` checks one without opening anything.
    #[arg(conflicts_with = "demo")]
    file: Option<PathBuf>,
    /// Run the built-in demo bus: a simulated sensor of every model on one line, with a Modbus
    /// TCP gateway on 127.0.0.1:5020.
    #[arg(long)]
    demo: bool,
    /// Where the gateway listens: the demo's (instead of 127.0.0.1:5020), or the bus file's
    /// (its one line with a `gateway`, or else its one RTU line, read-only).
    #[arg(long, value_name = "ADDRESS")]
    gateway: Option<SocketAddr>,
    /// Serve the console in the browser here (instead of the bus file's `outputs.http`
    /// address, keeping its token, origins and hosts).
    #[arg(long, value_name = "ADDRESS")]
    http: Option<SocketAddr>,
    /// Write a CSV per device into this folder (the `record` format; a row per poll).
    #[arg(long, value_name = "DIR")]
    record: Option<PathBuf>,
    /// Stop after this long (default: until Ctrl-C).
    #[arg(long, value_parser = inputs::RUN_FOR.parser())]
    duration: Option<Duration>,
    /// Publish to this MQTT broker (HOST or HOST:PORT), over the bus file's `mqtt` broker if it
    /// has one.
    #[arg(long, value_name = "HOST:PORT")]
    mqtt: Option<String>,
    /// Announce the devices to Home Assistant (MQTT discovery under `homeassistant`).
    #[arg(long)]
    homeassistant: bool,
    /// Serve Prometheus metrics on http://ADDRESS/metrics (a port alone is on 127.0.0.1).
    #[arg(long, value_name = "ADDRESS")]
    prometheus: Option<String>,
}

/// The outputs the command line adds to the bus file's, or overrides in it.
fn command_line_outputs(outputs: &mut OutputsConfig, args: &RunArgs) -> Result<(), CliError> {
    if let Some(broker) = &args.mqtt {
        let given =
            MqttConfig::for_broker(broker).map_err(|e| CliError::new(format!("--mqtt: {e}")))?;
        match outputs.mqtt.as_mut() {
            Some(mqtt) => (mqtt.host, mqtt.port) = (given.host, given.port),
            None => outputs.mqtt = Some(given),
        }
    }
    if args.homeassistant {
        let mqtt = outputs.mqtt.as_mut().ok_or_else(|| {
            CliError::new(
                "--homeassistant needs a broker: give --mqtt HOST:PORT or `mqtt` in the bus file",
            )
        })?;
        mqtt.homeassistant
            .get_or_insert_with(|| "homeassistant".to_owned());
    }
    if let Some(address) = args.http {
        match outputs.http.as_mut() {
            Some(http) => http.listen = address,
            None => outputs.http = Some(HttpConfig::new(address)),
        }
    }
    if let Some(address) = &args.prometheus {
        outputs.metrics = Some(
            MetricsConfig::for_address(address)
                .map_err(|e| CliError::new(format!("--prometheus: {e}")))?,
        );
    }
    Ok(())
}

/// `--gateway ADDRESS`: the bus file's one gateway listens there instead (or its one RTU
/// line gets a read-only one); which gateway is meant must be plain.
fn move_gateway(bus: &mut BusFile, address: SocketAddr) -> Result<(), CliError> {
    bus.move_gateway(address).map_err(|error| {
        let refused = CliError::new(format!("--gateway: {error}"));
        match error {
            GatewayMoveError::NoRtuLine => {
                refused.hint("other masters reach the devices of a Modbus TCP line directly")
            }
            GatewayMoveError::SeveralRtuLines { .. } => {
                refused.hint("give `gateway: ADDRESS` under that line in the bus file")
            }
            GatewayMoveError::SeveralGateways { .. } => {
                refused.hint("give each its address in the bus file")
            }
        }
    })
}

/// The latest values and health of each device as text blocks, and under them a line per
/// measurement, for the terminal (the console's `Board` keeps the same facts as JSON for the
/// browser, with errors and lines).
struct TerminalView {
    /// Per device, in file order.
    devices: Vec<DeviceBlock>,
    /// Per measurement, in the order the bus computes them: its latest value.
    measurements: Vec<(String, Option<Arc<MeasurementEvent>>)>,
}

/// One device's block: its header facts, health and latest values.
struct DeviceBlock {
    name: String,
    facts: String,
    health: Health,
    values: BTreeMap<(u8, u16, &'static str), (&'static RegisterInfo, Value)>,
}

impl TerminalView {
    fn new(bus: &BusFile) -> Self {
        let devices = bus
            .devices
            .iter()
            .map(|device| DeviceBlock {
                name: device.name.clone(),
                facts: format!(
                    "{} · line {} · slave {}",
                    device.device.model_name(),
                    bus.lines[device.line].name,
                    device.slave
                ),
                health: Health::Online,
                values: BTreeMap::new(),
            })
            .collect();
        let measurements = bus
            .measurements
            .plan
            .formulas
            .iter()
            .map(|formula| (formula.name.clone(), None))
            .collect();
        Self {
            devices,
            measurements,
        }
    }

    fn measurement(&mut self, event: &Arc<MeasurementEvent>) {
        let latest = self
            .measurements
            .iter_mut()
            .find(|(name, _)| *name == *event.measurement);
        if let Some((_, latest)) = latest {
            *latest = Some(Arc::clone(event));
        }
    }

    fn device(&mut self, name: &str) -> Option<&mut DeviceBlock> {
        self.devices.iter_mut().find(|d| d.name == name)
    }

    fn sample(&mut self, sample: &Sample) {
        if let Some(block) = self.device(&sample.source.device) {
            let key = (
                sample.register.table as u8,
                sample.register.address,
                sample.register.name,
            );
            block
                .values
                .insert(key, (sample.register, sample.value.clone()));
        }
    }

    fn health(&mut self, device: &str, health: Health) {
        if let Some(block) = self.device(device) {
            block.health = health;
        }
    }

    fn text(&self, header: &str) -> String {
        let mut text = format!("{}  {header}\n", time_of_day());
        for device in &self.devices {
            let health = match device.health {
                Health::Online => "online",
                Health::Offline => "OFFLINE",
            };
            text += &format!("\n{} · {} · {health}\n", device.name, device.facts);
            let values: Vec<(&'static RegisterInfo, Value)> =
                device.values.values().cloned().collect();
            text += &values_text(&values);
        }
        if !self.measurements.is_empty() {
            text += "\nmeasurements\n";
            let width = self.measurements.iter().map(|(n, _)| n.len()).max();
            for (name, latest) in &self.measurements {
                let line = match latest {
                    Some(event) => measurement_text(event),
                    None => "no value yet".to_owned(),
                };
                text += &format!("{name:<width$}  {line}\n", width = width.unwrap_or(0));
            }
        }
        text
    }
}

/// A judgement as the terminal marks it: its name and an arrow, readable without colour.
fn judgement_mark(name: &str) -> &'static str {
    match name {
        "ll" => "LL ▼▼",
        "lo" => "LO ▼",
        "go" => "GO ✓",
        "hi" => "HI ▲",
        "hh" => "HH ▲▲",
        _ => "?",
    }
}

/// A measurement's latest value on one line: value and unit (or `—` and why it has none), its
/// judgement, the skew between its inputs, and its statistics (n, mean, sd, Cpk where it has
/// limits), as the bus computed them; the statistics to one decimal more than the value.
fn measurement_text(event: &MeasurementEvent) -> String {
    let unit = if event.unit.is_empty() {
        String::new()
    } else {
        format!(" {}", event.unit)
    };
    let (mut text, places) = match &event.value {
        Ok(value) => {
            let shown = value.to_string();
            let places = shown.split_once('.').map_or(0, |(_, d)| d.len());
            (format!("{shown}{unit}"), places + 1)
        }
        Err(reason) => (format!("—  ({reason})"), 4),
    };
    if let Some(judgement) = event.judgement {
        text += &format!("  [{}]", judgement_mark(judgement.name()));
    }
    text += &format!("  skew {:.2} ms", event.skew.as_secs_f64() * 1000.0);
    if let Some(stats) = &event.stats {
        text += &format!("  n {}  mean {:.places$}{unit}", stats.count, stats.mean);
        if let Some(sd) = stats.sd {
            text += &format!("  sd {sd:.places$}{unit}");
        }
        if let Some(cpk) = stats.cpk {
            text += &format!("  Cpk {cpk:.2}");
        }
    }
    text
}

/// Stdout: a line per item, or on a terminal the newest view drawn over the last one.
enum Stdout {
    Lines,
    Screen { drawn: u16 },
}

impl Sink<String> for Stdout {
    fn write(&mut self, items: Vec<String>, _: u64) {
        let mut out = std::io::stdout().lock();
        match self {
            Self::Lines => {
                let mut text = String::with_capacity(items.iter().map(|i| i.len() + 1).sum());
                for line in items {
                    text += &line;
                    text.push('\n');
                }
                // A closed pipe (`| head`) is not an error worth a message.
                let _ = out.write_all(text.as_bytes());
            }
            Self::Screen { drawn } => {
                // Only the newest drawing matters.
                if let Some(view) = items.last() {
                    let size = screen(crossterm::terminal::size().ok());
                    *drawn = redraw(&mut out, *drawn, view, size);
                }
            }
        }
        let _ = out.flush();
    }
}

/// One JSON line for a sample: the bus's fields, its time with the local offset.
fn sample_json(sample: &Sample) -> String {
    let mut json = serde_json::to_value(sample).unwrap_or_default();
    if let Some(object) = json.as_object_mut() {
        object.insert("time".into(), local_time(sample.replied).into());
    }
    json.to_string()
}

pub(crate) async fn run(json: bool, args: &RunArgs) -> Result<(), CliError> {
    // The operator's news on stderr (a service, a pipe, --json); the live view in a terminal
    // shows the devices' health itself and would be torn by lines between its drawings.
    if !std::io::stdout().is_terminal() || json {
        crate::log::show_operations();
    }
    let mut file = match &args.file {
        Some(path) => {
            let mut file = crate::bus_file::load_with_outputs(path)?;
            if let Some(address) = args.gateway {
                move_gateway(&mut file.bus, address)?;
            }
            file
        }
        None if args.demo => {
            let mut bus = optobus_service::demo::bus(models::catalogue())
                .map_err(|rejected| CliError::new(rejected.render()))?;
            if let Some(address) = args.gateway {
                move_gateway(&mut bus, address)?;
            }
            ServiceFile::from(bus)
        }
        None => {
            let hint = "`optobus run --demo` runs a built-in bus of simulated sensors, one of \
                        every model; `optobus bus schema` prints what a bus file takes";
            return Err(CliError::usage(
                "`optobus run` needs a bus file: `optobus run plant.yaml`",
            )
            .hint(hint));
        }
    };
    command_line_outputs(&mut file.outputs, args)?;
    let mut view = TerminalView::new(&file.bus);
    let (lines, devices) = (file.bus.lines.len(), file.bus.devices.len());
    let options = Options {
        record: args.record.clone(),
    };
    let mut service = Service::start(file, options, Arc::new(|text: &str| note!("{text}")))
        .await
        .map_err(|e| CliError::failed(e.to_string()))?;
    let header = format!(
        "{}, {}{}",
        counted(lines, "line"),
        counted(devices, "device"),
        service
            .summary()
            .iter()
            .map(|part| format!(" · {part}"))
            .collect::<String>()
    );
    let events = service
        .events()
        .ok_or_else(|| CliError::failed("the run's events were taken"))?;
    let terminal = std::io::stdout().is_terminal() && !json;
    let stdout = if terminal {
        // The newest drawing only: one waiting drawing is replaced by the next.
        Outlet::start("optobus-stdout", 1, Stdout::Screen { drawn: 0 })
    } else {
        Outlet::start("optobus-stdout", STDOUT_LINES, Stdout::Lines)
    };
    let stop = inputs::until_stopped(args.duration);
    let mut redraw_at = tokio::time::Instant::now();
    let take = |event: Event| {
        match &event {
            Event::Sample(sample) => {
                let line = if json {
                    Some(sample_json(sample))
                } else if !terminal {
                    Some(format!(
                        "{}  {}  {}  {}",
                        time_of_day(),
                        sample.source.device,
                        sample.register.name,
                        sample.value
                    ))
                } else {
                    None
                };
                if let Some(line) = line {
                    if stdout.push(line).first_drop() {
                        note!("optobus: stdout is not being read: dropping its oldest lines");
                    }
                }
                view.sample(sample);
            }
            Event::Health(health) => view.health(&health.source.device, health.health),
            // Samples and measurements only on stdout: writes are in the audit trail (stderr).
            Event::Line(_) | Event::Written(_) => {}
            Event::Measurement(measurement) => {
                view.measurement(measurement);
                // A line per value, as JSON (its keys are the contract) or as text.
                let line = if json {
                    serde_json::to_string(&**measurement).ok()
                } else if !terminal {
                    let value = match &measurement.value {
                        Ok(value) => format!("{value} {}", measurement.unit),
                        Err(reason) => format!("invalid: {reason}"),
                    };
                    let judgement = measurement.judgement.map(|j| format!("  {j}"));
                    Some(format!(
                        "{}  {}  {value}{}",
                        time_of_day(),
                        measurement.measurement,
                        judgement.unwrap_or_default()
                    ))
                } else {
                    None
                };
                if let Some(line) = line {
                    if stdout.push(line).first_drop() {
                        note!("optobus: stdout is not being read: dropping its oldest lines");
                    }
                }
            }
        }
        if terminal && tokio::time::Instant::now() >= redraw_at {
            stdout.push(view.text(&header));
            redraw_at = tokio::time::Instant::now() + REDRAW_EVERY;
        }
    };
    let mut missed = 0;
    Follower::new(events, |count| missed += count)
        .until(stop, take)
        .await;
    // Stdout is waited for on a thread of the blocking pool while the service stops.
    let drained = tokio::task::spawn_blocking(move || {
        let unwritten = stdout.flush(DRAIN_AT_END);
        (unwritten, stdout.dropped())
    });
    let stopped = service.stop().await;
    let (unwritten, stdout_dropped) = drained
        .await
        .map_err(|e| CliError::failed(format!("the end of the run: {e}")))?;
    if !terminal {
        if stdout_dropped > 0 {
            note!(
                "optobus: stdout fell behind: {} dropped, the oldest first",
                counted(stdout_dropped, "line")
            );
        }
        if unwritten > 0 {
            note!(
                "optobus: stdout is not being read: {} not written (the last of the run)",
                counted(unwritten, "line")
            );
        }
    }
    if missed > 0 {
        note!(
            "optobus: the display fell behind and skipped {}",
            counted(missed, "event")
        );
    }
    stopped.map_err(|e| CliError::failed(e.to_string()))
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use optobus_bus::Bus;

    use super::*;

    const GAP: &str = "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: top, model: p-series, slave: 1, timeout: 50ms, poll: [{ read: distance_1, every: 20ms }] }
  - { name: bottom, model: p-series, slave: 2, timeout: 50ms, poll: [{ read: distance_1, every: 20ms }] }
measurements:
  - name: gap
    expr: 20mm - top.distance_1 - bottom.distance_1
    limits: { lo: 9.9mm, hi: 10.1mm }
    stats: 100
    max_skew: 1s
";

    /// Issue 32, point 5: under the devices, a line per measurement: the value with its unit,
    /// its judgement marked in text, the skew and the statistics, all as the bus's event says.
    #[tokio::test]
    async fn the_terminal_view_has_a_line_per_measurement_under_the_devices() {
        let file = BusFile::parse("bus.yaml", GAP, Path::new("."), models::catalogue())
            .unwrap_or_else(|e| panic!("{}", e.render()));
        let mut view = TerminalView::new(&file);
        assert!(view
            .text("")
            .ends_with("\nmeasurements\ngap  no value yet\n"));
        let bus = Bus::new(file);
        let mut events = bus.subscribe();
        let _running = bus.start().unwrap();
        let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
        let event = loop {
            assert!(tokio::time::Instant::now() < deadline, "no valid gap value");
            let Ok(Ok(event)) = tokio::time::timeout(Duration::from_secs(5), events.recv()).await
            else {
                continue;
            };
            if let Event::Measurement(measurement) = &event {
                view.measurement(measurement);
                let counted = measurement.stats.is_some_and(|s| s.count >= 3);
                if measurement.value.is_ok() && counted {
                    break Arc::clone(measurement);
                }
            }
        };
        let text = view.text("2 devices");
        let (devices, block) = text.split_once("\nmeasurements\n").expect("a block");
        assert!(devices.contains("\nbottom · "), "{text}");
        let line = block.strip_prefix("gap  ").expect("the gap's line");
        let value = event.value.as_ref().unwrap();
        let stats = event.stats.unwrap();
        let mark = match event.judgement.unwrap().name() {
            "lo" => "[LO ▼]",
            "go" => "[GO ✓]",
            "hi" => "[HI ▲]",
            other => panic!("{other}"),
        };
        let places = value.to_string().split_once('.').unwrap().1.len() + 1;
        let expected = format!(
            "{value} mm  {mark}  skew {:.2} ms  n {}  mean {:.places$} mm  sd {:.places$} mm  \
             Cpk {:.2}\n",
            event.skew.as_secs_f64() * 1000.0,
            stats.count,
            stats.mean,
            stats.sd.unwrap(),
            stats.cpk.unwrap(),
        );
        assert_eq!(line, expected);
    }

    #[test]
    fn an_invalid_value_shows_a_dash_and_why() {
        let mut view = TerminalView::new(
            &BusFile::parse("bus.yaml", GAP, Path::new("."), models::catalogue()).unwrap(),
        );
        view.measurement(&Arc::new(MeasurementEvent {
            measurement: "gap".into(),
            unit: "mm".into(),
            value: Err("top is offline".into()),
            inputs: Vec::new(),
            skew: Duration::from_micros(1500),
            judgement: None,
            stats: None,
            counts: None,
            time: std::time::SystemTime::now(),
        }));
        assert!(
            view.text("")
                .ends_with("\nmeasurements\ngap  —  (top is offline)  skew 1.50 ms\n"),
            "{}",
            view.text("")
        );
    }
}
