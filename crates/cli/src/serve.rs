//! Commands that are more than a read or a write: serving a simulator, scanning a line, and
//! the P-series buffer download.

use std::io::IsTerminal;
use std::path::Path;
use std::time::Duration;

use optobus_codec::{ReadFunction, Request, WriteValue};
use optobus_device::DeviceInfo;
use optobus_driver::transport::Parity;
use optobus_driver::{serial_settings, Core};
use optobus_simulator::{Exchange, Reply, Simulator};

use crate::commands::{answering_slave, print, target};
use crate::error::{driver_error, CliError};
use crate::link::{self, Link};
use crate::log::{self, note, Log};
use crate::{inputs, models, values, Global};

/// One log line for a request the simulator answered.
fn describe(exchange: &Exchange<'_>) -> String {
    let slave = exchange
        .slave
        .map(|s| format!("slave {s} "))
        .unwrap_or_default();
    let request = match exchange.request {
        Some(Request::Read {
            function,
            address,
            count,
        }) => {
            let table = match function {
                ReadFunction::Holding => "holding",
                ReadFunction::Input => "input",
            };
            format!("read {table} {address} x{count}")
        }
        Some(Request::Write { address, value }) => match value {
            WriteValue::Word(word) => format!("write {address} = {word}"),
            WriteValue::DoubleWord(value) => format!("write {address} = {value} (4 bytes)"),
        },
        None => format!("function {:02X}", exchange.function),
    };
    let reply = match exchange.reply {
        Reply::Read { words, .. } => format!("{} words", words.len()),
        Reply::Write { .. } => "echo".to_owned(),
        Reply::Exception { code, .. } => format!("exception {:02X}", code.0),
        Reply::Silent => "no reply".to_owned(),
    };
    format!("{} {slave}{request} -> {reply}", link::timestamp())
}

/// `optobus simulate`: serves a virtual device until Ctrl-C or `duration`. Every exchange is
/// logged on stderr by a thread of its own ([`Log`]), so a slow or closed stderr never holds
/// up a reply.
pub(crate) async fn simulate(
    device: &'static DeviceInfo,
    global: &Global,
    pty: bool,
    duration: Option<Duration>,
) -> Result<(), CliError> {
    let slave = global.slave.unwrap_or(device.default_slave);
    if slave == 0 {
        return Err(CliError::new(
            "a device never has slave address 0: it is the broadcast address",
        )
        .hint("serve at 1 to 247 with --slave"));
    }
    let log = Log::start();
    let sim = Simulator::new(device).slave(slave).observe({
        let log = log.clone();
        move |exchange| log.line(describe(exchange))
    });
    let served = match serve(device, global, pty, slave, &sim, &log).await {
        Ok(server) => {
            let _ = std::io::Write::flush(&mut std::io::stdout());
            match duration {
                Some(duration) => tokio::select! {
                    () = tokio::time::sleep(duration) => {}
                    _ = tokio::signal::ctrl_c() => {}
                },
                None => {
                    let _ = tokio::signal::ctrl_c().await;
                }
            }
            drop(server);
            Ok(())
        }
        Err(error) => Err(error),
    };
    // Whether lines were dropped, if stderr takes it.
    log.finish(Duration::from_millis(200));
    served
}

/// Starts serving `sim` as `global` and `pty` say; gives what must be kept alive.
async fn serve(
    device: &'static DeviceInfo,
    global: &Global,
    pty: bool,
    slave: u8,
    sim: &Simulator,
    log: &Log,
) -> Result<Box<dyn std::any::Any>, CliError> {
    Ok(if pty {
        let pty = sim
            .serve_pty()
            .map_err(|e| CliError::new(format!("cannot open a pty: {e}")))?;
        print(&pty.path().display().to_string());
        log.line(format!(
            "optobus: simulating {} (slave {slave}) on RTU at {}",
            device.family,
            pty.path().display()
        ));
        Box::new(pty)
    } else if let Some(path) = &global.serial {
        let mut settings = serial_settings(device, path.as_str());
        if let Some(baud) = global.baud {
            settings.line.baud = baud;
        }
        if let Some(parity) = global.parity.and_then(|p| Parity::from_name(p.name())) {
            settings.line.parity = parity;
        }
        let port = settings
            .open()
            .map_err(|e| CliError::new(format!("cannot open {path}: {e}")))?;
        print(path);
        log.line(format!(
            "optobus: simulating {} (slave {slave}) on RTU at {path}",
            device.family
        ));
        let sim = sim.clone();
        Box::new(tokio::spawn(async move { sim.serve_rtu(port).await }))
    } else {
        let address = global.tcp.as_deref().unwrap_or("127.0.0.1:5020");
        let address = link::resolve_tcp(address, 5020).await?;
        let server = sim.serve_tcp(address).await.map_err(|e| {
            CliError::new(format!("cannot listen on {address}: {e}"))
                .hint("is another server using the port? try --tcp 127.0.0.1:0")
        })?;
        print(&server.local_addr().to_string());
        log.line(format!(
            "optobus: simulating {} (slave {slave}) on Modbus TCP at {}",
            device.family,
            server.local_addr()
        ));
        Box::new(server)
    })
}

