//! `optobus simulate --faults … --seed …` and `--line-timing`, checked on real bytes: raw
//! Modbus TCP and raw RTU frames on the pty the simulator serves, no optobus client between.

mod common;

use std::fs::File;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::process::{Child, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};

use optobus_codec::crc::crc16;
use optobus_codec::{rtu, Decoded, ExceptionShape, ReadFunction, Request, Response};

/// `optobus simulate p-series args…` with stdout and stderr piped; gives the child and where it
/// serves (its first line on stdout).
fn simulate(args: &[&str]) -> (Child, String) {
    let mut child = common::optobus()
        .args(["simulate", "p-series"])
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start optobus simulate");
    let at = common::serves_at(&mut child);
    (child, at)
}

/// Waits for the child to end on its own (its --duration); gives its stderr.
fn finish(mut child: Child) -> String {
    let started = Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            assert!(status.success(), "simulate ended with {status}");
            break;
        }
        if started.elapsed() > Duration::from_secs(30) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("simulate did not end on its own");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let mut stderr = String::new();
    child
        .stderr
        .take()
        .expect("stderr")
        .read_to_string(&mut stderr)
        .expect("read stderr");
    assert!(!stderr.contains("panicked"), "{stderr}");
    stderr
}

/// The RTU frame of `request` to slave 1.
fn frame(request: &Request) -> Vec<u8> {
    let mut buf = [0u8; rtu::MAX_FRAME_LEN];
    let len = rtu::encode_request(&mut buf, 1, request).expect("encode");
    buf[..len].to_vec()
}

/// FC04 of the first `count` input registers (the P series' measurements).
fn read_inputs(count: u16) -> Request {
    Request::Read {
        function: ReadFunction::Input,
        address: 0,
        count,
    }
}

/// FC03 of holding register 2 (light power: a setting, the same in every run).
fn read_setting() -> Request {
    Request::Read {
        function: ReadFunction::Holding,
        address: 2,
        count: 1,
    }
}

/// The pty at `path`, opened for raw RTU: the writing end, and the bytes read from it as
/// they arrive (from a thread of their own, so reads can time out).
fn open_pty(path: &str) -> (File, Receiver<(Instant, Vec<u8>)>) {
    let file = File::options()
        .read(true)
        .write(true)
        .open(path)
        .unwrap_or_else(|e| panic!("open {path}: {e}"));
    let mut reader = file.try_clone().expect("clone the pty");
    let (sender, receiver) = mpsc::channel();
    std::thread::spawn(move || {
        let mut buf = [0u8; 512];
        while let Ok(read) = reader.read(&mut buf) {
            if read == 0 || sender.send((Instant::now(), buf[..read].to_vec())).is_err() {
                break;
            }
        }
    });
    (file, receiver)
}

/// Bytes that arrive while `more` gives how long to wait for the next chunk (it is given the
/// bytes so far and the deadline, 3 s away), and when the last came.
fn collect_while(
    bytes: &Receiver<(Instant, Vec<u8>)>,
    more: impl Fn(&[u8], Instant) -> Option<Duration>,
) -> (Vec<u8>, Option<Instant>) {
    let deadline = Instant::now() + Duration::from_secs(3);
    let mut reply = Vec::new();
    let mut last = None;
    while let Some(wait) = more(&reply, deadline) {
        match bytes.recv_timeout(wait) {
            Ok((at, chunk)) => {
                reply.extend_from_slice(&chunk);
                last = Some(at);
            }
            Err(_) => break,
        }
    }
    (reply, last)
}

/// Bytes that arrive until `quiet` passes without any (at most 3 s), and when the last came.
fn collect(bytes: &Receiver<(Instant, Vec<u8>)>, quiet: Duration) -> (Vec<u8>, Option<Instant>) {
    collect_while(bytes, |_, deadline| {
        (Instant::now() < deadline).then_some(quiet)
    })
}

/// Bytes that arrive until there are `len` of them (at most 3 s), and when the last came.
fn collect_len(bytes: &Receiver<(Instant, Vec<u8>)>, len: usize) -> (Vec<u8>, Option<Instant>) {
    collect_while(bytes, |reply, deadline| {
        (reply.len() < len).then(|| deadline.saturating_duration_since(Instant::now()))
    })
}

