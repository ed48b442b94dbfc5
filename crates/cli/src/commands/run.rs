//! `optobus run BUS.yaml`: a bus of sensors polled on schedule, shown live (a block per
//! device), as JSON lines (`--json`), and recorded to a CSV per device (`--record DIR`).
//! `--demo` runs a built-in bus of simulated sensors with a gateway for other tools.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::future::Future;
use std::io::{BufWriter, IsTerminal, Write};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, SystemTime};

use clap::Args;
use optobus_bus::file::GatewayConfig;
use optobus_bus::{
    Bus, BusFile, Event, Health, HttpConfig, LineConfig, MetricsConfig, MqttConfig, Sample,
};
use optobus_device::RegisterInfo;
use optobus_inspect::Value;
use tokio::sync::broadcast::{self, error::RecvError, error::TryRecvError};

use crate::commands::bus::load;
use crate::error::CliError;
use crate::inputs;
use crate::log::note;
use crate::models;
use crate::outlet::{Outlet, Sink};
use crate::render::{counted, csv_cells, csv_headers, redraw, screen, time_of_day, values_text};

/// The demo bus: a sensor of every built-in model on one simulated line, with a gateway.
const DEMO: &str = include_str!("../demo.yaml");

/// How often the terminal view is redrawn.
const REDRAW_EVERY: Duration = Duration::from_millis(250);

/// Lines stdout may fall behind by (seconds of a busy bus) before its oldest are dropped.
const STDOUT_LINES: usize = 4096;

/// Samples the CSVs of `--record` may fall behind by before their oldest are dropped.
const RECORD_SAMPLES: usize = 4096;

/// How long the end of a run waits for stdout and the CSVs to take what is still queued: a
/// reader that stalled for good must not hold the exit forever.
const DRAIN_AT_END: Duration = Duration::from_secs(2);

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
fn command_line_outputs(bus: &mut BusFile, args: &RunArgs) -> Result<(), CliError> {
    if let Some(broker) = &args.mqtt {
        let given =
            MqttConfig::for_broker(broker).map_err(|e| CliError::new(format!("--mqtt: {e}")))?;
        match bus.outputs.mqtt.as_mut() {
            Some(mqtt) => (mqtt.host, mqtt.port) = (given.host, given.port),
            None => bus.outputs.mqtt = Some(given),
        }
    }
    if args.homeassistant {
        let mqtt = bus.outputs.mqtt.as_mut().ok_or_else(|| {
            CliError::new(
                "--homeassistant needs a broker: give --mqtt HOST:PORT or `mqtt` in the bus file",
            )
        })?;
        mqtt.homeassistant
            .get_or_insert_with(|| "homeassistant".to_owned());
    }
    if let Some(address) = args.http {
        match bus.outputs.http.as_mut() {
            Some(http) => http.listen = address,
            None => bus.outputs.http = Some(HttpConfig::new(address)),
        }
    }
    if let Some(address) = &args.prometheus {
        bus.outputs.metrics = Some(
            MetricsConfig::for_address(address)
                .map_err(|e| CliError::new(format!("--prometheus: {e}")))?,
        );
    }
    Ok(())
}

/// The demo's bus file, its gateway moved to `gateway` if given.
pub(crate) fn demo(gateway: Option<SocketAddr>) -> Result<BusFile, CliError> {
    let mut bus = BusFile::parse("demo.yaml", DEMO, ".".as_ref(), models::catalogue())
        .map_err(|rejected| CliError::new(rejected.render()))?;
    if let Some(address) = gateway {
        move_gateway(&mut bus, address)?;
    }
    Ok(bus)
}