/// `optobus scan`: which baud rate and slave address a device answers on.
pub(crate) async fn scan(
    global: &Global,
    bauds: Option<&str>,
    slaves: Option<&str>,
) -> Result<(), CliError> {
    let device = models::find(&global.model)?;
    answering_slave(device, global, "scan")?;
    let bauds: Vec<u32> = match (bauds, global.baud) {
        (Some(text), _) => inputs::parse_bauds(device, text, global.any_baud)?,
        (None, Some(baud)) => {
            inputs::check_baud(device, "--baud", baud, global.any_baud)?;
            vec![baud]
        }
        (None, None) => device
            .rtu
            .map(|r| r.bauds.to_vec())
            .unwrap_or_else(|| vec![9600]),
    };
    let slaves = match slaves {
        Some(text) => inputs::parse_slaves(text)?,
        None => {
            let (first, last) = inputs::SLAVES;
            (device.slaves.0.max(first)..=device.slaves.1.min(last)).collect()
        }
    };
    let Some(path) = &global.serial else {
        return Err(CliError::new("scan needs a serial port").hint("give --serial PORT"));
    };
    let probe = device
        .registers
        .iter()
        .find(|r| r.access.readable())
        .ok_or_else(|| CliError::new("the model has no readable register"))?;
    let progress = std::io::stderr().is_terminal();
    let mut found = Vec::new();
    for &baud in &bauds {
        let mut target = target(global);
        target.baud = Some(baud);
        // A silent address costs the whole timeout: keep it short unless asked otherwise.
        target.timeout = global.timeout.min(Duration::from_millis(200));
        let link = link::open(device, 0, &target).await?;
        let mut core = Core::with_default_slave(link, device);
        for (i, &slave) in slaves.iter().enumerate() {
            if progress {
                log::stderr(format_args!(
                    "\rscanning {baud} baud: slave {slave} ({}/{})   ",
                    i + 1,
                    slaves.len()
                ));
            }
            core.set_slave(slave)?;
            let answered = match core.read_words(probe).await {
                Ok(_) => true,
                // An exception is an answer too: something lives at this address.
                Err(e) => e.exception().is_some(),
            };
            if answered {
                if progress {
                    note!();
                }
                print(&format!("found: slave {slave} at {baud} baud"));
                found.push((baud, slave));
            }
        }
    }
    if progress {
        note!();
    }
    if global.json {
        let list: Vec<serde_json::Value> = found
            .iter()
            .map(|(baud, slave)| serde_json::json!({"baud": baud, "slave": slave}))
            .collect();
        print(&serde_json::Value::Array(list).to_string());
    }
    if found.is_empty() {
        return Err(CliError::new(format!("no device answered on {path}"))
            .hint("check wiring and parity, or widen --bauds and --slaves"));
    }
    Ok(())
}

/// The measurement `source` names, with `count` checked against the values the P series lets
/// be read out (appendix 3): both refused before anything is opened or sent.
pub(crate) fn buffer_input(
    count: u16,
    source: &str,
) -> Result<optobus_p_series::MeasurementSource, CliError> {
    use optobus_p_series::{MeasurementSource, DEVICE};
    let register = |name: &str| {
        DEVICE
            .register(name)
            .ok_or_else(|| CliError::new(format!("the P-series spec has no {name}")))
    };
    let most = optobus_p_series::download::MAX_DOWNLOAD;
    if !(1..=most).contains(&count) {
        return Err(CliError::new(format!(
            "--count {count}: the P series buffers 1 to {most} values for reading out"
        )));
    }
    let words = values::parse(register("buffer_data_type")?, source)?;
    Ok(MeasurementSource::from_raw(u32::from(
        words.first().copied().unwrap_or(0),
    )))
}

/// `optobus buffer` (P series): buffer `count` values of `source`, download, write CSV.
pub(crate) async fn buffer(
    link: Link,
    slave: u8,
    global: &Global,
    count: u16,
    source: optobus_p_series::MeasurementSource,
    wait: Duration,
    out: Option<&Path>,
) -> Result<(), CliError> {
    use optobus_p_series::PSeries;
    let mut sensor = PSeries::new(link, slave)?;
    sensor
        .start_buffering(source, count)
        .await
        .map_err(|e| driver_error(e, Some("buffer_report_count")))?;
    note!(
        "optobus: buffering {count} values of {source}; reading out in {} ms",
        wait.as_millis()
    );
    tokio::time::sleep(wait).await;
    let terminal = std::io::stderr().is_terminal();
    let values = sensor
        .download_buffer(|p| {
            let width = 30;
            let done = (p.received * width)
                .checked_div(p.expected)
                .unwrap_or(width);
            let bar = format!(
                "[{}{}] {}/{} values, {} pages",
                "#".repeat(done),
                "-".repeat(width - done.min(width)),
                p.received,
                p.expected,
                p.pages
            );
            if terminal {
                log::stderr(format_args!("\r{bar}"));
            } else {
                note!("{bar}");
            }
        })
        .await
        .map_err(|e| driver_error(e, Some("buffer")))?;
    if terminal {
        note!();
    }
    let mut csv = String::from("index,value_mm\n");
    for (index, value) in values.iter().enumerate() {
        match value {
            Some(value) => csv.push_str(&format!("{index},{}\n", value.millimetres())),
            None => csv.push_str(&format!("{index},\n")),
        }
    }
    if global.json && out.is_none() {
        let list: Vec<serde_json::Value> = values
            .iter()
            .map(|v| match v {
                Some(v) => serde_json::json!(v.to_f64()),
                None => serde_json::Value::Null,
            })
            .collect();
        print(&serde_json::json!({"unit": "mm", "values": list}).to_string());
        return Ok(());
    }
    match out {
        Some(path) => {
            std::fs::write(path, csv)
                .map_err(|e| CliError::new(format!("cannot write {}: {e}", path.display())))?;
            note!(
                "optobus: {} values written to {}",
                values.len(),
                path.display()
            );
        }
        None => print(&csv),
    }
    Ok(())
}