/// Whether the last two bytes of `frame` are the CRC of the others.
fn crc_ok(frame: &[u8]) -> bool {
    match frame.len().checked_sub(2) {
        Some(body) if body > 0 => crc16(&frame[..body]).to_le_bytes() == frame[body..],
        _ => false,
    }
}

#[test]
fn dropped_replies_never_come_over_tcp_and_are_summed_up_at_exit() {
    let (child, address) = simulate(&[
        "--tcp",
        "127.0.0.1:0",
        "--faults",
        "drop=1",
        "--duration",
        "3s",
    ]);
    assert!(address.starts_with("127.0.0.1:"), "{address}");
    let mut stream = TcpStream::connect(&address).expect("connect");
    stream
        .set_read_timeout(Some(Duration::from_millis(700)))
        .expect("timeout");
    // Transaction 7, unit 1, FC03 of holding register 2.
    stream
        .write_all(&[0, 7, 0, 0, 0, 6, 1, 0x03, 0, 2, 0, 1])
        .expect("send");
    let mut reply = [0u8; 64];
    match stream.read(&mut reply) {
        Ok(0) => panic!("the connection was closed instead of the reply dropped"),
        Ok(n) => panic!("a reply came: {:02X?}", &reply[..n]),
        Err(e) => assert!(
            matches!(
                e.kind(),
                std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
            ),
            "{e}"
        ),
    }
    let stderr = finish(child);
    let banner = "optobus: simulating p-series (slave 1) on Modbus TCP at";
    assert!(stderr.starts_with(banner), "{stderr}");
    logged(
        &stderr,
        ", faults drop=1",
        "faults injected: 1 of 1 replies (drop 1)",
    );
}

/// The log's first line ends with `banner_end`, and one line is the summary `summary`.
fn logged(stderr: &str, banner_end: &str, summary: &str) {
    let first = stderr.lines().next().unwrap_or_default();
    assert!(first.ends_with(banner_end), "{stderr}");
    let summary = format!("optobus: {summary}");
    assert!(stderr.lines().any(|l| l == summary), "{stderr}");
}

#[test]
fn corrupted_replies_over_a_pty_fail_their_crc() {
    let (child, path) = simulate(&[
        "--pty",
        "--faults",
        "corrupt=1",
        "--seed",
        "3",
        "--duration",
        "3s",
    ]);
    let (mut pty, bytes) = open_pty(&path);
    // Slave, function, byte count, 2 words, CRC: a flipped bit keeps the length.
    let request = read_inputs(2);
    for _ in 0..3 {
        pty.write_all(&frame(&request)).expect("send");
        let (reply, _) = collect_len(&bytes, 9);
        assert_eq!(reply.len(), 9, "{reply:02X?}");
        assert!(!crc_ok(&reply), "the CRC still matches: {reply:02X?}");
        assert!(
            rtu::decode_response(&reply, 1, &request, ExceptionShape::Standard).is_err(),
            "{reply:02X?}"
        );
    }
    let stderr = finish(child);
    logged(
        &stderr,
        ", faults corrupt=1,seed=3",
        "faults injected: 3 of 3 replies (corrupt 3)",
    );
}

