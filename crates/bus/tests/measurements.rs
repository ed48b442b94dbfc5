//! Issue 32, point 1: `measurements:` in the bus file, checked with the rest of it, every
//! problem at once and at its line and column inside the expression; nothing opened. On the
//! running bus: the values, their judgement and counts, and (point 5) the gateway's
//! measurements unit read by a real Modbus TCP client.

use std::path::Path;
use std::time::Duration;

use optobus_bus::{BusFile, Catalogue};
use optobus_measure::Window;

fn parse(text: &str) -> Result<BusFile, String> {
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE, &optobus_ccs::DEVICE]);
    BusFile::parse("bus.yaml", text, Path::new("."), &catalogue).map_err(|e| e.render())
}

const DEVICES: &str = "
lines:
  - { name: rs485, serial: /dev/ttyUSB0 }
devices:
  - { name: top, model: p-series, slave: 1, poll: [{ read: distance_1, every: 20ms }] }
  - { name: bottom, model: p-series, slave: 2, poll: [{ read: distance_1, every: 50ms }] }
";

#[test]
fn a_measurement_reads_with_its_limits_statistics_and_skew() {
    let file = parse(&format!(
        "{DEVICES}measurements:
  - name: gap
    expr: 20mm - top.distance_1 - bottom.distance_1
    unit: mm
    limits: {{ lo: 9.9mm, hi: 10100um, hysteresis: 0.001mm }}
    stats: 200
  - name: twice
    expr: gap * 2
    stats: 10s
    max_skew: 5ms
"
    ))
    .expect("the file passes");
    let measurements = &file.measurements;
    let names: Vec<&str> = measurements
        .plan
        .formulas
        .iter()
        .map(|f| f.name.as_str())
        .collect();
    assert_eq!(names, ["gap", "twice"]);
    let inputs: Vec<String> = measurements
        .plan
        .inputs
        .iter()
        .map(ToString::to_string)
        .collect();
    assert_eq!(inputs, ["top.distance_1", "bottom.distance_1"]);
    let gap = &measurements.settings[0];
    let limits = gap.limits.expect("limits");
    assert_eq!(limits.hi.unwrap().to_f64(), 10.1);
    assert_eq!(limits.hysteresis.to_f64(), 0.001);
    assert_eq!(gap.stats, Some(Window::Count(200)));
    // By default the slowest input's period.
    assert_eq!(gap.max_skew, Duration::from_millis(50));
    let twice = &measurements.settings[1];
    assert_eq!(twice.stats, Some(Window::Duration(Duration::from_secs(10))));
    assert_eq!(twice.max_skew, Duration::from_millis(5));
    assert_eq!(measurements.plan.formulas[1].unit.name, "mm");
}

#[test]
fn every_problem_of_the_measurements_is_refused_at_its_line_and_column() {
    let rendered = parse(&format!(
        "{DEVICES}measurements:
  - name: units
    expr: 20s - top.distance_1
  - name: names
    expr: top.distanse_1 + middle.distance_1
  - name: unpolled
    expr: top.light_power + 1%
  - name: dimension
    expr: top.distance_1
    unit: s
  - name: loop_a
    expr: loop_b + 1mm
  - name: loop_b
    expr: loop_a - 1mm
  - name: limits
    expr: top.distance_1
    unit: mm
    limits: {{ lo: 2mm, hi: 1mm }}
  - name: window
    expr: top.distance_1
    stats: lots
"
    ))
    .expect_err("the measurements have problems");
    for (expected, place) in [
        ("m cannot be subtracted from s", "bus.yaml:9:17"),
        (
            "`p-series` has no register `distanse_1` (did you mean `distance_1`",
            "bus.yaml:11:11",
        ),
        ("the bus has no device `middle`", "bus.yaml:11:28"),
        (
            "no poll of `top` reads `light_power`: add it to one of its polls",
            "bus.yaml:13:11",
        ),
        (
            "`unit: s` is s, but the expression gives m",
            "bus.yaml:16:11",
        ),
        ("measurements use each other in a circle", "bus.yaml:"),
        ("`lo` must not be above `hi`", "bus.yaml:"),
        (
            "`stats` `lots` is neither a count of values nor a duration",
            "bus.yaml:",
        ),
    ] {
        assert!(
            rendered.contains(expected),
            "missing {expected:?} in:\n{rendered}"
        );
        assert!(rendered.contains(place), "missing {place} in:\n{rendered}");
    }
}

