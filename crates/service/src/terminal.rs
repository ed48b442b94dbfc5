//! A running bus as a terminal shows it: the latest values and health of each device as text
//! blocks with a line per measurement under them ([`TerminalView`], redrawn in place by the
//! front end), and, for a pipe or a script, a line per sample and per measurement
//! ([`event_line`]). The console's `Board` keeps the same facts as JSON for the browser.

use std::collections::BTreeMap;
use std::sync::Arc;

use optobus_bus::{BusFile, Event, Health, MeasurementEvent, Sample};
use optobus_device::RegisterInfo;
use optobus_inspect::{values_text, Value};

use crate::journal::time_of_day;
use crate::recording::local_time;

/// The latest values and health of each device as text blocks, and under them a line per
/// measurement, for the terminal (the console's `Board` keeps the same facts as JSON for the
/// browser, with errors and lines).
pub struct TerminalView {
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
    /// The view of the bus of `bus`: every device online with no value yet, every measurement
    /// with no value yet.
    pub fn new(bus: &BusFile) -> Self {
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

    /// Takes what `event` says about the devices and measurements in view (a sample, a
    /// device's health, a measurement); the other events change nothing shown.
    pub fn follow(&mut self, event: &Event) {
        match event {
            Event::Sample(sample) => self.sample(sample),
            Event::Health(health) => self.health(&health.source.device, health.health),
            Event::Measurement(measurement) => self.measurement(measurement),
            Event::Line(_) | Event::Written(_) => {}
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

    /// The view as text: the time of day and `header` on the first line, then a block per
    /// device and, where the bus has measurements, a line per measurement.
    pub fn text(&self, header: &str) -> String {
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

/// An event as one line for a pipe, or as JSON for a script (`json`): a sample (the bus's
/// fields, its time with the local offset) or a measurement (its keys are the contract);
/// `None` for the other events (writes are in the audit trail, on stderr).
pub fn event_line(event: &Event, json: bool) -> Option<String> {
    match event {
        Event::Sample(sample) if json => Some(sample_line(sample)),
        Event::Sample(sample) => Some(format!(
            "{}  {}  {}  {}",
            time_of_day(),
            sample.source.device,
            sample.register.name,
            sample.value
        )),
        Event::Measurement(measurement) if json => serde_json::to_string(&**measurement).ok(),
        Event::Measurement(measurement) => {
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
        }
        Event::Health(_) | Event::Line(_) | Event::Written(_) => None,
    }
}

/// One JSON line for a sample: the bus's fields, its time with the local offset.
fn sample_line(sample: &Sample) -> String {
    let mut json = serde_json::to_value(sample).unwrap_or_default();
    if let Some(object) = json.as_object_mut() {
        object.insert("time".into(), local_time(sample.replied).into());
    }
    json.to_string()
}

#[cfg(test)]
mod tests {
    use std::path::Path;
    use std::time::Duration;

    use optobus_bus::{Bus, Catalogue};
    use optobus_testkit::bus_files::two_heads_gap;

    use super::*;

    fn gap_bus() -> BusFile {
        let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
        let text = two_heads_gap().timeout("50ms").stats(100).text();
        BusFile::parse("bus.yaml", &text, Path::new("."), &catalogue)
            .unwrap_or_else(|e| panic!("{}", e.render()))
    }

    /// Issue 32, point 5: under the devices, a line per measurement: the value with its unit,
    /// its judgement marked in text, the skew and the statistics, all as the bus's event says.
    #[tokio::test]
    async fn the_terminal_view_has_a_line_per_measurement_under_the_devices() {
        let file = gap_bus();
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
            view.follow(&event);
            if let Event::Measurement(measurement) = &event {
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

    /// The gap's event while its top head is offline, 1.5 ms apart from the bottom.
    fn top_offline() -> Arc<MeasurementEvent> {
        Arc::new(MeasurementEvent {
            measurement: "gap".into(),
            unit: "mm".into(),
            value: Err("top is offline".into()),
            inputs: Vec::new(),
            skew: Duration::from_micros(1500),
            judgement: None,
            stats: None,
            counts: None,
            time: std::time::SystemTime::now(),
        })
    }

    #[test]
    fn an_invalid_value_shows_a_dash_and_why() {
        let mut view = TerminalView::new(&gap_bus());
        view.measurement(&top_offline());
        assert!(
            view.text("")
                .ends_with("\nmeasurements\ngap  —  (top is offline)  skew 1.50 ms\n"),
            "{}",
            view.text("")
        );
    }

    #[test]
    fn a_measurement_is_one_line_for_a_pipe_and_its_event_for_a_script() {
        let event = Event::Measurement(top_offline());
        let line = event_line(&event, false).expect("a line");
        assert!(line.ends_with("  gap  invalid: top is offline"), "{line}");
        let json: serde_json::Value =
            serde_json::from_str(&event_line(&event, true).expect("a line")).unwrap();
        assert_eq!(json["measurement"], "gap");
        assert_eq!(json["reason"], "top is offline");
    }
}
