//! `optobus run`'s own consumers of the bus (stdout, `--record`, its notes on stderr) follow it
//! without ever holding up the runtime: a stdout nobody reads costs its own oldest lines, and
//! the gateway, /metrics, the console and the schedule go on.

mod common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, ChildStderr, ChildStdout, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// Generous: the machine may be busy.
const PATIENCE: Duration = Duration::from_secs(60);

/// What a test waits for and every read it makes gets at most this long.
const REPLY_WITHIN: Duration = Duration::from_secs(5);

/// `optobus run --demo --gateway 127.0.0.1:0 args…` with stdout and stderr pipes; killed when
/// dropped.
struct Demo {
    child: Child,
    /// stderr's lines as they come, read by a thread of the test.
    stderr: mpsc::Receiver<String>,
}

impl Demo {
    fn start(args: &[&str]) -> Self {
        let mut child = common::optobus()
            .args(["run", "--demo", "--gateway", "127.0.0.1:0"])
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("run the demo");
        let stderr = lines_of(child.stderr.take().expect("stderr"));
        Self { child, stderr }
    }

    /// The next stderr line that contains `text`, waiting at most `within`.
    fn said(&self, text: &str, within: Duration) -> Result<String, String> {
        let deadline = Instant::now() + within;
        let mut heard = Vec::new();
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.stderr.recv_timeout(left) {
                Ok(line) if line.contains(text) => return Ok(line),
                Ok(line) => heard.push(line),
                Err(_) => return Err(heard.join("\n")),
            }
        }
    }

    /// The addresses named on the first line of stderr: the gateway's and, with
    /// `--prometheus`, the metrics'.
    fn addresses(&self) -> (String, Option<String>) {
        let line = self
            .said("gateway of rs485 on ", PATIENCE)
            .unwrap_or_else(|heard| panic!("no gateway address on stderr: {heard}"));
        let gateway = line
            .split("gateway of rs485 on ")
            .nth(1)
            .and_then(|rest| rest.split([',', ' ']).next())
            .expect("an address")
            .to_owned();
        let metrics = line
            .split("http://")
            .nth(1)
            .and_then(|rest| rest.split('/').next())
            .map(str::to_owned);
        (gateway, metrics)
    }

    fn stdout(&mut self) -> ChildStdout {
        self.child.stdout.take().expect("stdout")
    }
}

impl Drop for Demo {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The lines of `stderr`, sent as they come by a thread of their own.
fn lines_of(stderr: ChildStderr) -> mpsc::Receiver<String> {
    let (sender, receiver) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines() {
            let Ok(line) = line else { return };
            if sender.send(line).is_err() {
                return;
            }
        }
    });
    receiver
}

/// Bytes waiting in the pipe of `stdout` (FIONREAD).
fn waiting_in(stdout: &ChildStdout) -> u64 {
    rustix::io::ioctl_fionread(stdout).expect("FIONREAD on the stdout pipe")
}

/// A Modbus TCP read of holding registers 0..7 of slave 1 (the demo's P series) on
/// `stream`: the reply's bytes after its transaction id, or why there are none.
fn read_settings(stream: &mut TcpStream, transaction: u16) -> Result<Vec<u8>, String> {
    let [hi, lo] = transaction.to_be_bytes();
    stream
        .write_all(&[hi, lo, 0, 0, 0, 6, 1, 0x03, 0, 0, 0, 7])
        .map_err(|e| format!("send: {e}"))?;
    let mut reply = [0u8; 9 + 14];
    stream
        .read_exact(&mut reply)
        .map_err(|e| format!("no reply within {REPLY_WITHIN:?}: {e}"))?;
    if reply[..2] != [hi, lo] {
        return Err(format!("the reply of another transaction: {reply:02X?}"));
    }
    Ok(reply[2..].to_vec())
}