#[test]
fn a_bus_file_without_measurements_has_none() {
    let file = parse(DEVICES).expect("the file passes");
    assert!(file.measurements.is_empty());
}

mod running {
    use std::time::Duration;

    use std::process::Command;

    use optobus_bus::{Bus, Event, MeasurementEvent};
    use optobus_codec::value::{Fixed, Scale};
    use serde_json::Value;
    use tokio::sync::broadcast::error::{RecvError, TryRecvError};
    use tokio::sync::broadcast::Receiver;

    /// The measurement line of the tests (`optobus_testkit::bus_files`), with a unit and
    /// statistics.
    fn gap_file() -> String {
        optobus_testkit::bus_files::two_heads_gap()
            .timeout("100ms")
            .unit("mm")
            .stats(50)
            .text()
    }

    async fn measurement(events: &mut Receiver<Event>) -> std::sync::Arc<MeasurementEvent> {
        loop {
            match tokio::time::timeout(Duration::from_secs(10), events.recv()).await {
                Ok(Ok(Event::Measurement(measurement))) => return measurement,
                Ok(Ok(_)) | Ok(Err(RecvError::Lagged(_))) => {}
                Ok(Err(RecvError::Closed)) => panic!("the bus stopped"),
                Err(_) => panic!("no measurement within 10 s"),
            }
        }
    }

    /// Issue 32: each value is the exact arithmetic of the inputs it carries, read within
    /// `max_skew` of each other, judged and summed up; its JSON is the documented contract.
    #[tokio::test]
    async fn the_running_bus_computes_the_gap_from_the_samples_it_carries() {
        let bus = Bus::new(super::parse(&gap_file()).unwrap());
        let mut events = bus.subscribe();
        let _running = bus.start().expect("starts");
        let mut counts = Vec::new();
        for _ in 0..10 {
            let gap = measurement(&mut events).await;
            let value = gap.value.clone().expect("both heads answer");
            let [top, bottom] = [0, 1].map(|i| gap.inputs[i].value.expect("an input value"));
            assert_eq!(&*gap.inputs[0].name, "top.distance_1");
            let exact = 20_000_000
                - top.to_scale(value.scale()).unwrap().raw()
                - bottom.to_scale(value.scale()).unwrap().raw();
            assert_eq!(value, Fixed::new(exact, value.scale()), "{gap:?}");
            assert!(gap.judgement.is_some());
            counts.push(gap.stats.expect("stats").count);
            let json: serde_json::Value = serde_json::to_value(&*gap).unwrap();
            assert_eq!(json["measurement"], "gap");
            assert_eq!(json["value"]["value"], value.to_string());
            assert_eq!(json["value"]["unit"], "mm");
            assert_eq!(json["inputs"]["top.distance_1"]["value"], top.to_string());
            assert!(json["skew_us"].is_u64());
            assert!(json["stats"]["mean"]["value"].is_string());
            assert!(json["time"].is_string());
        }
        assert!(counts.windows(2).all(|c| c[1] > c[0]), "{counts:?}");
    }

    /// Issue 32, point 3: OK/NG counts of each judgement since start, reset through the
    /// library's handle (the statistics start again with them).
    #[tokio::test]
    async fn judgement_counts_are_kept_and_reset_through_the_handle() {
        let bus = Bus::new(super::parse(&gap_file()).unwrap());
        let mut events = bus.subscribe();
        let running = bus.start().expect("starts");
        let handle = running.handle();
        assert_eq!(handle.measurements(), [("gap", "mm")]);
        let mut judged = 0;
        while judged < 5 {
            if measurement(&mut events).await.judgement.is_some() {
                judged += 1;
            }
        }
        // Values may have come since the last one read here: at least those five.
        let counts = handle.judgement_counts("gap").expect("gap has limits");
        assert!(counts.iter().sum::<u64>() >= 5, "{counts:?}");
        assert_eq!(handle.judgement_counts("nothing"), None);
        handle.reset_measurements();
        let after = handle.judgement_counts("gap").unwrap();
        assert!(after.iter().sum::<u64>() <= 1, "reset: {after:?}");
        // The statistics begin again: a count far below what had been gathered.
        let mut counts = Vec::new();
        for _ in 0..40 {
            counts.push(measurement(&mut events).await.stats.expect("stats").count);
        }
        assert!(
            counts.iter().any(|&count| count <= 2),
            "never restarted: {counts:?}"
        );
    }