/// `--gateway ADDRESS`: the bus file's one gateway listens there instead; a file without one
/// gets a read-only gateway there on its one RTU line (a Modbus TCP line needs none). Which
/// gateway is meant must be plain: several are refused.
fn move_gateway(bus: &mut BusFile, address: SocketAddr) -> Result<(), CliError> {
    let names = |lines: &[&LineConfig]| {
        let names: Vec<String> = lines.iter().map(|l| format!("`{}`", l.name)).collect();
        names.join(", ")
    };
    let with_gateway: Vec<&LineConfig> = bus.lines.iter().filter(|l| l.gateway.is_some()).collect();
    let rtu: Vec<&LineConfig> = bus.lines.iter().filter(|l| l.port.is_rtu()).collect();
    let refusal = match (with_gateway.as_slice(), rtu.as_slice()) {
        ([_], _) | ([], [_]) => None,
        ([], []) => Some(
            CliError::new("--gateway: the bus file has no RTU line for a gateway to serve")
                .hint("other masters reach the devices of a Modbus TCP line directly"),
        ),
        ([], several) => Some(
            CliError::new(format!(
                "--gateway: which line should it serve? The bus file has RTU lines {}",
                names(several)
            ))
            .hint("give `gateway: ADDRESS` under that line in the bus file"),
        ),
        (several, _) => Some(
            CliError::new(format!(
                "--gateway: lines {} of the bus file have gateways, and it moves one",
                names(several)
            ))
            .hint("give each its address in the bus file"),
        ),
    };
    if let Some(refusal) = refusal {
        return Err(refusal);
    }
    let line = match with_gateway.first().or(rtu.first()) {
        Some(line) => line.name.clone(),
        None => return Ok(()),
    };
    if let Some(line) = bus.lines.iter_mut().find(|l| l.name == line) {
        match line.gateway.as_mut() {
            Some(gateway) => gateway.listen = address,
            None => line.gateway = Some(GatewayConfig::new(address)),
        }
    }
    Ok(())
}

/// The latest of everything, for the terminal view.
#[derive(Default)]
struct Board {
    /// Per device, in file order: its header facts, health and latest values.
    devices: Vec<Shown>,
}

struct Shown {
    name: String,
    facts: String,
    health: Health,
    values: BTreeMap<(u8, u16, &'static str), (&'static RegisterInfo, Value)>,
}

