//! `optobus run BUS.yaml`: a bus of sensors polled on schedule, shown live (a block per
//! device), as JSON lines (`--json`), and recorded to a CSV per device (`--record DIR`).
//! `--demo` runs a built-in bus of simulated sensors with a gateway for other tools.

use std::io::{IsTerminal, Write};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use clap::Args;
use optobus_bus::{BusFile, Event, Follower, GatewayMoveError};
use optobus_service::outlet::{Outlet, Sink};
use optobus_service::terminal::{event_line, TerminalView};
use optobus_service::{
    HttpConfig, MetricsConfig, MqttConfig, Options, OutputsConfig, Service, ServiceFile,
    DRAIN_AT_END,
};

use crate::error::CliError;
use crate::inputs;
use crate::log::note;
use crate::models;
use crate::render::{counted, redraw, screen};

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
        // On a terminal the view shows the events; else a line each for a pipe or a script.
        let line = if terminal {
            None
        } else {
            event_line(&event, json)
        };
        if let Some(line) = line {
            if stdout.push(line).first_drop() {
                note!("optobus: stdout is not being read: dropping its oldest lines");
            }
        }
        view.follow(&event);
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