    /// Issue 32: an offline device makes the measurement invalid with the reason, and no value
    /// made of a stale reading is ever given.
    #[tokio::test]
    async fn an_offline_head_makes_the_gap_invalid_with_the_reason() {
        let bus = Bus::new(super::parse(&gap_file()).unwrap());
        let mut events = bus.subscribe();
        let running = bus.start().expect("starts");
        measurement(&mut events)
            .await
            .value
            .clone()
            .expect("a first value");
        running.simulator("top").unwrap().set_silent(true);
        let reason = loop {
            let gap = measurement(&mut events).await;
            if let Err(reason) = &gap.value {
                break reason.clone();
            }
        };
        // Its failing polls first make the values stop, then it is offline.
        assert_eq!(reason, "top.distance_1: top is offline");
        let json = serde_json::to_value(&*measurement(&mut events).await).unwrap();
        assert!(json["value"].is_null());
        assert_eq!(json["reason"], "top.distance_1: top is offline");
        assert!(json["inputs"]["top.distance_1"].is_null());
    }

    /// `text` with a gateway on its line.
    fn gateway(text: &str) -> String {
        text.replace(
            "any_format: true }",
            "any_format: true, gateway: { listen: 127.0.0.1:0 } }",
        )
    }

    /// pymodbus reads the first block of the measurements unit `argv[3]` `argv[4]` times, decodes
    /// it with its own converters (32-bit words high word first) and prints each as a JSON line;
    /// then a read outside the map, an FC03 and a write, each answer a JSON line.
    const PYMODBUS: &str = r#"
import json, sys, time
from pymodbus.client import ModbusTcpClient

host, port, unit, reads = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
client = ModbusTcpClient(host, port=port, timeout=3, retries=0)
assert client.connect()

def call(method, *args, **kwargs):
    try:
        return method(*args, device_id=unit, **kwargs)
    except TypeError:
        return method(*args, slave=unit, **kwargs)

def number(words, kind):
    return client.convert_from_registers(words, data_type=kind, word_order="big")

types = ModbusTcpClient.DATATYPE
for _ in range(reads):
    reply = call(client.read_input_registers, 0, count=20)
    assert not reply.isError(), reply
    r = reply.registers
    print(json.dumps({
        "value": number(r[0:2], types.INT32),
        "exponent": number(r[2:3], types.INT16),
        "status": r[3],
        "judgement": r[4],
        "counts": [number(r[5 + 2 * i:7 + 2 * i], types.UINT32) for i in range(5)],
        "skew_us": number(r[15:17], types.UINT32),
    }))
    sys.stdout.flush()
    time.sleep(0.02)

for method, address, data in [
    (client.read_input_registers, 20, {"count": 1}),
    (client.read_holding_registers, 0, {"count": 1}),
]:
    reply = call(method, address, **data)
    print(json.dumps({"exception": getattr(reply, "exception_code", None)}))
reply = call(client.write_register, 0, 1)
print(json.dumps({"exception": getattr(reply, "exception_code", None)}))
client.close()
"#;

    /// The judgement codes of the map: 0 none, then lowest first.
    const JUDGEMENTS: [Option<&str>; 6] = [
        None,
        Some("ll"),
        Some("lo"),
        Some("go"),
        Some("hi"),
        Some("hh"),
    ];

    /// A block as pymodbus decoded it, in the JSON's terms: value, judgement, counts by name,
    /// skew.
    fn as_json(read: &Value) -> (Value, Value, Value, Value) {
        let exponent = i8::try_from(read["exponent"].as_i64().unwrap()).unwrap();
        let value = match read["status"].as_u64().unwrap() {
            0 => Value::from(
                Fixed::new(read["value"].as_i64().unwrap(), Scale::Decimal { exponent })
                    .to_string(),
            ),
            _ => Value::Null,
        };
        let judgement = JUDGEMENTS[read["judgement"].as_u64().unwrap() as usize];
        let counts: serde_json::Map<String, Value> = ["ll", "lo", "go", "hi", "hh"]
            .into_iter()
            .zip(read["counts"].as_array().unwrap())
            .map(|(name, count)| (name.to_owned(), count.clone()))
            .collect();
        (
            value,
            judgement.map_or(Value::Null, Value::from),
            Value::Object(counts),
            read["skew_us"].clone(),
        )
    }

