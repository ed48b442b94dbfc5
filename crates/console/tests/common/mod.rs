//! What the console's API tests share: a running simulated bus, a console on it, requests
//! through its router or over real sockets.

#![allow(dead_code, unused_imports, unreachable_pub)]

pub use std::net::SocketAddr;
pub use std::path::Path;
pub use std::time::Duration;

pub use axum::body::Body;
pub use axum::http::{Request, StatusCode};
pub use axum::Router;
pub use optobus_bus::{Bus, BusFile, Catalogue, Running};
pub use optobus_console::Console;
pub use optobus_console::HttpConfig;
pub use serde_json::{json, Value};
pub use tower::ServiceExt;

pub const TWO: &str = "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 50ms, poll: [{ read: measurements, every: 20ms }] }
  - { name: confocal, model: ccs, slave: 2, timeout: 50ms, poll: [{ read: measurements, every: 20ms }] }
";

pub const ADDRESS: &str = "127.0.0.1:8080";

pub fn start(text: &str) -> Running {
    let catalogue = Catalogue::new([
        &optobus_p_series::DEVICE,
        &optobus_ccs::DEVICE,
        &optobus_rangefinder::DEVICE,
    ]);
    let file = BusFile::parse("bus.yaml", text, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()));
    Bus::new(file).start().unwrap()
}

pub fn console(running: &Running, config: &HttpConfig) -> Console {
    Console::new(running, config, config.listen).unwrap()
}

pub fn loopback() -> HttpConfig {
    HttpConfig::new(ADDRESS.parse::<SocketAddr>().unwrap())
}

/// Sends a request (to 127.0.0.1:8080 unless `host` says otherwise): its status and JSON body.
pub async fn call(router: &Router, request: Request<Body>) -> (StatusCode, Value) {
    let response = router.clone().oneshot(request).await.unwrap();
    let status = response.status();
    let bytes = axum::body::to_bytes(response.into_body(), 1 << 20)
        .await
        .unwrap();
    let json = serde_json::from_slice(&bytes).unwrap_or(Value::Null);
    (status, json)
}

pub fn get(path: &str) -> Request<Body> {
    Request::get(path)
        .header("host", ADDRESS)
        .body(Body::empty())
        .unwrap()
}

/// Waits until `path` gives what `ready` accepts (30 s at most).
pub async fn until(router: &Router, path: &str, ready: impl Fn(&Value) -> bool) -> Value {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
    while tokio::time::Instant::now() < deadline {
        let (status, json) = call(router, get(path)).await;
        assert_eq!(status, StatusCode::OK, "{json}");
        if ready(&json) {
            return json;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    panic!("{path} never became ready");
}

pub const WRITABLE: &str = "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 50ms, writable: [light_power, save_parameters], poll: [{ read: measurements, every: 20ms }] }
";

pub fn post(path: &str, body: impl Into<String>) -> Request<Body> {
    Request::post(path)
        .header("host", ADDRESS)
        .header("content-type", "application/json")
        .body(Body::from(body.into()))
        .unwrap()
}

/// Whether the head's frames hold a write (FC06 or FC16).
pub fn wrote(running: &Running) -> bool {
    running
        .handle()
        .frames("head")
        .unwrap()
        .iter()
        .any(|f| f.direction == optobus_bus::Direction::Sent && matches!(f.bytes[1], 6 | 16))
}

pub fn light_power(running: &Running) -> Option<Vec<u16>> {
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    running
        .simulator("head")
        .unwrap()
        .peek(optobus_device::Table::Holding, power.address)
}

// Short limits, so that the tests wait little; a read until the server closes.
pub use optobus_testkit::http::{short_limits as short, until_closed};

/// One request on a new connection; the reply's text.
pub async fn over_socket(address: SocketAddr, request: &str) -> String {
    use tokio::io::AsyncWriteExt;
    let mut stream = tokio::net::TcpStream::connect(address).await.unwrap();
    stream.write_all(request.as_bytes()).await.unwrap();
    until_closed(&mut stream).await
}

pub fn status_request(address: SocketAddr) -> String {
    format!("GET /api/status HTTP/1.1\r\nHost: {address}\r\nConnection: close\r\n\r\n")
}

/// One request to the console at `address` on a new connection, `Host` and other headers as
/// given: the status and the JSON body of its reply.
pub async fn exchange(
    address: SocketAddr,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &str,
) -> (u16, Value) {
    let mut request = format!("{method} {path} HTTP/1.1\r\n");
    for (name, value) in headers {
        request.push_str(&format!("{name}: {value}\r\n"));
    }
    if !body.is_empty() {
        request.push_str("content-type: application/json\r\n");
    }
    request.push_str(&format!(
        "content-length: {}\r\nconnection: close\r\n\r\n{body}",
        body.len()
    ));
    // Real clients connect to the loopback whatever the console is bound to.
    let to = SocketAddr::from(([127, 0, 0, 1], address.port()));
    let reply = over_socket(to, &request).await;
    let status = reply
        .strip_prefix("HTTP/1.1 ")
        .and_then(|rest| rest.get(..3))
        .and_then(|code| code.parse().ok())
        .unwrap_or_else(|| panic!("no HTTP reply: {reply:?}"));
    let json = reply
        .split_once("\r\n\r\n")
        .and_then(|(_, body)| serde_json::from_str(body).ok())
        .unwrap_or(Value::Null);
    (status, json)
}

/// A token file with `token` in it, removed when dropped.
pub struct TokenFile(pub std::path::PathBuf);

impl TokenFile {
    pub fn new(name: &str, token: &str) -> Self {
        let path =
            std::env::temp_dir().join(format!("optobus-{name}-{}.token", std::process::id()));
        std::fs::write(&path, format!("{token}\n")).unwrap();
        Self(path)
    }
}

impl Drop for TokenFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}