/// A GET of `path` at `address`: the whole reply.
fn get(address: &str, path: &str) -> Result<String, String> {
    let mut stream = TcpStream::connect(address).map_err(|e| format!("connect: {e}"))?;
    stream.set_read_timeout(Some(REPLY_WITHIN)).unwrap();
    write!(
        stream,
        "GET {path} HTTP/1.1\r\nHost: {address}\r\nConnection: close\r\n\r\n"
    )
    .map_err(|e| format!("send: {e}"))?;
    let mut reply = String::new();
    stream
        .read_to_string(&mut reply)
        .map_err(|e| format!("no reply within {REPLY_WITHIN:?}: {e}"))?;
    Ok(reply)
}

#[test]
fn a_stalled_stdout_freezes_nothing() {
    let mut demo = Demo::start(&[
        "--prometheus",
        "127.0.0.1:0",
        "--http",
        "127.0.0.1:0",
        "--json",
        "--duration",
        "120s",
    ]);
    let (gateway, metrics) = demo.addresses();
    let metrics = metrics.expect("the metrics address on stderr");
    let console = demo
        .said("optobus: the console is on http://", PATIENCE)
        .unwrap_or_else(|heard| panic!("no console address on stderr: {heard}"));
    let console = console
        .split("http://")
        .nth(1)
        .and_then(|rest| rest.split('/').next())
        .expect("an address")
        .to_owned();
    // The P series' settings, as the gateway reads them before stdout is full: well formed,
    // light power (holding 2) in its range 5 ..= 1000.
    let mut client = TcpStream::connect(&gateway).expect("the gateway listens");
    client.set_read_timeout(Some(REPLY_WITHIN)).unwrap();
    let before = read_settings(&mut client, 1).expect("the gateway answers");
    assert_eq!(before[..7], [0, 0, 0, 17, 1, 0x03, 14], "{before:02X?}");
    let light_power = u16::from_be_bytes([before[11], before[12]]);
    assert!((5..=1000).contains(&light_power), "{before:02X?}");
    // Stdout is never read: wait until its pipe (64 KiB) is full.
    let mut stdout = demo.stdout();
    let started = Instant::now();
    while waiting_in(&stdout) < 60 * 1024 {
        assert!(
            started.elapsed() < PATIENCE,
            "stdout's pipe never filled: {} bytes",
            waiting_in(&stdout)
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    // Every read through the gateway is still answered, with the same values.
    for transaction in 2..=101 {
        let after = read_settings(&mut client, transaction).unwrap_or_else(|why| {
            panic!("read {transaction} through the gateway while stdout is full: {why}")
        });
        assert_eq!(after, before, "read {transaction} while stdout is full");
    }
    // A new client too.
    let mut another = TcpStream::connect(&gateway).expect("the gateway still listens");
    another.set_read_timeout(Some(REPLY_WITHIN)).unwrap();
    let reply = read_settings(&mut another, 7)
        .unwrap_or_else(|why| panic!("a new client of the gateway while stdout is full: {why}"));
    assert_eq!(reply, before);
    // /metrics answers, and the line goes on: its transactions counter moves on.
    // (The line's statistics come once a second: the pipe may be full before the first.)
    let transactions = |reply: &str| -> Option<f64> {
        reply
            .lines()
            .find(|l| l.starts_with("optobus_line_transactions"))
            .and_then(|l| l.rsplit(' ').next())
            .and_then(|n| n.parse().ok())
    };
    let scraped = get(&metrics, "/metrics")
        .unwrap_or_else(|why| panic!("/metrics while stdout is full: {why}"));
    assert!(scraped.starts_with("HTTP/1.1 200"), "{scraped}");
    assert!(
        scraped.contains("optobus_device_up{device=\"head\","),
        "{scraped}"
    );
    let first = transactions(&scraped);
    let started = Instant::now();
    loop {
        let now = get(&metrics, "/metrics")
            .unwrap_or_else(|why| panic!("/metrics while stdout is full: {why}"));
        if transactions(&now).is_some_and(|now| Some(now) > first) {
            break;
        }
        assert!(
            started.elapsed() < PATIENCE,
            "the line's transactions stayed at {first:?} while stdout was full"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    // So does the console.
    let status = get(&console, "/api/status")
        .unwrap_or_else(|why| panic!("/api/status while stdout is full: {why}"));
    assert!(status.starts_with("HTTP/1.1 200"), "{status}");
    // The run says, once, that stdout is dropping its oldest lines.
    demo.said(
        "optobus: stdout is not being read: dropping its oldest lines",
        PATIENCE,
    )
    .unwrap_or_else(|heard| panic!("stderr never said stdout drops lines; it said:\n{heard}"));
    // And the pipe still holds what was written first: JSON lines, whole.
    let mut held = vec![0u8; 4096];
    let count = stdout.read(&mut held).expect("read the pipe");
    let text = String::from_utf8_lossy(&held[..count]);
    let first = text.lines().next().expect("a line");
    let sample: serde_json::Value = serde_json::from_str(first).expect("a JSON line");
    assert!(sample.get("device").is_some(), "{first}");
}

/// The values of a CSV's last row, by register name (the header without its unit); empty
/// cells left out.
fn last_row(csv: &str) -> Vec<(String, String)> {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("a header").split(',').collect();
    let row: Vec<&str> = lines.last().expect("a row").split(',').collect();
    header
        .iter()
        .zip(&row)
        .skip(2)
        .filter(|(_, cell)| !cell.is_empty())
        .map(|(name, cell)| {
            let name = name.split(" [").next().unwrap_or(name);
            (name.to_owned(), (*cell).to_owned())
        })
        .collect()
}

#[test]
fn with_duration_the_last_polls_samples_reach_json() {
    let dir = std::env::temp_dir().join(format!("optobus-last-poll-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut demo = Demo::start(&[
        "--json",
        "--record",
        dir.to_str().unwrap(),
        "--duration",
        "6s",
    ]);
    let (gateway, _) = demo.addresses();
    let stdout = demo.stdout();
    // Stdout is not read until the run has stopped (its gateway closed).
    let started = Instant::now();
    while TcpStream::connect(&gateway).is_ok() {
        assert!(started.elapsed() < PATIENCE, "the run never stopped");
        std::thread::sleep(Duration::from_millis(20));
    }
    let samples: Vec<serde_json::Value> = BufReader::new(stdout)
        .lines()
        .map(|line| serde_json::from_str(&line.expect("a line")).expect("a JSON line"))
        .collect();
    let status = demo.child.wait().expect("the run ends");
    let said: Vec<String> = demo.stderr.try_iter().collect();
    assert!(status.success(), "{status}: {said:#?}");
    // The recording (a file, never stalled) saw the bus poll until the stop: its last row
    // of the head (polled every 100 ms) is from the run's last seconds.
    let head = std::fs::read_to_string(dir.join("head.csv")).expect("head.csv");
    let elapsed: f64 = head
        .lines()
        .last()
        .and_then(|row| row.split(',').nth(1))
        .and_then(|cell| cell.parse().ok())
        .expect("an elapsed time in the last row");
    assert!(
        elapsed > 4.0,
        "the bus stopped polling {elapsed} s into a 6 s run: {head}"
    );
    // Each device's last poll, as the recording has it, is on stdout: the last value
    // stdout carries of each of its registers is the one in the CSV's last row.
    for device in ["head", "confocal", "four-channel", "distance"] {
        let csv = std::fs::read_to_string(dir.join(format!("{device}.csv"))).expect("a CSV");
        for (register, cell) in last_row(&csv) {
            let last = samples
                .iter()
                .rev()
                .find(|s| s["device"] == device && s["register"] == register.as_str())
                .unwrap_or_else(|| panic!("no {device} {register} on stdout"));
            let value = match &last["value"] {
                // An invalid reading: `null` in JSON, `NaN` in the recording.
                serde_json::Value::Null => "NaN".to_owned(),
                serde_json::Value::Object(quantity) => quantity["value"]
                    .as_str()
                    .expect("a quantity's number")
                    .to_owned(),
                other => other.to_string(),
            };
            assert_eq!(
                value, cell,
                "{device} {register}: stdout's last {last} against the CSV's last row"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