impl Board {
    fn new(bus: &BusFile) -> Self {
        let devices = bus
            .devices
            .iter()
            .map(|device| Shown {
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
        Self { devices }
    }

    fn device(&mut self, name: &str) -> Option<&mut Shown> {
        self.devices.iter_mut().find(|d| d.name == name)
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
        text
    }
}

/// A CSV per device: a row per poll, columns for every register the device's polls read (a
/// column per field of packed and record registers); a row leaves empty the columns its poll
/// does not read, and marks an invalid reading `NaN`.
/// It writes on a thread of its own (an [`Outlet`]): a slow disk costs its own oldest samples,
/// never the runtime's time.
struct Recorder {
    started: SystemTime,
    files: HashMap<String, DeviceCsv>,
    /// The first write that failed: the recording stopped there.
    failed: Option<CliError>,
}

struct DeviceCsv {
    out: BufWriter<File>,
    path: PathBuf,
    /// Each register's first column and its count (one per field of a packed or record
    /// register).
    columns: HashMap<&'static str, (usize, usize)>,
    /// Columns in all.
    width: usize,
    /// The poll being gathered: its request time and cells (empty until read).
    row: Option<(SystemTime, Vec<String>)>,
}

impl Recorder {
    fn create(dir: &std::path::Path, bus: &BusFile) -> Result<Self, CliError> {
        std::fs::create_dir_all(dir)
            .map_err(|e| CliError::failed(format!("cannot create {}: {e}", dir.display())))?;
        let mut files = HashMap::new();
        for device in &bus.devices {
            let mut registers: Vec<&'static RegisterInfo> = device
                .polls
                .iter()
                .flat_map(|p| p.registers.iter().copied())
                .collect();
            registers.sort_by_key(|r| (r.table, r.address));
            registers.dedup_by_key(|r| r.name);
            let path = dir.join(format!("{}.csv", device.name));
            let file = File::create(&path)
                .map_err(|e| CliError::failed(format!("cannot write {}: {e}", path.display())))?;
            let mut out = BufWriter::new(file);
            let mut header = Vec::new();
            let mut columns = HashMap::new();
            for register in registers {
                let split = csv_headers(register);
                columns.insert(register.name, (header.len(), split.len()));
                header.extend(split);
            }
            writeln!(out, "time,elapsed [s],{}", header.join(","))
                .map_err(|e| CliError::failed(format!("cannot write {}: {e}", path.display())))?;
            files.insert(
                device.name.clone(),
                DeviceCsv {
                    out,
                    path,
                    columns,
                    width: header.len(),
                    row: None,
                },
            );
        }
        Ok(Self {
            started: SystemTime::now(),
            files,
            failed: None,
        })
    }

    fn add(&mut self, sample: &Sample) -> Result<(), CliError> {
        let Some(csv) = self.files.get_mut(&*sample.source.device) else {
            return Ok(());
        };
        if csv
            .row
            .as_ref()
            .is_some_and(|(at, _)| *at != sample.requested)
        {
            csv.flush_row(self.started)?;
        }
        let width = csv.width;
        let (_, cells) = csv
            .row
            .get_or_insert_with(|| (sample.requested, vec![String::new(); width]));
        if let Some(&(first, count)) = csv.columns.get(sample.register.name) {
            let split = csv_cells(sample.register, &sample.value);
            for (cell, value) in cells.iter_mut().skip(first).take(count).zip(split) {
                *cell = value;
            }
        }
        Ok(())
    }

    /// Writes the last rows; gives the first failure of the whole recording.
    fn finish(mut self) -> Result<(), CliError> {
        if let Some(failed) = self.failed {
            return Err(failed);
        }
        for csv in self.files.values_mut() {
            csv.flush_row(self.started)?;
            csv.out.flush().map_err(|e| {
                CliError::failed(format!("cannot write {}: {e}", csv.path.display()))
            })?;
        }
        Ok(())
    }
}

impl Sink<Arc<Sample>> for Recorder {
    fn write(&mut self, samples: Vec<Arc<Sample>>, _: u64) {
        if self.failed.is_some() {
            return;
        }
        for sample in samples {
            if let Err(error) = self.add(&sample) {
                // Said now (the run goes on for its other outputs), and again at the end.
                note!("optobus: --record stopped: {error}");
                self.failed = Some(error);
                return;
            }
        }
    }
}

/// Stdout: a line per item, or on a terminal the newest board drawn over the last one.
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
                // Only the newest board matters.
                if let Some(board) = items.last() {
                    let size = screen(crossterm::terminal::size().ok());
                    *drawn = redraw(&mut out, *drawn, board, size);
                }
            }
        }
        let _ = out.flush();
    }
}

/// Takes `events` as they come until `stop` ends, then what the receiver already holds (the
/// samples of the last poll before the stop, which a stop that won the race would leave
/// behind); gives how many events it fell too far behind to see.
async fn follow<E: Clone>(
    events: &mut broadcast::Receiver<E>,
    stop: impl Future<Output = ()>,
    mut take: impl FnMut(E),
) -> u64 {
    let mut missed = 0;
    tokio::pin!(stop);
    loop {
        let event = tokio::select! {
            event = events.recv() => event,
            () = &mut stop => break,
        };
        match event {
            Ok(event) => take(event),
            Err(RecvError::Lagged(count)) => missed += count,
            Err(RecvError::Closed) => return missed,
        }
    }
    loop {
        match events.try_recv() {
            Ok(event) => take(event),
            Err(TryRecvError::Lagged(count)) => missed += count,
            Err(TryRecvError::Empty | TryRecvError::Closed) => return missed,
        }
    }
}

impl DeviceCsv {
    fn flush_row(&mut self, started: SystemTime) -> Result<(), CliError> {
        let Some((at, cells)) = self.row.take() else {
            return Ok(());
        };
        let elapsed = at.duration_since(started).unwrap_or_default().as_secs_f64();
        writeln!(
            self.out,
            "{},{elapsed:.6},{}",
            local_time(at),
            cells.join(",")
        )
        .map_err(|e| CliError::failed(format!("cannot write {}: {e}", self.path.display())))
    }
}