    #[tokio::test]
    #[cfg_attr(
        not(peer_pymodbus),
        ignore = "pymodbus is not installed (pip install pymodbus, or Debian package python3-pymodbus)"
    )]
    async fn a_pymodbus_read_of_the_virtual_unit_equals_the_json() {
        let bus = Bus::new(super::parse(&gateway(&gap_file())).unwrap());
        let mut events = bus.subscribe();
        let running = bus.start().expect("starts");
        let address = running.gateway_address("rs485").unwrap();
        let mut measurements: Vec<Value> = Vec::new();
        // Until a first judged value, so that every read below has counts to compare.
        while measurements.last().is_none_or(|m| m["judgement"].is_null()) {
            match tokio::time::timeout(Duration::from_secs(10), events.recv()).await {
                Ok(Ok(Event::Measurement(m))) => {
                    measurements.push(serde_json::to_value(&*m).unwrap())
                }
                Ok(_) => {}
                Err(_) => panic!("no judged value within 10 s"),
            }
        }
        let reads = 20;
        let client = tokio::task::spawn_blocking(move || {
            Command::new("python3")
                .args(["-c", PYMODBUS, &address.ip().to_string()])
                .args([address.port().to_string(), "255".into(), reads.to_string()])
                .output()
                .expect("python3 runs")
        });
        tokio::pin!(client);
        // Every measurement while pymodbus reads: the value of each read is one of them.
        let output = loop {
            tokio::select! {
                output = &mut client => break output.unwrap(),
                event = events.recv() => {
                    if let Ok(Event::Measurement(m)) = event {
                        measurements.push(serde_json::to_value(&*m).unwrap());
                    }
                }
            }
        };
        loop {
            match events.try_recv() {
                Ok(Event::Measurement(m)) => measurements.push(serde_json::to_value(&*m).unwrap()),
                Ok(_) | Err(TryRecvError::Lagged(_)) => {}
                Err(_) => break,
            }
        }
        let stdout = String::from_utf8_lossy(&output.stdout);
        assert!(
            output.status.success(),
            "pymodbus: {stdout}{}",
            String::from_utf8_lossy(&output.stderr)
        );
        let lines: Vec<Value> = stdout
            .lines()
            .map(|line| serde_json::from_str(line).unwrap())
            .collect();
        assert_eq!(lines.len(), reads + 3, "{stdout}");
        let (blocks, exceptions) = lines.split_at(reads);
        let mut valid = 0;
        for read in blocks {
            // Like with like: the value whose counts the read carries (each judged value adds
            // one), and of those the one with the read's value, judgement and skew.
            let (value, judgement, counts, skew_us) = as_json(read);
            let same = measurements.iter().any(|m| {
                m["value"]["value"] == value
                    && m["judgement"] == judgement
                    && m["counts"] == counts
                    && m["skew_us"] == skew_us
            });
            assert!(
                same,
                "no measurement has {read} ({value}, {judgement}, {counts}): {measurements:#?}"
            );
            if !value.is_null() {
                valid += 1;
            }
        }
        assert!(valid > 0, "no valid value read: {blocks:?}");
        // Outside the map: 02; input registers only: FC03 01; never written: 01.
        let codes: Vec<&Value> = exceptions.iter().map(|e| &e["exception"]).collect();
        assert_eq!(codes, [&Value::from(2), &Value::from(1), &Value::from(1)]);
        let counts = running.gateway_counts("rs485").unwrap();
        assert_eq!(counts.measurements, reads as u64 + 3);
        assert_eq!(counts.requests, 0, "nothing reached the line");
    }

    #[test]
    fn a_measurements_unit_of_a_device_is_refused_where_it_is_given() {
        let clash =
            gateway(&gap_file()).replace("127.0.0.1:0 }", "127.0.0.1:0, measurements_unit: 2 }");
        let rendered = super::parse(&clash).expect_err("unit 2 is bottom's");
        assert!(
            rendered.contains(
                "the gateway of line `rs485` answers unit 2 with the measurements, but device `bottom` is slave 2"
            ),
            "{rendered}"
        );
        assert!(rendered.contains("bus.yaml:3:"), "{rendered}");
        // By default 255, which no device can have; any other free unit id may be given.
        let file = super::parse(&gateway(&gap_file())).unwrap();
        let config = file.lines[0].gateway.as_ref().unwrap();
        assert_eq!(config.measurements_unit, 255);
        let free =
            gateway(&gap_file()).replace("127.0.0.1:0 }", "127.0.0.1:0, measurements_unit: 100 }");
        let config = super::parse(&free).unwrap().lines[0]
            .gateway
            .clone()
            .unwrap();
        assert_eq!(config.measurements_unit, 100);
    }
}
