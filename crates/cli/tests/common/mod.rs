//! Running the `optobus` binary in tests, and a simulator served by it in the background.

#![allow(dead_code, unreachable_pub)]

use std::io::{BufRead, BufReader};
use std::process::{Child, ChildStderr, Command, Output, Stdio};

/// The built binary.
pub fn optobus() -> Command {
    let mut command = Command::new(assert_cmd::cargo::cargo_bin!("optobus"));
    command.env("NO_COLOR", "1");
    // The user's default model would hide what a test leaves out.
    command.env_remove("OPTOBUS_MODEL");
    command
}

/// A command line's words: `words("read distance_1")` is `["read", "distance_1"]`.
pub fn words(line: &str) -> Vec<&str> {
    line.split_whitespace().collect()
}

/// Runs `optobus args…` to completion.
pub fn run(args: &[&str]) -> Output {
    optobus().args(args).output().expect("run optobus")
}

/// Stdout of a successful run (fails the test with stderr otherwise).
pub fn ok(args: &[&str]) -> String {
    let output = run(args);
    assert!(
        output.status.success(),
        "optobus {args:?} failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// Stderr of a failing run (fails the test if it succeeded).
pub fn fails(args: &[&str]) -> String {
    let output = run(args);
    assert!(
        !output.status.success(),
        "optobus {args:?} should have failed: {}",
        String::from_utf8_lossy(&output.stdout)
    );
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// JSON stdout of a successful run.
pub fn json(args: &[&str]) -> serde_json::Value {
    let mut with_json = args.to_vec();
    with_json.push("--json");
    serde_json::from_str(&ok(&with_json)).expect("valid JSON")
}

/// Exit code of clap's usage errors (a value its parser refused).
pub const USAGE: i32 = 2;
/// Exit code of the tool's own refusals: input checked and refused before anything was sent.
pub const REFUSED: i32 = 3;
/// Exit code of a failure of the device, the line or the system.
pub const FAILED: i32 = 1;

/// Runs `args`; gives (exit code, stdout, stderr).
pub fn outcome(args: &[&str]) -> (Option<i32>, String, String) {
    let output = run(args);
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stdout).into_owned(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

/// Runs `args --verbose`: it must fail with `code` and a stderr containing `message`, without
/// a panic, without sending a frame (` -> ` with --verbose) and without opening a connection
/// (the built-in simulator's line, "cannot open", "cannot connect"); the tool's own refusals
/// (`REFUSED`) in one line. Gives stderr. (`frame` sends nothing and takes no --verbose.)
pub fn refused(args: &[&str], code: i32, message: &str) -> String {
    let mut verbose = args.to_vec();
    if args.first() != Some(&"frame") {
        verbose.push("--verbose");
    }
    let (status, _, stderr) = outcome(&verbose);
    assert_eq!(status, Some(code), "{args:?}: {stderr}");
    assert!(stderr.contains(message), "{args:?}: {stderr}");
    assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    for sign in [" -> ", "built-in", "cannot open", "cannot connect"] {
        assert!(
            !stderr.contains(sign),
            "{args:?} went as far as `{sign}`: {stderr}"
        );
    }
    if code == REFUSED {
        assert_eq!(stderr.lines().count(), 1, "one line: {stderr}");
    }
    stderr
}

/// The first line `optobus simulate` prints on stdout: where it serves (the TCP address or
/// the pty path).
pub fn serves_at(child: &mut Child) -> String {
    let mut line = String::new();
    let stdout = child.stdout.take().expect("stdout");
    BufReader::new(stdout)
        .read_line(&mut line)
        .expect("where it serves");
    line.trim().to_owned()
}

/// `optobus simulate …` running in the background; stopped when dropped.
pub struct Served {
    child: Child,
    /// What it printed first: the TCP address or the pty path.
    pub at: String,
    /// The model it serves (as named first; p-series by default).
    pub model: String,
}

impl Served {
    /// The command line `rest --serial <where it serves> --model <its model>`, for
    /// [`words`] (device options follow the command).
    pub fn serial(&self, rest: &str) -> String {
        format!("{rest} --serial {} --model {}", self.at, self.model)
    }

    pub fn start(args: &[&str]) -> Self {
        let mut child = optobus()
            .arg("simulate")
            .args(args)
            .args(["--duration", "60s"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("start optobus simulate");
        let at = serves_at(&mut child);
        let model = match args.first() {
            Some(name) if !name.starts_with('-') => (*name).to_owned(),
            _ => "p-series".to_owned(),
        };
        Self { child, at, model }
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Runs `optobus args…`, sends it Ctrl-C (SIGINT) after `after`, and gives how it ended.
#[allow(dead_code)]
pub fn interrupted(args: &[&str], after: std::time::Duration) -> Output {
    let child = optobus()
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("start optobus");
    std::thread::sleep(after);
    let sent = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill -INT");
    assert!(sent.success());
    child.wait_with_output().expect("optobus ends")
}

/// `mbpoll args…` once; the values it printed (`[3]: 425` lines).
#[allow(dead_code)]
pub fn mbpoll(args: &[&str]) -> Vec<i64> {
    let output = std::process::Command::new("mbpoll")
        .args(args)
        .output()
        .expect("run mbpoll");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "mbpoll {args:?}: {stdout}");
    stdout
        .lines()
        .filter_map(|line| line.trim().strip_prefix('['))
        .filter_map(|rest| rest.split_once("]:"))
        .filter_map(|(_, value)| value.trim().parse().ok())
        .collect()
}

/// A process killed when dropped.
pub struct Killed(pub Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A TCP port on 127.0.0.1 that was free a moment ago.
pub fn free_port() -> u16 {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    listener.local_addr().unwrap().port()
}

/// A mosquitto broker on 127.0.0.1:`port`, its configuration in `dir`, until dropped.
pub fn mosquitto(dir: &std::path::Path, port: u16) -> Killed {
    let conf = dir.join("mosquitto.conf");
    std::fs::write(
        &conf,
        format!("listener {port} 127.0.0.1\nallow_anonymous true\n"),
    )
    .unwrap();
    Killed(
        Command::new("mosquitto")
            .arg("-c")
            .arg(&conf)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("mosquitto starts"),
    )
}

/// An HTTP/1.1 POST of the JSON `body` to the console at `address`: the status and the body.
pub fn post(address: &str, path: &str, body: &str) -> (u16, String) {
    exchange(
        address,
        &format!(
            "POST {path} HTTP/1.1\r\nHost: {address}\r\nContent-Type: application/json\r\n\
             Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
            body.len()
        ),
    )
}

/// A bare HTTP/1.1 GET to the console at `address`: the status code and the body.
pub fn get(address: &str, path: &str) -> (u16, String) {
    exchange(
        address,
        &format!("GET {path} HTTP/1.1\r\nHost: {address}\r\nConnection: close\r\n\r\n"),
    )
}

/// Sends `request` to the console at `address` on a new connection: the status code and the
/// body of its reply.
fn exchange(address: &str, request: &str) -> (u16, String) {
    use std::io::{Read, Write};
    let mut stream = std::net::TcpStream::connect(address).expect("the console listens");
    stream.write_all(request.as_bytes()).unwrap();
    let mut reply = String::new();
    stream.read_to_string(&mut reply).unwrap();
    let (head, body) = reply.split_once("\r\n\r\n").expect("a head and a body");
    let status = head.split(' ').nth(1).and_then(|s| s.parse().ok()).unwrap();
    (status, body.to_owned())
}

/// A running `optobus run --demo`.
pub struct Demo {
    /// The process.
    pub child: Child,
    /// The first line of its stderr, where it names its listeners.
    pub first_line: String,
    /// The rest of its stderr, kept open while the demo runs (it may write more).
    pub stderr: BufReader<ChildStderr>,
}

/// Starts `optobus run --demo` with `outputs` (such as `["--gateway", "127.0.0.1:0"]`) for
/// 20 s, its samples as JSON lines on `stdout`, and reads the first line of its stderr.
pub fn demo_with(outputs: &[&str], stdout: Stdio) -> Demo {
    let mut child = optobus()
        .args(["run", "--demo"])
        .args(outputs)
        .args(["--duration", "20s", "--json"])
        .stdout(stdout)
        .stderr(Stdio::piped())
        .spawn()
        .expect("run the demo");
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut first_line = String::new();
    stderr.read_line(&mut first_line).unwrap();
    Demo {
        child,
        first_line,
        stderr,
    }
}
