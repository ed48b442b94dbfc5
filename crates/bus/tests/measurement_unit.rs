//! Issue 32, point 5: the bus file's measurements as input registers of the gateway's
//! measurements unit, read by a real Modbus TCP client (pymodbus), equal to the measurements'
//! JSON; the unit id checked against the devices' when the file is read.

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use optobus_bus::{Bus, BusFile, Catalogue, Event};
use optobus_codec::value::{Fixed, Scale};
use serde_json::Value;
use tokio::sync::broadcast::error::TryRecvError;

fn parse(text: &str) -> Result<BusFile, String> {
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
    BusFile::parse("bus.yaml", text, Path::new("."), &catalogue).map_err(|e| e.render())
}

const GAP: &str = "
lines:
  - name: rs485
    simulated: true
    baud: 115200
    any_format: true
    gateway: { listen: 127.0.0.1:0 }
devices:
  - { name: top, model: p-series, slave: 1, timeout: 100ms, poll: [{ read: distance_1, every: 20ms }] }
  - { name: bottom, model: p-series, slave: 2, timeout: 100ms, poll: [{ read: distance_1, every: 20ms }] }
measurements:
  - name: gap
    expr: 20mm - top.distance_1 - bottom.distance_1
    unit: mm
    limits: { lo: 9.9mm, hi: 10.1mm }
    max_skew: 1s           # how close the inputs are is a bench's matter, not a test's
";

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
            Fixed::new(read["value"].as_i64().unwrap(), Scale::Decimal { exponent }).to_string(),
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
    let bus = Bus::new(parse(GAP).unwrap());
    let mut events = bus.subscribe();
    let running = bus.start().expect("starts");
    let address = running.gateway_address("rs485").unwrap();
    let mut measurements: Vec<Value> = Vec::new();
    // Until a first judged value, so that every read below has counts to compare.
    while measurements.last().is_none_or(|m| m["judgement"].is_null()) {
        match tokio::time::timeout(Duration::from_secs(10), events.recv()).await {
            Ok(Ok(Event::Measurement(m))) => measurements.push(serde_json::to_value(&*m).unwrap()),
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
    let clash = GAP.replace(
        "listen: 127.0.0.1:0",
        "listen: 127.0.0.1:0, measurements_unit: 2",
    );
    let rendered = parse(&clash).expect_err("unit 2 is bottom's");
    assert!(
        rendered.contains(
            "the gateway of line `rs485` answers unit 2 with the measurements, but device `bottom` is slave 2"
        ),
        "{rendered}"
    );
    assert!(rendered.contains("bus.yaml:7:"), "{rendered}");
    // By default 255, which no device can have; any other free unit id may be given.
    let file = parse(GAP).unwrap();
    let gateway = file.lines[0].gateway.as_ref().unwrap();
    assert_eq!(gateway.measurements_unit, 255);
    let free = GAP.replace(
        "listen: 127.0.0.1:0",
        "listen: 127.0.0.1:0, measurements_unit: 100",
    );
    let gateway = parse(&free).unwrap().lines[0].gateway.clone().unwrap();
    assert_eq!(gateway.measurements_unit, 100);
}
