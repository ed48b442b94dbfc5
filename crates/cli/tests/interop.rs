//! Independent Modbus tools against `optobus simulate`: mbpoll (libmodbus) over TCP and over a
//! socat pty pair reads the values optobus wrote, and optobus reads what mbpoll wrote.
//!
//! `.ci/run` installs mbpoll and socat and sets `OPTOBUS_REQUIRE_INTEROP=1`, so there a missing
//! tool fails the build; elsewhere the tests are listed as ignored, with the reason.

mod common;

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::{json, mbpoll, ok, Served};

/// `mbpoll` with the connection options, `options`, the target and values to write.
fn mbpoll_at(connection: &[&str], target: &str, options: &[&str], values: &[&str]) -> Vec<i64> {
    let mut args = connection.to_vec();
    args.extend(options);
    args.push(target);
    args.extend(values);
    mbpoll(&args)
}

/// Light power 42.5 % written by optobus is holding register 2 = 425 for mbpoll; mbpoll
/// writes 300 and optobus reads 30.0 %; both read the factory IP address (input 150-153).
fn exchange(optobus: &[&str], connection: &[&str], target: &str) {
    let with = |more: &[&str]| -> Vec<String> {
        more.iter()
            .chain(optobus)
            .chain(&["--model", "p-series"])
            .map(|s| (*s).to_owned())
            .collect()
    };
    let args = with(&["set", "light_power", "42.5"]);
    ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    // -0: PDU addresses; -t 4: holding; -t 3: input; -1: poll once.
    let light_power = ["-0", "-r", "2", "-c", "1", "-t", "4", "-1"];
    assert_eq!(mbpoll_at(connection, target, &light_power, &[]), [425]);
    mbpoll_at(connection, target, &["-0", "-r", "2", "-t", "4"], &["300"]);
    let args = with(&["read", "light_power"]);
    let values = json(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(values["light_power"]["value"], "30.0");
    let ip = ["-0", "-r", "150", "-c", "4", "-t", "3", "-1"];
    assert_eq!(mbpoll_at(connection, target, &ip, &[]), [192, 168, 0, 10]);
}

#[test]
#[cfg_attr(
    not(peer_mbpoll),
    ignore = "mbpoll is not installed (Debian package mbpoll)"
)]
fn mbpoll_over_tcp() {
    let served = Served::start(&["p-series", "--tcp", "127.0.0.1:0"]);
    let (host, port) = served.at.rsplit_once(':').expect("host:port");
    exchange(
        &["--tcp", &served.at],
        &["-m", "tcp", "-p", port, "-a", "1"],
        host,
    );
}

/// A socat pty pair: `optobus simulate --serial A` on one end, mbpoll on the other.
struct PtyPair {
    socat: Child,
    ends: [String; 2],
}

impl PtyPair {
    fn new() -> Self {
        let dir = std::env::temp_dir().join(format!("optobus-pty-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let ends = ["a", "b"].map(|n| dir.join(n).to_string_lossy().into_owned());
        let socat = Command::new("socat")
            .args([
                format!("pty,raw,echo=0,link={}", ends[0]),
                format!("pty,raw,echo=0,link={}", ends[1]),
            ])
            .stderr(Stdio::null())
            .spawn()
            .expect("start socat");
        let deadline = Instant::now() + Duration::from_secs(5);
        while !ends.iter().all(|e| std::path::Path::new(e).exists()) {
            assert!(Instant::now() < deadline, "socat made no ptys");
            std::thread::sleep(Duration::from_millis(20));
        }
        Self { socat, ends }
    }
}

impl Drop for PtyPair {
    fn drop(&mut self) {
        let _ = self.socat.kill();
        let _ = self.socat.wait();
    }
}

#[test]
#[cfg_attr(
    not(all(peer_mbpoll, peer_socat)),
    ignore = "mbpoll or socat is not installed (Debian packages mbpoll, socat)"
)]
fn mbpoll_over_a_socat_pty_pair() {
    let pair = PtyPair::new();
    let _served = Served::start(&["p-series", "--serial", &pair.ends[0]]);
    let rtu = ["-m", "rtu", "-b", "115200", "-P", "none", "-a", "1"];
    exchange(&["--serial", &pair.ends[1]], &rtu, &pair.ends[1]);
}
