//! A stderr nobody reads, or one that is closed, never costs a reply: `optobus simulate` logs
//! every exchange from a thread of its own and drops lines it cannot write, and no message
//! of the tool panics on a closed stderr.

mod common;

use std::io::{BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

/// `optobus simulate p-series --tcp 127.0.0.1:0 --duration …` with stderr a pipe; gives the
/// child and its address. With `close_stderr`, the pipe's read end is dropped at once.
fn simulate(duration: &str, close_stderr: bool) -> (Child, String) {
    let mut child = common::optobus()
        .args(["simulate", "p-series", "--tcp", "127.0.0.1:0"])
        .args(["--duration", duration])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start optobus simulate");
    if close_stderr {
        drop(child.stderr.take());
    }
    let address = common::serves_at(&mut child);
    assert!(address.starts_with("127.0.0.1:"), "{address:?}");
    (child, address)
}

/// Sends `count` Modbus TCP reads of holding register 0 one after another; every one must
/// get its reply within 5 s.
fn requests(address: &str, count: u16) {
    let mut stream = TcpStream::connect(address).expect("connect");
    stream
        .set_read_timeout(Some(Duration::from_secs(5)))
        .expect("timeout");
    let _ = stream.set_nodelay(true);
    for transaction in 1..=count {
        let [hi, lo] = transaction.to_be_bytes();
        let request = [hi, lo, 0, 0, 0, 6, 1, 0x03, 0, 0, 0, 1];
        stream.write_all(&request).expect("send");
        let mut reply = [0u8; 11];
        stream
            .read_exact(&mut reply)
            .unwrap_or_else(|e| panic!("no reply to request {transaction}: {e}"));
        assert_eq!(&reply[..2], &[hi, lo], "reply to request {transaction}");
        assert_eq!(&reply[7..9], &[0x03, 2], "reply to request {transaction}");
    }
}

/// Waits for the child to end on its own (its --duration), at most `within`.
fn ends_on_its_own(child: &mut Child, within: Duration) {
    let started = Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            assert!(status.success(), "simulate ended with {status}");
            return;
        }
        if started.elapsed() > within {
            let _ = child.kill();
            let _ = child.wait();
            panic!("simulate did not end within {within:?} of its --duration");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn a_full_stderr_pipe_never_holds_up_a_reply() {
    // About 50 bytes a log line: 4000 exchanges are three times a 64 KiB pipe, and more than
    // the log holds back besides.
    let (mut child, address) = simulate("8s", false);
    let stderr = child.stderr.take().expect("stderr, never read");
    requests(&address, 4000);
    ends_on_its_own(&mut child, Duration::from_secs(30));
    // Read now: the log said lines were dropped (when it could), and nothing panicked.
    let mut text = String::new();
    let _ = BufReader::new(stderr).read_to_string(&mut text);
    assert!(!text.contains("panicked"), "{text}");
    assert!(
        text.contains("read holding 0 x1 -> 1 words"),
        "some lines got through"
    );
}

#[test]
fn a_closed_stderr_never_costs_a_reply() {
    let (mut child, address) = simulate("3s", true);
    requests(&address, 200);
    ends_on_its_own(&mut child, Duration::from_secs(30));
}

#[test]
fn messages_on_a_closed_stderr_do_not_panic() {
    let served = common::Served::start(&["p-series", "--tcp", "127.0.0.1:0"]);
    for (args, code) in [
        // Success with a note on stderr ("… registers in … requests").
        (
            vec!["--model", "p-series", "dump", "--tcp", served.at.as_str()],
            0,
        ),
        // Every frame traced to a stderr that is gone.
        (
            vec![
                "--model",
                "p-series",
                "dump",
                "--tcp",
                served.at.as_str(),
                "--verbose",
            ],
            0,
        ),
        // A refusal: its one line goes nowhere, the exit code still says so.
        (vec!["read", "distance_1", "--slave", "0"], common::REFUSED),
    ] {
        let mut child = common::optobus()
            .args(&args)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start optobus");
        drop(child.stderr.take());
        let status = child.wait().expect("optobus ends");
        assert_eq!(status.code(), Some(code), "{args:?}");
    }
}
