//! The one write policy, asked through every network path of `optobus run` with real clients:
//! pymodbus through the gateway, HTTP to the console, mosquitto_pub through a real mosquitto.
//! Each kind of refusal gets the same answer on each path (exception 01/02/03, 403/422, the
//! same message on `/error` as in the console's body), and nothing refused reaches a device.

mod common;

use common::{free_port, mosquitto, Killed};

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::{json, Value};

/// pymodbus as a Modbus TCP client: each request of the JSON list in argv[3] (`[unit,
/// function, address, values or count]`) sent in turn, each answer printed as a JSON line.
const PYMODBUS: &str = r#"
import json, sys
from pymodbus.client import ModbusTcpClient

client = ModbusTcpClient(sys.argv[1], port=int(sys.argv[2]), timeout=3, retries=0)
client.connect()

def call(method, *args, unit, **kwargs):
    try:
        return method(*args, device_id=unit, **kwargs)
    except TypeError:
        return method(*args, slave=unit, **kwargs)

for unit, function, address, data in json.loads(sys.argv[3]):
    try:
        if function == 3:
            reply = call(client.read_holding_registers, address, count=data, unit=unit)
        elif function == 4:
            reply = call(client.read_input_registers, address, count=data, unit=unit)
        elif function == 6:
            reply = call(client.write_register, address, data[0], unit=unit)
        else:
            reply = call(client.write_registers, address, data, unit=unit)
        if reply.isError():
            print(json.dumps({"exception": getattr(reply, "exception_code", None)}))
        else:
            print(json.dumps({"registers": list(getattr(reply, "registers", []) or [])}))
    except Exception as error:
        print(json.dumps({"failed": type(error).__name__}))
    sys.stdout.flush()
client.close()
"#;

/// pymodbus's answers to `requests` through the gateway at `address`.
fn pymodbus(address: &str, requests: &Value) -> Vec<Value> {
    let (host, port) = address.rsplit_once(':').unwrap();
    let output = Command::new("python3")
        .args(["-c", PYMODBUS, host, port, &requests.to_string()])
        .output()
        .expect("python3 runs");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "pymodbus: {stdout}{}",
        String::from_utf8_lossy(&output.stderr)
    );
    stdout
        .lines()
        .map(|line| serde_json::from_str(line).unwrap())
        .collect()
}

/// A POST of the JSON `body` to the console at `address`: the status and the JSON reply.
fn post(address: &str, path: &str, body: &Value) -> (u16, Value) {
    let (status, reply) = common::post(address, path, &body.to_string());
    (status, serde_json::from_str(&reply).unwrap_or(Value::Null))
}

/// What `mosquitto_sub -v` heard: `topic payload` lines.
fn subscribe(port: u16, filter: &str) -> (Killed, Arc<Mutex<Vec<String>>>) {
    let mut child = Command::new("mosquitto_sub")
        .args([
            "-h",
            "127.0.0.1",
            "-p",
            &port.to_string(),
            "-v",
            "-t",
            filter,
        ])
        .stdout(Stdio::piped())
        .spawn()
        .expect("mosquitto_sub runs");
    let heard = Arc::new(Mutex::new(Vec::new()));
    let lines = BufReader::new(child.stdout.take().unwrap());
    let into = Arc::clone(&heard);
    std::thread::spawn(move || {
        for line in lines.lines().map_while(Result::ok) {
            into.lock().unwrap().push(line);
        }
    });
    (Killed(child), heard)
}

fn publish(port: u16, topic: &str, payload: &str) {
    let status = Command::new("mosquitto_pub")
        .args(["-h", "127.0.0.1", "-p", &port.to_string(), "-q", "1"])
        .args(["-t", topic, "-m", payload])
        .status()
        .expect("mosquitto_pub runs");
    assert!(status.success());
}