#[test]
fn bad_fault_specs_are_refused_before_serving() {
    for (faults, message) in [
        ("lightning=1", "unknown fault `lightning`"),
        (
            "corrupt=2",
            "`corrupt=2`: a probability is a number in 0..=1",
        ),
        ("drop=0.6,delay=0.6", "more than 1"),
        ("corrupt", "`corrupt` needs a value"),
        ("late=soon", "`late=soon`: a duration"),
    ] {
        let output = common::run(&["simulate", "--tcp", "127.0.0.1:0", "--faults", faults]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(
            output.status.code(),
            Some(common::REFUSED),
            "{faults}: {stderr}"
        );
        assert!(
            stderr.starts_with(&format!("optobus: --faults `{faults}`: ")),
            "{faults}: {stderr}"
        );
        assert!(stderr.contains(message), "{faults}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{faults}: {stderr}");
        assert!(output.stdout.is_empty(), "served: {:?}", output.stdout);
    }
    // --seed seeds --faults; --turnaround times --line-timing.
    for args in [
        &["simulate", "--seed", "3"][..],
        &["simulate", "--pty", "--turnaround", "1ms"][..],
        &["simulate", "--faults", "drop=1", "--seed", "-1"][..],
    ] {
        let output = common::run(args);
        assert_eq!(output.status.code(), Some(common::USAGE), "{args:?}");
        assert!(output.stdout.is_empty(), "{args:?}");
    }
}

#[test]
fn line_timing_is_refused_for_modbus_tcp() {
    let output = common::run(&["simulate", "--tcp", "127.0.0.1:0", "--line-timing"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(common::REFUSED), "{stderr}");
    assert!(
        stderr.starts_with("optobus: --line-timing times an RTU serial line"),
        "{stderr}"
    );
    assert!(stderr.contains("--pty"), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(output.stdout.is_empty());
}

#[test]
fn a_timed_pty_answers_no_sooner_than_the_line_allows() {
    let turnaround = Duration::from_millis(20);
    let (child, path) = simulate(&[
        "--pty",
        "--line-timing",
        "--turnaround",
        "20ms",
        "--duration",
        "3s",
    ]);
    let (mut pty, bytes) = open_pty(&path);
    let format = optobus_driver::line_format(&optobus_p_series::DEVICE);
    let request = read_inputs(6);
    let sent = frame(&request);
    for _ in 0..3 {
        let start = Instant::now();
        pty.write_all(&sent).expect("send");
        let (reply, last) = collect_len(&bytes, 17);
        let Ok(Decoded::Frame {
            frame: Response::Read { words, .. },
            consumed: 17,
        }) = rtu::decode_response(&reply, 1, &request, ExceptionShape::Standard)
        else {
            panic!("not a reply of 6 words: {reply:02X?}");
        };
        assert_eq!(words.len(), 6);
        // The request's characters, t3.5, the turnaround and the reply's characters.
        let least =
            format.transmit_time(sent.len() + reply.len()) + format.frame_gap() + turnaround;
        let took = last.expect("a reply").duration_since(start);
        assert!(
            took >= least,
            "answered in {took:?}, the line needs {least:?}"
        );
        // A pause longer than t3.5 before the next request.
        std::thread::sleep(Duration::from_millis(20));
    }
    let stderr = finish(child);
    let baud = format.baud;
    assert!(
        stderr.lines().next().is_some_and(
            |l| l.contains(&format!(", line timed at {baud} baud 8N1, turnaround 20ms"))
        ),
        "{stderr}"
    );
    assert!(
        stderr
            .lines()
            .any(|l| l.starts_with("optobus: line: 3 requests, 3 replies")),
        "{stderr}"
    );
}

/// The replies to five reads of a setting from `optobus simulate --pty --faults … --seed 11`.
fn faulty_replies() -> Vec<Vec<u8>> {
    let (child, path) = simulate(&[
        "--pty",
        "--faults",
        "corrupt=0.2,truncate=0.2,garbage=0.2,wrong_slave=0.2,drop=0.1",
        "--seed",
        "11",
        "--duration",
        "4s",
    ]);
    let (mut pty, bytes) = open_pty(&path);
    let sent = frame(&read_setting());
    let replies = (0..5)
        .map(|_| {
            pty.write_all(&sent).expect("send");
            // Longer than the simulator's 20 ms frame gap: each request stands alone.
            collect(&bytes, Duration::from_millis(150)).0
        })
        .collect();
    finish(child);
    replies
}

#[test]
fn the_same_seed_gives_the_same_reply_bytes() {
    let first = faulty_replies();
    let second = faulty_replies();
    assert_eq!(first, second);
    // Faults were injected: not every reply is the clean 7-byte frame.
    assert!(
        first.iter().any(|r| r.len() != 7 || !crc_ok(r)),
        "{first:02X?}"
    );
}
