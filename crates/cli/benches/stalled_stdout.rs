//! `optobus run --demo --json` with its stdout never read, against the same run with stdout
//! drained (the anchor), trials interleaved: the share of 800 Modbus TCP reads through the
//! gateway answered with the right bytes, their rate against the anchor's, and whether
//! /metrics answers. `cargo bench -p optobus-cli --bench stalled_stdout`
//! (`OPTOBUS_BENCH_TRIALS`, default 3).

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Reads per trial, as the issue counted them with pymodbus.
const READS: u16 = 800;

/// A read unanswered this long counts as lost.
const REPLY_WITHIN: Duration = Duration::from_secs(1);

/// No trial waits longer than this for its reads (a frozen gateway costs a timeout each).
const TRIAL_BUDGET: Duration = Duration::from_secs(60);

struct Trial {
    answered: u16,
    asked: u16,
    took: Duration,
    metrics: bool,
}

/// The addresses on the first line of stderr: the gateway's and the metrics'.
fn addresses(child: &mut Child) -> (String, String) {
    let mut stderr = BufReader::new(child.stderr.take().expect("stderr"));
    let mut line = String::new();
    stderr.read_line(&mut line).expect("a first line");
    // The rest of stderr is drained: only stdout is the stalled reader here.
    std::thread::spawn(move || std::io::copy(&mut stderr, &mut std::io::sink()));
    let gateway = line
        .split("gateway of rs485 on ")
        .nth(1)
        .and_then(|rest| rest.split([',', ' ']).next())
        .expect("the gateway's address")
        .to_owned();
    let metrics = line
        .split("http://")
        .nth(1)
        .and_then(|rest| rest.split('/').next())
        .expect("the metrics' address")
        .to_owned();
    (gateway, metrics)
}

fn metrics_answer(address: &str) -> bool {
    let Ok(mut stream) = TcpStream::connect(address) else {
        return false;
    };
    let _ = stream.set_read_timeout(Some(Duration::from_secs(5)));
    let request = format!("GET /metrics HTTP/1.1\r\nHost: {address}\r\nConnection: close\r\n\r\n");
    let mut reply = String::new();
    stream.write_all(request.as_bytes()).is_ok()
        && stream.read_to_string(&mut reply).is_ok()
        && reply.starts_with("HTTP/1.1 200")
}

fn trial(stdout_read: bool) -> Trial {
    let mut child = Command::new(env!("CARGO_BIN_EXE_optobus"))
        .args(["run", "--demo", "--json", "--gateway", "127.0.0.1:0"])
        .args(["--prometheus", "127.0.0.1:0", "--duration", "300s"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run the demo");
    let (gateway, metrics) = addresses(&mut child);
    let stdout = child.stdout.take().expect("stdout");
    let reader = stdout_read.then(|| {
        std::thread::spawn(move || {
            let mut stdout = stdout;
            std::io::copy(&mut stdout, &mut std::io::sink())
        })
    });
    // Long enough for a never-read pipe (64 KiB) to fill several times over.
    std::thread::sleep(Duration::from_secs(3));
    let mut client = TcpStream::connect(&gateway).expect("the gateway listens");
    client.set_read_timeout(Some(REPLY_WITHIN)).unwrap();
    let _ = client.set_nodelay(true);
    // The P series' settings (holding 0..7 of slave 1), as the demo starts them.
    let expected = [0, 0, 0, 0, 0, 5, 0, 0, 0, 0, 0, 0, 0, 8];
    let (mut answered, mut asked) = (0, 0);
    let started = Instant::now();
    for transaction in 1..=READS {
        if started.elapsed() > TRIAL_BUDGET {
            break;
        }
        asked += 1;
        let [hi, lo] = transaction.to_be_bytes();
        if client
            .write_all(&[hi, lo, 0, 0, 0, 6, 1, 0x03, 0, 0, 0, 7])
            .is_err()
        {
            continue;
        }
        let mut reply = [0u8; 9 + 14];
        if client.read_exact(&mut reply).is_ok()
            && reply[..9] == [hi, lo, 0, 0, 0, 17, 1, 0x03, 14]
            && reply[9..] == expected
        {
            answered += 1;
        }
    }
    let took = started.elapsed();
    let metrics = metrics_answer(&metrics);
    let _ = child.kill();
    let _ = child.wait();
    if let Some(reader) = reader {
        let _ = reader.join();
    }
    Trial {
        answered,
        asked,
        took,
        metrics,
    }
}

fn main() {
    let trials: usize = std::env::var("OPTOBUS_BENCH_TRIALS")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(3);
    println!("optobus run --demo --json: {READS} gateway reads per trial, stdout drained (anchor) or never read");
    for number in 1..=trials {
        let anchor = trial(true);
        let stalled = trial(false);
        let rate = |t: &Trial| f64::from(t.answered) / t.took.as_secs_f64();
        for (name, t) in [("drained", &anchor), ("never read", &stalled)] {
            println!(
                "trial {number}, stdout {name:>10}: {} of {} reads answered right (share {:.3} of {READS}), {:.0} reads/s, {:.2} × the anchor's rate, /metrics {}",
                t.answered,
                t.asked,
                f64::from(t.answered) / f64::from(READS),
                rate(t),
                rate(t) / rate(&anchor),
                if t.metrics { "answers" } else { "does not answer" },
            );
        }
    }
}