/// A time in the tool's RFC 3339 form, with the local offset.
fn local_time(at: SystemTime) -> String {
    jiff::Timestamp::try_from(at)
        .map(|t| {
            t.to_zoned_datetime(jiff::tz::TimeZone::system())
                .strftime("%Y-%m-%dT%H:%M:%S%.6f%:z")
                .to_string()
        })
        .unwrap_or_default()
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
    let mut bus_file = match &args.file {
        Some(path) => {
            let mut bus = load(path)?;
            if let Some(address) = args.gateway {
                move_gateway(&mut bus, address)?;
            }
            bus
        }
        None if args.demo => demo(args.gateway)?,
        None => {
            let hint = "`optobus run --demo` runs a built-in bus of simulated sensors, one of \
                        every model; `optobus bus schema` prints what a bus file takes";
            return Err(CliError::usage(
                "`optobus run` needs a bus file: `optobus run plant.yaml`",
            )
            .hint(hint));
        }
    };
    command_line_outputs(&mut bus_file, args)?;
    let mut board = Board::new(&bus_file);
    let recorder = match &args.record {
        Some(dir) => Some(Outlet::start(
            "optobus-record",
            RECORD_SAMPLES,
            Recorder::create(dir, &bus_file)?,
        )),
        None => None,
    };
    let http = bus_file.outputs.http.clone();
    let lines = bus_file.lines.len();
    let devices = bus_file.devices.len();
    let bus = Bus::new(bus_file.clone());
    let mut events = bus.subscribe();
    let mut outputs = Vec::new();
    let exporter = match &bus_file.outputs.metrics {
        Some(config) => {
            let exporter = optobus_metrics::Exporter::start(config, &bus_file, bus.subscribe())
                .await
                .map_err(|e| CliError::failed(format!("metrics on {}: {e}", config.listen)))?;
            outputs.push(format!("metrics on http://{}/metrics", exporter.address()));
            Some(exporter)
        }
        None => None,
    };
    let mqtt_events = bus_file.outputs.mqtt.as_ref().map(|_| bus.subscribe());
    let running = bus.start().map_err(|e| CliError::failed(e.to_string()))?;
    let publisher = match (&bus_file.outputs.mqtt, mqtt_events) {
        (Some(config), Some(events)) => {
            let publisher =
                optobus_mqtt::Publisher::start(config, &bus_file, events, Some(running.handle()))
                    .map_err(|e| CliError::failed(e.to_string()))?;
            outputs.push(format!(
                "MQTT to {}:{}, topics {}/…{}",
                config.host,
                config.port,
                config.prefix,
                if config.homeassistant.is_some() {
                    ", Home Assistant discovery"
                } else {
                    ""
                }
            ));
            if let Some(exporter) = &exporter {
                crate::mqtt_metrics::add(exporter.metrics(), publisher.counts_reader())
                    .map_err(|e| CliError::failed(format!("metrics of MQTT: {e}")))?;
            }
            Some(publisher)
        }
        _ => None,
    };
    let gateways: Vec<String> = running
        .gateways()
        .map(|(line, address)| format!("gateway of {line} on {address}"))
        .chain(outputs)
        .collect();
    let header = format!(
        "{lines} line{}, {devices} device{}{}",
        if lines == 1 { "" } else { "s" },
        if devices == 1 { "" } else { "s" },
        gateways
            .iter()
            .map(|g| format!(" · {g}"))
            .collect::<String>()
    );
    if !gateways.is_empty() {
        note!("optobus: {}", gateways.join(", "));
    }
    let console = match &http {
        Some(config) => {
            let server = optobus_console::serve(&running, config)
                .await
                .map_err(|e| CliError::failed(e.to_string()))?;
            note!("optobus: the console is on {}", server.url());
            Some(server)
        }
        None => None,
    };
    let terminal = std::io::stdout().is_terminal() && !json;
    let stdout = if terminal {
        // The newest board only: one waiting drawing is replaced by the next.
        Outlet::start("optobus-stdout", 1, Stdout::Screen { drawn: 0 })
    } else {
        Outlet::start("optobus-stdout", STDOUT_LINES, Stdout::Lines)
    };
    let stop = async {
        let ctrl_c = tokio::signal::ctrl_c();
        match args.duration {
            Some(duration) => {
                tokio::select! {
                    _ = ctrl_c => {},
                    () = tokio::time::sleep(duration) => {},
                }
            }
            None => {
                let _ = ctrl_c.await;
            }
        }
    };
    let mut redraw_at = tokio::time::Instant::now();
    let take = |event: Event| {
        match &event {
            Event::Sample(sample) => {
                if let Some(recorder) = &recorder {
                    if recorder.push(Arc::clone(sample)).first_drop() {
                        note!("optobus: --record is not keeping up: dropping its oldest samples");
                    }
                }
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
                if let Some(shown) = board.device(&sample.source.device) {
                    let key = (
                        sample.register.table as u8,
                        sample.register.address,
                        sample.register.name,
                    );
                    shown
                        .values
                        .insert(key, (sample.register, sample.value.clone()));
                }
            }
            Event::Health(health) => {
                if let Some(shown) = board.device(&health.source.device) {
                    shown.health = health.health;
                }
            }
            // Samples and measurements only on stdout: writes are in the audit trail (stderr).
            Event::Line(_) | Event::Written(_) => {}
            Event::Measurement(measurement) => {
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
            stdout.push(board.text(&header));
            redraw_at = tokio::time::Instant::now() + REDRAW_EVERY;
        }
    };
    let missed = follow(&mut events, stop, take).await;
    drop(console);
    drop(running);
    if let Some(publisher) = publisher {
        let counts = publisher.counts();
        if counts.dropped > 0 || !counts.connected {
            note!(
                "optobus: MQTT: {} published, {} dropped while the broker was away, {} still queued",
                counted(counts.published, "sample"),
                counts.dropped,
                counts.queued
            );
        }
        publisher.stop(Duration::from_secs(2)).await;
    }
    drop(exporter);
    // Stdout and the CSVs are waited for on a thread of the blocking pool: meanwhile the
    // runtime goes on closing the gateway and the other listeners.
    let (unwritten, stdout_dropped, recording) = tokio::task::spawn_blocking(move || {
        let unwritten = stdout.flush(DRAIN_AT_END);
        let recording = recorder.map(|r| (r.dropped(), r.finish(DRAIN_AT_END)));
        (unwritten, stdout.dropped(), recording)
    })
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
    if let Some((dropped, recorder)) = recording {
        if dropped > 0 {
            note!("optobus: --record fell behind: its {dropped} oldest samples were dropped");
        }
        match recorder {
            Some(recorder) => recorder.finish()?,
            None => {
                return Err(CliError::failed(
                    "--record: the CSVs did not take their last rows in time",
                ))
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn with_duration_the_last_polls_samples_are_taken_at_the_stop() {
        // The last poll's events are in the receiver when the stop comes, in the same turn
        // of the runtime: every one of them is still taken.
        let (sender, mut events) = broadcast::channel(256);
        for event in 0..100u32 {
            sender.send(event).unwrap();
        }
        let mut taken = Vec::new();
        let missed = follow(&mut events, std::future::ready(()), |e| taken.push(e)).await;
        assert_eq!(missed, 0);
        assert_eq!(taken, (0..100).collect::<Vec<_>>());
    }

    #[tokio::test]
    async fn events_beyond_the_channel_are_counted_as_missed() {
        let (sender, mut events) = broadcast::channel(4);
        for event in 0..10u32 {
            sender.send(event).unwrap();
        }
        let mut taken = Vec::new();
        let missed = follow(&mut events, std::future::ready(()), |e| taken.push(e)).await;
        assert_eq!(missed, 6);
        assert_eq!(taken, [6, 7, 8, 9]);
    }
}