/// The payload of the first line heard on `topic`, waiting up to 20 s.
fn heard_on(heard: &Mutex<Vec<String>>, topic: &str) -> String {
    let deadline = Instant::now() + Duration::from_secs(20);
    let prefix = format!("{topic} ");
    loop {
        let found = heard
            .lock()
            .unwrap()
            .iter()
            .find_map(|line| line.strip_prefix(&prefix).map(str::to_owned));
        if let Some(payload) = found {
            return payload;
        }
        assert!(Instant::now() < deadline, "nothing heard on {topic}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// `optobus run --bus bus` running; its gateway's and its console's addresses.
fn run(bus: &std::path::Path) -> (Killed, String, String) {
    let mut child = common::optobus()
        .args(["run", bus.to_str().unwrap(), "--duration", "120s"])
        .args(["--json"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("optobus run starts");
    let stderr = BufReader::new(child.stderr.take().unwrap());
    let (mut gateway, mut console) = (None, None);
    let mut lines = stderr.lines().map_while(Result::ok);
    while gateway.is_none() || console.is_none() {
        let line = lines.next().expect("optobus says where it serves");
        if let Some(rest) = line.split("gateway of rs485 on ").nth(1) {
            gateway = rest.split([',', ' ']).next().map(str::to_owned);
        }
        if let Some(url) = line.strip_prefix("optobus: the console is on http://") {
            console = Some(url.trim_end_matches('/').to_owned());
        }
    }
    // Keep reading stderr so that the process never blocks on it.
    std::thread::spawn(move || lines.for_each(drop));
    (Killed(child), gateway.unwrap(), console.unwrap())
}

/// A register of the P series, by name.
fn p(name: &str) -> &'static optobus_device::RegisterInfo {
    optobus_p_series::DEVICE.register(name).unwrap()
}

#[test]
#[cfg_attr(
    not(all(peer_mosquitto, peer_mosquitto_pub, peer_pymodbus)),
    ignore = "mosquitto, mosquitto_pub or pymodbus is not installed (Debian packages mosquitto, mosquitto-clients; pip install pymodbus)"
)]
fn every_network_path_refuses_alike() {
    let dir = std::env::temp_dir().join(format!("optobus-policy-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let broker_port = free_port();
    let _broker = mosquitto(&dir, broker_port);
    let bus = dir.join("bus.yaml");
    std::fs::write(
        &bus,
        format!(
            "
lines:
  - name: rs485
    simulated: true
    baud: 115200
    any_format: true
    gateway: {{ listen: 127.0.0.1:0, writes: true }}
devices:
  - name: top
    model: p-series
    slave: 1
    poll: [{{ read: distance_1, every: 100ms }}]
    writable: [light_power, zero_position_1]
  - {{ name: confocal, model: ccs, slave: 2, poll: [{{ read: measurements, every: 100ms }}] }}
outputs:
  mqtt: {{ broker: 127.0.0.1:{broker_port}, prefix: plant }}
  http: 127.0.0.1:0
"
        ),
    )
    .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let (_subscriber, heard) = subscribe(broker_port, "plant/+/+/error");
    let (_run, gateway, console) = run(&bus);
    // The publisher subscribes to the write topics once connected.
    std::thread::sleep(Duration::from_secs(2));

    let watched = [
        "light_power",
        "laser_enabled",
        "slave_address",
        "save_parameters",
    ];
    let read_watched = || {
        let reads: Vec<Value> = watched
            .iter()
            .map(|name| json!([1, 3, p(name).address, 1]))
            .collect();
        pymodbus(&gateway, &Value::Array(reads))
    };
    let before = read_watched();
    assert!(
        before.iter().all(|r| r.get("registers").is_some()),
        "{before:?}"
    );

    // (what, the gateway's request and its exception, the console's request and status,
    // MQTT's topic and payload): the console's message and MQTT's `/error` are the same text.
    struct Case {
        what: &'static str,
        gateway: Option<(Value, u8)>,
        console: Option<(&'static str, Value, u16)>,
        mqtt: Option<(&'static str, &'static str)>,
    }
    let write = |name: &str, value: u16| json!([1, 6, p(name).address, [value]]);
    let buffer_page = p("buffer_sample_1_buffered_value").address;
    let cases = [
        Case {
            what: "a register the bus file does not list",
            gateway: Some((write("laser_enabled", 0), 0x01)),
            console: Some((
                "set",
                json!({"register": "laser_enabled", "value": "false"}),
                403,
            )),
            mqtt: Some(("plant/top/laser_enabled/set", "false")),
        },
        Case {
            what: "the slave address",
            gateway: Some((write("slave_address", 31), 0x01)),
            console: Some((
                "set",
                json!({"register": "slave_address", "value": "31"}),
                403,
            )),
            mqtt: Some(("plant/top/slave_address/set", "31")),
        },
        Case {
            what: "a drastic command not named",
            gateway: Some((write("save_parameters", 1), 0x01)),
            console: Some(("do", json!({"command": "save_parameters"}), 403)),
            mqtt: Some(("plant/top/save_parameters/do", "PRESS")),
        },
        Case {
            what: "a value the spec refuses",
            gateway: Some((write("light_power", 1001), 0x03)),
            console: Some((
                "set",
                json!({"register": "light_power", "value": "100.1"}),
                422,
            )),
            mqtt: Some(("plant/top/light_power/set", "100.1")),
        },
        Case {
            what: "a read that changes the device",
            gateway: Some((json!([1, 4, buffer_page, 2]), 0x01)),
            console: Some((
                "read",
                json!({"register": "buffer_sample_1_buffered_value"}),
                403,
            )),
            mqtt: None,
        },
        Case {
            what: "no such register",
            gateway: Some((json!([1, 6, 0x7FF0, [1]]), 0x02)),
            console: Some(("set", json!({"register": "warp", "value": "1"}), 422)),
            mqtt: Some(("plant/top/warp/set", "1")),
        },
        Case {
            what: "a broadcast a device of the line refuses",
            gateway: Some((json!([0, 6, p("light_power").address, [600]]), 0x01)),
            console: None,
            mqtt: None,
        },
        Case {
            what: "a read of the broadcast address",
            gateway: Some((json!([0, 3, p("light_power").address, 1]), 0x01)),
            console: None,
            mqtt: None,
        },
    ];
    let mut table = vec!["| refusal | gateway | console | MQTT |".to_owned()];
    for case in &cases {
        let gateway_answer = case.gateway.as_ref().map(|(request, code)| {
            let answer = pymodbus(&gateway, &json!([request]));
            assert_eq!(
                answer[0]["exception"],
                json!(code),
                "{}: pymodbus heard {answer:?}",
                case.what
            );
            format!("exception {code:02X}")
        });
        let console_answer = case.console.as_ref().map(|(action, body, status)| {
            let (got, reply) = post(&console, &format!("/api/devices/top/{action}"), body);
            assert_eq!(got, *status, "{}: {reply}", case.what);
            (got, reply["error"].as_str().unwrap_or_default().to_owned())
        });
        let mqtt_answer = case.mqtt.map(|(topic, payload)| {
            publish(broker_port, topic, payload);
            let error_topic = format!("{}/error", topic.rsplit_once('/').unwrap().0);
            heard_on(&heard, &error_topic)
        });
        if let (Some((_, console)), Some(mqtt)) = (&console_answer, &mqtt_answer) {
            assert_eq!(console, mqtt, "{}: the same message on both", case.what);
        }
        table.push(format!(
            "| {} | {} | {} | {} |",
            case.what,
            gateway_answer.unwrap_or_else(|| "—".into()),
            console_answer.map_or_else(|| "—".into(), |(status, text)| format!("{status}: {text}")),
            mqtt_answer.map_or_else(|| "—".into(), |text| format!("/error: {text}")),
        ));
    }
    println!("{}", table.join("\n"));
    assert_eq!(read_watched(), before, "nothing refused reached the head");
    let _ = std::fs::remove_dir_all(&dir);
}
