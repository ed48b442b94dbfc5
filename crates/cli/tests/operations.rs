//! What `optobus run` tells its operator on stderr: each change of state once (a line that
//! cannot be opened, a broker that cannot be reached and then is, a device offline and online
//! again), never each retry, and the audit trail of every write from the network; under
//! systemd in the form journald keeps (a syslog priority first).

mod common;

use common::{free_port, mosquitto, post, Killed};

use std::io::{BufRead, BufReader, Read, Write};
use std::process::Stdio;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// `optobus simulate --tcp address` (a P series at slave 1) until dropped.
fn simulator(address: &str) -> Killed {
    let mut child = common::optobus()
        .args(["simulate", "--tcp", address, "--duration", "120s"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("optobus simulate starts");
    common::serves_at(&mut child);
    Killed(child)
}

/// Lines heard on stderr, as they come.
type Heard = Arc<Mutex<Vec<String>>>;

/// Waits (up to 30 s) for a line that starts with `start` and contains `part`; gives it.
fn wait_for(heard: &Heard, start: &str, part: &str) -> String {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let found = heard
            .lock()
            .unwrap()
            .iter()
            .find(|line| line.starts_with(start) && line.contains(part))
            .cloned();
        if let Some(line) = found {
            return line;
        }
        assert!(
            Instant::now() < deadline,
            "no `{start}…{part}` on stderr: {:#?}",
            heard.lock().unwrap()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn count(heard: &Heard, part: &str) -> usize {
    heard
        .lock()
        .unwrap()
        .iter()
        .filter(|line| line.contains(part))
        .count()
}

/// FC06 through the gateway at `address`: the reply PDU.
fn gateway_write(address: &str, unit: u8, register: u16, value: u16) -> Vec<u8> {
    let mut stream = std::net::TcpStream::connect(address).expect("the gateway listens");
    let [r_high, r_low] = register.to_be_bytes();
    let [v_high, v_low] = value.to_be_bytes();
    stream
        .write_all(&[0, 1, 0, 0, 0, 6, unit, 0x06, r_high, r_low, v_high, v_low])
        .unwrap();
    let mut header = [0u8; 7];
    stream.read_exact(&mut header).unwrap();
    let mut pdu = vec![0u8; usize::from(header[5]) - 1];
    stream.read_exact(&mut pdu).unwrap();
    pdu
}

#[test]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
fn operations_are_told_once_per_change_and_network_writes_are_audited() {
    let dir = std::env::temp_dir().join(format!("optobus-operations-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let (broker_port, http_port) = (free_port(), free_port());
    let device_address = format!("127.0.0.1:{}", free_port());
    let device = simulator(&device_address);
    let bus = dir.join("bus.yaml");
    std::fs::write(
        &bus,
        format!(
            "
lines:
  - {{ name: plc, tcp: '{device_address}' }}
  - {{ name: usb, serial: /dev/ttyOPTOBUS-NONE, baud: 9600 }}
  - {{ name: sim, simulated: true, baud: 115200, any_format: true, gateway: {{ listen: 127.0.0.1:0, writes: true }} }}
devices:
  - {{ name: top, line: plc, model: p-series, slave: 1, timeout: 100ms, poll: [{{ read: distance_1, every: 100ms }}], writable: [light_power] }}
  - {{ name: gone, line: usb, model: p-series, slave: 3, poll: [{{ read: distance_1, every: 100ms }}] }}
  - {{ name: side, line: sim, model: p-series, slave: 2, poll: [{{ read: distance_1, every: 100ms }}], writable: [light_power] }}
outputs:
  mqtt: {{ broker: '127.0.0.1:{broker_port}', prefix: plant }}
  http: '127.0.0.1:{http_port}'
"
        ),
    )
    .unwrap();
    let mut run = common::optobus()
        .args(["run", bus.to_str().unwrap(), "--duration", "120s", "--json"])
        // As systemd starts a service whose stderr goes to the journal.
        .env("JOURNAL_STREAM", "8:12345")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("optobus run starts");
    let heard: Heard = Arc::default();
    let stderr = BufReader::new(run.stderr.take().unwrap());
    let into = Arc::clone(&heard);
    std::thread::spawn(move || {
        for line in stderr.lines().map_while(Result::ok) {
            into.lock().unwrap().push(line);
        }
    });
    let run = Killed(run);

    // A port that is not there: said once, a warning (<4>), though the line keeps retrying.
    wait_for(&heard, "<4>optobus: ", "line `usb` cannot be opened");
    wait_for(&heard, "<6>optobus: ", "line `sim` is open");
    wait_for(
        &heard,
        "<4>optobus: ",
        &format!("MQTT: the broker at 127.0.0.1:{broker_port} cannot be reached"),
    );

    // The audit trail: who asked what, done or why not.
    let console = format!("127.0.0.1:{http_port}");
    let set = |register: &str, value: &str| {
        post(
            &console,
            "/api/devices/top/set",
            &format!(r#"{{"register": "{register}", "value": "{value}"}}"#),
        )
        .0
    };
    assert_eq!(set("light_power", "55 %"), 200);
    let done = wait_for(
        &heard,
        "<6>optobus: console 127.0.0.1:",
        "set `light_power` of `top` to \"55 %\"",
    );
    assert!(done.ends_with(": done, reads back 55.0 %"), "{done}");
    assert_eq!(set("laser_enabled", "false"), 403);
    let refused = wait_for(
        &heard,
        "<4>optobus: console 127.0.0.1:",
        "set `laser_enabled` of `top`",
    );
    assert!(
        refused.contains("not done: `laser_enabled` of `top` is not writable here"),
        "{refused}"
    );
    // A request for another Host (DNS rebinding) is refused, and told.
    let mut stream = std::net::TcpStream::connect(&console).unwrap();
    write!(
        stream,
        "POST /api/devices/top/set HTTP/1.1\r\nHost: evil.example\r\nContent-Length: 0\r\n\
         Connection: close\r\n\r\n"
    )
    .unwrap();
    let mut reply = String::new();
    stream.read_to_string(&mut reply).unwrap();
    assert!(reply.starts_with("HTTP/1.1 421"), "{reply}");
    wait_for(
        &heard,
        "<4>optobus: console 127.0.0.1:",
        "POST /api/devices/top/set: refused, 421: the console does not answer requests for `evil.example`",
    );
    let gateway_line = wait_for(&heard, "optobus: gateway of sim on ", "");
    let gateway = gateway_line
        .trim_start_matches("optobus: gateway of sim on ")
        .split([',', ' '])
        .next()
        .unwrap()
        .to_owned();
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    let slave_address = optobus_p_series::DEVICE.register("slave_address").unwrap();
    assert_eq!(
        gateway_write(&gateway, 2, power.address, 600),
        [0x06, 0, power.address as u8, 0x02, 0x58]
    );
    wait_for(
        &heard,
        "<6>optobus: gateway 127.0.0.1:",
        &format!("FC06 to slave 2 at {}: [600]: done", power.address),
    );
    assert_eq!(
        gateway_write(&gateway, 2, slave_address.address, 31),
        [0x86, 0x01]
    );
    let refused = wait_for(
        &heard,
        "<4>optobus: gateway 127.0.0.1:",
        "[31]: not done, exception 01",
    );
    assert!(
        refused.contains("`slave_address` is never written on a bus"),
        "{refused}"
    );

    // A device that stops answering, and answers again.
    drop(device);
    wait_for(&heard, "<4>optobus: ", "device `top` (slave 1) is offline");
    let device = simulator(&device_address);
    wait_for(&heard, "<6>optobus: ", "device `top` (slave 1) is online");

    // The broker comes: connected again, said once.
    let broker = mosquitto(&dir, broker_port);
    wait_for(
        &heard,
        "<6>optobus: ",
        &format!("MQTT: connected to the broker at 127.0.0.1:{broker_port} again"),
    );
    // Every retry of the port and of the broker went by without a word.
    assert_eq!(count(&heard, "line `usb` cannot be opened"), 1);
    assert_eq!(count(&heard, "cannot be reached"), 1);
    drop((run, broker, device));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
fn a_clean_stop_tells_of_no_lost_broker() {
    // Found in the README walk: every stop of a run with MQTT ended in "the broker … cannot be
    // reached", a warning in the journal at each restart of the service.
    let dir = std::env::temp_dir().join(format!("optobus-clean-stop-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let broker_port = free_port();
    let _broker = mosquitto(&dir, broker_port);
    std::thread::sleep(Duration::from_millis(300));
    let bus = dir.join("bus.yaml");
    std::fs::write(
        &bus,
        format!(
            "
lines: [{{ name: sim, simulated: true, baud: 115200, any_format: true }}]
devices: [{{ name: top, model: p-series, slave: 1, poll: [{{ read: distance_1, every: 100ms }}] }}]
outputs: {{ mqtt: {{ broker: '127.0.0.1:{broker_port}', prefix: plant }} }}
"
        ),
    )
    .unwrap();
    let output = common::optobus()
        .args(["run", bus.to_str().unwrap(), "--duration", "2s", "--json"])
        .output()
        .expect("optobus run");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "MQTT: connected to the broker at 127.0.0.1:{broker_port}"
        )),
        "{stderr}"
    );
    assert!(!stderr.contains("cannot be reached"), "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}
