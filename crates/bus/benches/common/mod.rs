//! What the bus's benches share: the mixed devices, bus files, emulated lines, statistics and
//! the machine's load.

#![allow(dead_code)]

use std::path::Path;
use std::time::Duration;

use optobus_bus::{BusFile, Catalogue};
use optobus_codec::LineFormat;
use optobus_device::DeviceInfo;
use optobus_simulator::{Line, LineStats, Simulator};

/// Eight devices of mixed families, at slaves 1 to 8.
pub(crate) fn models() -> [&'static DeviceInfo; 8] {
    [
        &optobus_p_series::DEVICE,
        &optobus_ccs::DEVICE,
        &optobus_ccf::DEVICE,
        &optobus_lc_rs::DEVICE,
        &optobus_rangefinder::DEVICE,
        &optobus_p_series::DEVICE,
        &optobus_ccs::DEVICE,
        &optobus_ccf::DEVICE,
    ]
}

/// The model's name as a bus file writes it.
pub(crate) fn model_name(device: &DeviceInfo) -> String {
    device.model_name().to_string()
}

/// A bus file of one line called `bench` (`line` holds the rest of its flow mapping, e.g.
/// `serial: bench, baud: 115200`) and the devices given as flow mappings.
pub(crate) fn bus_file(line: &str, devices: &[String]) -> BusFile {
    let catalogue = Catalogue::new(models());
    let mut text = format!("lines:\n  - {{ name: bench, {line}, any_format: true }}\ndevices:\n");
    for device in devices {
        text += &format!("  - {device}\n");
    }
    BusFile::parse("bench.yaml", &text, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}\n{text}", e.render()))
}

/// Simulators of `models` at slaves 1, 2, … with steady signals (no sentinel samples).
pub(crate) fn simulators(models: &[&'static DeviceInfo]) -> Vec<Simulator> {
    models
        .iter()
        .enumerate()
        .map(|(i, model)| Simulator::new(model).slave(i as u8 + 1).sentinel_every(0))
        .collect()
}

/// An emulated RS-485 line of `format` (device turnaround 0) to `simulators`: the client's
/// end and the line's counters.
pub(crate) fn emulated_line(
    simulators: Vec<Simulator>,
    format: LineFormat,
) -> (tokio::io::DuplexStream, LineStats) {
    let line = Line::new(format);
    let stats = line.stats();
    let (stream, _server) = optobus_simulator::Slaves::new(simulators).duplex_line(line);
    (stream, stats)
}

/// The `q` quantile (0 to 1) of `values`, by nearest rank.
pub(crate) fn quantile(values: &[f64], q: f64) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

pub(crate) fn median(values: &[f64]) -> f64 {
    quantile(values, 0.5)
}

pub(crate) fn ms(duration: Duration) -> f64 {
    duration.as_secs_f64() * 1e3
}

/// The load average of the last minute, as `uptime` shows it (the machine is shared).
pub(crate) fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(str::to_owned))
        .unwrap_or_else(|| "?".to_owned())
}

/// A single-threaded runtime, as the other benches use.
pub(crate) fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap()
}
