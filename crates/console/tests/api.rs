//! The console's JSON API, asked through its router: real values from a simulated bus, the
//! register map from the spec, frames as they went, and every bad request refused with a 4xx
//! and the tool's one-line message.

use std::net::SocketAddr;
use std::path::Path;
use std::time::Duration;

use axum::body::Body;
use axum::http::{Request, StatusCode};
use axum::Router;
use optobus_bus::{Bus, BusFile, Catalogue, HttpConfig, Running};
use optobus_console::Console;
use serde_json::{json, Value};
use tower::ServiceExt;

const TWO: &str = "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 50ms, poll: [{ read: measurements, every: 20ms }] }
  - { name: confocal, model: ccs, slave: 2, timeout: 50ms, poll: [{ read: measurements, every: 20ms }] }
";

const ADDRESS: &str = "127.0.0.1:8080";

pub(crate) fn start(text: &str) -> Running {
    let catalogue = Catalogue::new([
        &optobus_p_series::DEVICE,
        &optobus_ccs::DEVICE,
        &optobus_rangefinder::DEVICE,
    ]);
    let file = BusFile::parse("bus.yaml", text, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()));
    Bus::new(file).start().unwrap()
}

fn console(running: &Running, config: &HttpConfig) -> Console {
    Console::new(running, config, config.listen).unwrap()
}

fn loopback() -> HttpConfig {
    HttpConfig::new(ADDRESS.parse::<SocketAddr>().unwrap())
}

/// Sends a request (to 127.0.0.1:8080 unless `host` says otherwise): its status and JSON body.
async fn call(router: &Router, request: Request<Body>) -> (StatusCode, Value) {
    let response = router.clone().oneshot(request).await.unwrap();
    let status = response.status();
    let bytes = axum::body::to_bytes(response.into_body(), 1 << 20)
        .await
        .unwrap();
    let json = serde_json::from_slice(&bytes).unwrap_or(Value::Null);
    (status, json)
}

fn get(path: &str) -> Request<Body> {
    Request::get(path)
        .header("host", ADDRESS)
        .body(Body::empty())
        .unwrap()
}

/// Waits until `path` gives what `ready` accepts (30 s at most).
async fn until(router: &Router, path: &str, ready: impl Fn(&Value) -> bool) -> Value {
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

#[tokio::test]
async fn devices_come_with_model_line_slave_and_health() {
    let running = start(TWO);
    let router = console(&running, &loopback()).router();
    let (status, json) = call(&router, get("/api/devices")).await;
    assert_eq!(status, StatusCode::OK);
    let devices = json["devices"].as_array().unwrap();
    let names: Vec<&str> = devices
        .iter()
        .map(|d| d["device"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["head", "confocal"]);
    assert_eq!(devices[0]["model"], "p-series");
    assert_eq!(devices[1]["slave"], 2);
    assert_eq!(devices[0]["line"], "rs485");
    assert_eq!(devices[0]["health"], "online");
    assert_eq!(json["needs_token"], false);
}

#[tokio::test]
async fn latest_values_are_the_polled_samples_with_their_units() {
    let running = start(TWO);
    let router = console(&running, &loopback()).router();
    let json = until(&router, "/api/values", |json| {
        json["head"].as_array().is_some_and(|v| !v.is_empty())
            && json["confocal"].as_array().is_some_and(|v| !v.is_empty())
    })
    .await;
    let distance = json["head"]
        .as_array()
        .unwrap()
        .iter()
        .find(|v| v["register"] == "distance_1")
        .expect("distance_1 is polled");
    let text = distance["text"].as_str().unwrap();
    let (number, unit) = text.split_once(' ').unwrap();
    assert_eq!(unit, "mm");
    assert_eq!(distance["value"]["unit"], "mm");
    assert_eq!(distance["value"]["value"], number);
    assert_eq!(
        distance["number"].as_f64().unwrap(),
        number.parse::<f64>().unwrap()
    );
    assert!(
        distance["time"].as_f64().unwrap() > 1.7e12,
        "milliseconds since 1970"
    );
}

#[tokio::test]
async fn point_5_a_record_registers_fields_come_each_with_its_unit_and_number() {
    let running = start(
        "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: ranger, model: rangefinder, slave: 3, timeout: 50ms, poll: [{ read: measurements, every: 20ms }] }
",
    );
    let router = console(&running, &loopback()).router();
    let json = until(&router, "/api/values", |json| {
        json["ranger"].as_array().is_some_and(|v| v.len() == 2)
    })
    .await;
    let values = json["ranger"].as_array().unwrap();
    let record = values
        .iter()
        .find(|v| v["register"] == "measurement_results")
        .expect("measurement_results is polled");
    let fields = record["fields"].as_array().expect("its fields");
    let names: Vec<(&str, &str)> = fields
        .iter()
        .map(|f| (f["name"].as_str().unwrap(), f["unit"].as_str().unwrap()))
        .collect();
    assert_eq!(
        names,
        [
            ("distance", "mm"),
            ("signal_strength", "uV"),
            ("temperature", "degC")
        ]
    );
    // Each field's text is its value in the record's JSON, with its unit, and its number.
    let temperature = &fields[2];
    assert_eq!(
        temperature["text"],
        format!(
            "{} degC",
            record["value"]["temperature"]["value"].as_str().unwrap()
        )
    );
    let number: f64 = record["value"]["temperature"]["value"]
        .as_str()
        .unwrap()
        .parse()
        .unwrap();
    assert_eq!(temperature["number"].as_f64(), Some(number));
    // A register of one value has none.
    let status = values
        .iter()
        .find(|v| v["register"] == "error_status")
        .unwrap();
    assert_eq!(status["fields"], Value::Null);
}

#[tokio::test]
async fn the_register_map_comes_from_the_spec() {
    let running = start(TWO);
    let router = console(&running, &loopback()).router();
    let (status, json) = call(&router, get("/api/devices/head")).await;
    assert_eq!(status, StatusCode::OK);
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    let row = json["registers"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["name"] == "light_power")
        .unwrap();
    assert_eq!(row["address"], power.address);
    assert_eq!(row["address_hex"], format!("0x{:04X}", power.address));
    assert_eq!(row["unit"], "%");
    assert_eq!(
        row["range"],
        optobus_inspect::range_text(power).unwrap().as_str()
    );
    assert_eq!(
        row["writable"], false,
        "nothing is writable unless the bus file lists it"
    );
    assert_eq!(row["section"], power.section);
    let commands = json["commands"].as_array().unwrap();
    for command in optobus_p_series::DEVICE.commands {
        let shown = commands.iter().find(|c| c["name"] == command.name).unwrap();
        assert_eq!(
            shown["drastic"],
            command.effect.is_drastic(),
            "{}",
            command.name
        );
    }
    assert!(commands.iter().any(|c| c["drastic"] == true));
}

#[tokio::test]
async fn frames_show_the_requests_and_replies_of_a_device() {
    let running = start(TWO);
    let router = console(&running, &loopback()).router();
    let frames = until(&router, "/api/devices/confocal/frames", |json| {
        json.as_array().is_some_and(|f| f.len() >= 2)
    })
    .await;
    let request = &frames[0];
    assert_eq!(request["direction"], "sent");
    assert!(
        request["hex"].as_str().unwrap().starts_with("02 04 "),
        "{request}"
    );
    assert_eq!(frames[1]["direction"], "received");
    assert!(frames[1]["hex"].as_str().unwrap().starts_with("02 04 "));
    assert!(frames[1]["after_us"].as_u64().unwrap() > 0);
}

#[tokio::test]
async fn a_register_is_read_on_demand_and_unknown_names_are_refused() {
    let running = start(TWO);
    let router = console(&running, &loopback()).router();
    let (status, json) = call(
        &router,
        post("/api/devices/head/read", r#"{"register": "light_power"}"#),
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{json}");
    let simulator = running.simulator("head").unwrap();
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    let raw = simulator
        .peek(optobus_device::Table::Holding, power.address)
        .unwrap();
    assert_eq!(
        json["text"],
        optobus_inspect::decode_value(power, &raw).to_string()
    );
    let (status, json) = call(&router, get("/api/devices/tail/frames")).await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    assert_eq!(json["error"], "the bus has no device `tail`");
    let (status, json) = call(
        &router,
        post("/api/devices/head/read", r#"{"register": "lihgt_power"}"#),
    )
    .await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    assert_eq!(
        json["error"],
        "p-series has no register `lihgt_power`; did you mean `light_power`?"
    );
    // A route that is not there (the README walk guessed `/write`): a 404 in the API's shape.
    let (status, json) = call(&router, post("/api/devices/head/write", "{}")).await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    assert!(
        json["error"]
            .as_str()
            .is_some_and(|e| e.starts_with("no such route")),
        "{json}"
    );
}

#[tokio::test]
async fn a_loopback_console_answers_its_own_host_and_origin_only() {
    let running = start(TWO);
    let router = console(&running, &loopback()).router();
    let rebound = Request::get("/api/devices")
        .header("host", "evil.example:8080")
        .body(Body::empty())
        .unwrap();
    let (status, json) = call(&router, rebound).await;
    assert_eq!(status, StatusCode::MISDIRECTED_REQUEST);
    assert_eq!(
        json["error"],
        "the console does not answer requests for `evil.example:8080`: a name it answers is \
         listed in `hosts:` of the bus file's `http:` (against DNS rebinding)"
    );
    let foreign = Request::get("/api/stream")
        .header("host", ADDRESS)
        .header("origin", "http://evil.example")
        .body(Body::empty())
        .unwrap();
    let (status, json) = call(&router, foreign).await;
    assert_eq!(status, StatusCode::FORBIDDEN);
    assert_eq!(
        json["error"],
        "pages of http://evil.example may not call this console"
    );
    let own = Request::get("/api/devices")
        .header("host", "localhost:8080")
        .header("origin", "http://localhost:8080")
        .body(Body::empty())
        .unwrap();
    assert_eq!(call(&router, own).await.0, StatusCode::OK);
}

#[tokio::test]
async fn a_listed_origin_may_call_and_is_told_so() {
    let running = start(TWO);
    let mut config = loopback();
    config.origins = vec!["https://scada.example".into()];
    let router = console(&running, &config).router();
    let request = Request::get("/api/devices")
        .header("host", ADDRESS)
        .header("origin", "https://scada.example")
        .body(Body::empty())
        .unwrap();
    let response = router.clone().oneshot(request).await.unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    assert_eq!(
        response.headers()["access-control-allow-origin"],
        "https://scada.example"
    );
}

#[tokio::test]
async fn the_page_and_its_assets_are_served_from_the_binary() {
    let running = start(TWO);
    let router = console(&running, &loopback()).router();
    let mut total = 0;
    for path in ["/", "/app.js", "/style.css"] {
        let response = router.clone().oneshot(get(path)).await.unwrap();
        assert_eq!(response.status(), StatusCode::OK, "{path}");
        assert!(response.headers()["content-security-policy"]
            .to_str()
            .unwrap()
            .starts_with("default-src 'self'"));
        let body = axum::body::to_bytes(response.into_body(), 1 << 20)
            .await
            .unwrap();
        total += body.len();
    }
    assert_eq!(total, optobus_console::PAGE_BYTES);
}

#[tokio::test]
async fn the_stream_sends_batches_of_samples_health_and_line_statistics() {
    use futures_util::StreamExt;
    let running = start(TWO);
    let console = console(&running, &loopback());
    let response = console.router().oneshot(get("/api/stream")).await.unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    assert_eq!(response.headers()["content-type"], "text/event-stream");
    let mut body = response.into_body().into_data_stream();
    let mut devices = std::collections::BTreeSet::new();
    let mut lines = 0;
    while devices.len() < 2 || lines == 0 {
        let chunk = tokio::time::timeout(Duration::from_secs(5), body.next())
            .await
            .expect("a batch within 5 s")
            .unwrap()
            .unwrap();
        let text = std::str::from_utf8(&chunk).unwrap();
        for data in text.lines().filter_map(|l| l.strip_prefix("data: ")) {
            let batch: Value = serde_json::from_str(data).unwrap();
            for sample in batch["samples"].as_array().unwrap() {
                assert!(sample["text"].is_string() && sample["register"].is_string());
                devices.insert(sample["device"].as_str().unwrap().to_owned());
            }
            lines += batch["lines"].as_array().unwrap().len();
            assert_eq!(batch["overflow"], 0);
        }
    }
    assert_eq!(console.dropped_batches(), 0);
}

const WRITABLE: &str = "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 50ms, writable: [light_power, save_parameters], poll: [{ read: measurements, every: 20ms }] }
";

fn post(path: &str, body: impl Into<String>) -> Request<Body> {
    Request::post(path)
        .header("host", ADDRESS)
        .header("content-type", "application/json")
        .body(Body::from(body.into()))
        .unwrap()
}

/// Whether the head's frames hold a write (FC06 or FC16).
fn wrote(running: &Running) -> bool {
    running
        .handle()
        .frames("head")
        .unwrap()
        .iter()
        .any(|f| f.direction == optobus_bus::Direction::Sent && matches!(f.bytes[1], 6 | 16))
}

fn light_power(running: &Running) -> Option<Vec<u16>> {
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    running
        .simulator("head")
        .unwrap()
        .peek(optobus_device::Table::Holding, power.address)
}

#[tokio::test]
async fn a_set_is_read_as_optobus_set_reads_it_and_answers_the_value_read_back() {
    let running = start(WRITABLE);
    let router = console(&running, &loopback()).router();
    let (status, json) = call(
        &router,
        post(
            "/api/devices/head/set",
            r#"{"register": "light_power", "value": "12.5 %"}"#,
        ),
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{json}");
    assert_eq!(json["text"], "12.5 %");
    assert_eq!(json["value"], json!({"value": "12.5", "unit": "%"}));
    assert_eq!(light_power(&running), Some(vec![125]));
    // A number is its text.
    let (status, json) = call(
        &router,
        post(
            "/api/devices/head/set",
            r#"{"register": "light_power", "value": 50}"#,
        ),
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{json}");
    assert_eq!(light_power(&running), Some(vec![500]));
}

#[tokio::test]
async fn bad_input_gets_a_4xx_with_the_tools_message_and_nothing_reaches_the_line() {
    let running = start(WRITABLE);
    let router = console(&running, &loopback()).router();
    let before = light_power(&running);
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    let refusal = |text: &str| {
        let error = optobus_inspect::parse_value(power, text).unwrap_err();
        optobus_inspect::Error::from(error).to_string()
    };
    let cases: Vec<(&str, String, StatusCode, String)> = vec![
        (
            "/api/devices/head/set",
            r#"{"register": "light_power", "value": "#.into(),
            StatusCode::BAD_REQUEST,
            "Failed to parse the request body as JSON".into(),
        ),
        (
            "/api/devices/head/set",
            r#"{"register": "light_power", "value": "1", "force": true}"#.into(),
            StatusCode::UNPROCESSABLE_ENTITY,
            "unknown field `force`".into(),
        ),
        (
            "/api/devices/tail/set",
            r#"{"register": "light_power", "value": "1"}"#.into(),
            StatusCode::NOT_FOUND,
            "the bus has no device `tail`".into(),
        ),
        (
            "/api/devices/head/set",
            r#"{"register": "lihgt_power", "value": "1"}"#.into(),
            StatusCode::UNPROCESSABLE_ENTITY,
            "`lihgt_power`".into(),
        ),
        (
            "/api/devices/head/set",
            r#"{"register": "light_power", "value": "12.5 mm"}"#.into(),
            StatusCode::UNPROCESSABLE_ENTITY,
            refusal("12.5 mm"),
        ),
        (
            "/api/devices/head/set",
            r#"{"register": "light_power", "value": "150"}"#.into(),
            StatusCode::UNPROCESSABLE_ENTITY,
            refusal("150"),
        ),
        (
            "/api/devices/head/set",
            r#"{"register": "light_power", "value": [1]}"#.into(),
            StatusCode::UNPROCESSABLE_ENTITY,
            "`value` is text".into(),
        ),
        (
            "/api/devices/head/set",
            r#"{"register": "median_filter_width", "value": "1"}"#.into(),
            StatusCode::FORBIDDEN,
            "`median_filter_width` of `head` is not writable here".into(),
        ),
        (
            "/api/devices/head/do",
            r#"{"command": "reboot"}"#.into(),
            StatusCode::FORBIDDEN,
            "`reboot` of `head` is not writable here".into(),
        ),
        (
            "/api/devices/head/set",
            format!(
                r#"{{"register": "light_power", "value": "{}"}}"#,
                "1".repeat(5000)
            ),
            StatusCode::PAYLOAD_TOO_LARGE,
            format!(
                "the body is too large: at most {} bytes",
                optobus_console::BODY_LIMIT
            ),
        ),
    ];
    for (path, body, status, message) in cases {
        let (got, json) = call(&router, post(path, body.clone())).await;
        assert_eq!(got, status, "{body:.80}: {json}");
        let error = json["error"].as_str().unwrap();
        assert!(
            error.contains(&message),
            "{body:.80}: {error} lacks {message}"
        );
        assert!(!error.contains('\n'), "one line: {error}");
    }
    assert_eq!(light_power(&running), before);
    assert!(!wrote(&running), "nothing refused reaches the line");
}

#[tokio::test]
async fn beyond_the_loopback_writes_need_the_token_from_the_file() {
    let running = start(WRITABLE);
    let body = r#"{"register": "light_power", "value": "20 %"}"#;
    let open = HttpConfig::new("0.0.0.0:8080".parse().unwrap());
    let router = console(&running, &open).router();
    let (status, json) = call(&router, post("/api/devices/head/set", body)).await;
    assert_eq!(status, StatusCode::FORBIDDEN);
    assert!(json["error"]
        .as_str()
        .unwrap()
        .starts_with("writes and reads of the line are off: the console listens beyond 127.0.0.1"));
    let token = std::env::temp_dir().join(format!("optobus-console-{}.token", std::process::id()));
    std::fs::write(&token, "correct-horse-battery-staple\n").unwrap();
    let mut guarded = open.clone();
    guarded.token_file = Some(token.clone());
    let router = console(&running, &guarded).router();
    let (status, json) = call(&router, post("/api/devices/head/set", body)).await;
    assert_eq!(status, StatusCode::UNAUTHORIZED, "{json}");
    let mut wrong = post("/api/devices/head/set", body);
    wrong
        .headers_mut()
        .insert("authorization", "Bearer correct-horse".parse().unwrap());
    assert_eq!(call(&router, wrong).await.0, StatusCode::UNAUTHORIZED);
    assert!(!wrote(&running));
    let mut right = post("/api/devices/head/set", body);
    right.headers_mut().insert(
        "authorization",
        "Bearer correct-horse-battery-staple".parse().unwrap(),
    );
    let (status, json) = call(&router, right).await;
    assert_eq!(status, StatusCode::OK, "{json}");
    assert_eq!(light_power(&running), Some(vec![200]));
    // Reads need no token.
    assert_eq!(call(&router, get("/api/devices")).await.0, StatusCode::OK);
    std::fs::write(&token, "short").unwrap();
    let error = Console::new(&running, &guarded, guarded.listen).unwrap_err();
    assert!(error.to_string().contains("at least 16"), "{error}");
    let _ = std::fs::remove_file(token);
}

#[tokio::test]
async fn a_command_listed_runs_and_the_map_says_what_may_be_written() {
    let running = start(WRITABLE);
    let router = console(&running, &loopback()).router();
    let (_, map) = call(&router, get("/api/devices/head")).await;
    let row = |name: &str| {
        map["registers"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["name"] == name)
            .unwrap()
            .clone()
    };
    assert_eq!(row("light_power")["writable"], true);
    assert_eq!(row("median_filter_width")["writable"], false);
    let command = |name: &str| {
        map["commands"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["name"] == name)
            .unwrap()
            .clone()
    };
    assert_eq!(command("save_parameters")["allowed"], true);
    assert_eq!(command("reboot")["allowed"], false);
    let (status, json) = call(
        &router,
        post("/api/devices/head/do", r#"{"command": "save_parameters"}"#),
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{json}");
    assert_eq!(json["done"], true);
    assert!(wrote(&running));
}

#[tokio::test]
async fn the_data_buffer_is_read_out_as_csv_when_its_lock_and_unlock_are_listed() {
    let running = start(
        "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, writable: [buffer_report_count, lock_buffer, unlock_buffer] }
  - { name: other, model: p-series, slave: 2 }
",
    );
    let router = console(&running, &loopback()).router();
    let (status, json) = call(
        &router,
        post(
            "/api/devices/head/set",
            r#"{"register": "buffer_report_count", "value": "100"}"#,
        ),
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{json}");
    let (status, json) = call(
        &router,
        post("/api/devices/head/do", r#"{"command": "unlock_buffer"}"#),
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{json}");
    tokio::time::sleep(Duration::from_millis(300)).await;
    let response = router
        .clone()
        .oneshot(post("/api/devices/head/buffer", ""))
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    assert_eq!(
        response.headers()["content-type"],
        "text/csv; charset=utf-8"
    );
    let csv = axum::body::to_bytes(response.into_body(), 1 << 20)
        .await
        .unwrap();
    let csv = std::str::from_utf8(&csv).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("index,time_s,value_mm"));
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), 100, "{csv}");
    for (index, row) in rows.iter().enumerate() {
        let cells: Vec<&str> = row.split(',').collect();
        assert_eq!(cells[0], index.to_string());
        assert!(
            cells[1].parse::<f64>().is_ok() && cells[2].parse::<f64>().is_ok(),
            "{row}"
        );
    }
    let (status, json) = call(&router, post("/api/devices/other/buffer", "")).await;
    assert_eq!(status, StatusCode::FORBIDDEN);
    assert_eq!(
        json["error"],
        "`lock_buffer` of `other` is not writable here: the bus file's `writable` does not list it"
    );
}

#[tokio::test]
async fn a_device_going_offline_shows_in_the_stream_and_the_device_list_with_its_reason() {
    use futures_util::StreamExt;
    let running = start(
        "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 50ms, poll: [{ read: measurements, every: 50ms }] }
  - { name: dead, model: p-series, slave: 2, timeout: 30ms, faults: 'drop=1', poll: [{ read: light_power, every: 50ms }] }
",
    );
    let console = console(&running, &loopback());
    let response = console.router().oneshot(get("/api/stream")).await.unwrap();
    let mut body = response.into_body().into_data_stream();
    let health = loop {
        let chunk = tokio::time::timeout(Duration::from_secs(5), body.next())
            .await
            .expect("a batch within 5 s")
            .unwrap()
            .unwrap();
        let text = std::str::from_utf8(&chunk).unwrap().to_owned();
        let found = text
            .lines()
            .filter_map(|l| l.strip_prefix("data: "))
            .map(|data| serde_json::from_str::<Value>(data).unwrap())
            .flat_map(|batch| batch["health"].as_array().cloned().unwrap_or_default())
            .find(|h| h["device"] == "dead");
        if let Some(health) = found {
            break health;
        }
    };
    assert_eq!(health["health"], "offline");
    assert!(
        health["errors"]["timeouts"].as_u64().unwrap() >= 3,
        "{health}"
    );
    let reason = health["reason"].as_str().unwrap();
    assert!(reason.contains("no reply within 30 ms"), "{reason}");
    let (_, json) = call(&console.router(), get("/api/devices")).await;
    let devices = json["devices"].as_array().unwrap();
    assert_eq!(devices[0]["health"], "online");
    assert_eq!(devices[1]["health"], "offline");
    assert_eq!(devices[1]["reason"], reason);
}

/// The frames the head was sent that read `register` (FC03/FC04 at its address).
fn read_frames(running: &Running, register: &str) -> usize {
    let info = optobus_p_series::DEVICE.register(register).unwrap();
    let [high, low] = info.address.to_be_bytes();
    running
        .handle()
        .frames("head")
        .unwrap()
        .iter()
        .filter(|f| {
            f.direction == optobus_bus::Direction::Sent
                && matches!(f.bytes[1], 3 | 4)
                && f.bytes[2..4] == [high, low]
        })
        .count()
}

/// Point 3 of issue 28: a line read is no simple cross-site request (an `<img>` of another
/// site is a GET without `Origin`; a form of another site posts text, not JSON), and off the
/// loopback it needs the token as writes do.
#[tokio::test]
async fn a_misspelt_register_in_a_read_gets_a_did_you_mean() {
    let running = start(
        "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 50ms }
",
    );
    let router = console(&running, &loopback()).router();
    // The README walk's GET of a misspelt register: 404, the nearest name, and how to read.
    let (status, json) = call(&router, get("/api/devices/head/read/lihgt_power")).await;
    assert_eq!(status, StatusCode::NOT_FOUND, "{json}");
    assert_eq!(
        json["error"],
        "p-series has no register `lihgt_power`; did you mean `light_power`? (a register is \
         read with POST /api/devices/{device}/read and a JSON body {\"register\": \"…\"})"
    );
    // The same in the read itself.
    let (status, json) = call(
        &router,
        post("/api/devices/head/read", r#"{"register": "distanse_1"}"#),
    )
    .await;
    assert_eq!(status, StatusCode::NOT_FOUND, "{json}");
    assert_eq!(
        json["error"],
        "p-series has no register `distanse_1`; did you mean `distance_1`, `distance_2`?"
    );
    // Nothing near: the plain 404.
    let (status, json) = call(
        &router,
        post("/api/devices/head/read", r#"{"register": "xyzzy"}"#),
    )
    .await;
    assert_eq!(status, StatusCode::NOT_FOUND, "{json}");
    assert_eq!(json["error"], "p-series has no register `xyzzy`");
    // A device that is not there, on the GET too.
    let (status, json) = call(&router, get("/api/devices/tail/read/light_power")).await;
    assert_eq!(status, StatusCode::NOT_FOUND, "{json}");
    assert_eq!(json["error"], "the bus has no device `tail`");
}

#[tokio::test]
async fn console_line_reads_need_post_and_the_token_off_loopback() {
    let running = start(
        "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 50ms }
",
    );
    let router = console(&running, &loopback()).router();
    // What an `<img src=…>` of another page sends: a GET, no Origin.
    let (status, json) = call(&router, get("/api/devices/head/read/light_power")).await;
    assert_eq!(status, StatusCode::METHOD_NOT_ALLOWED, "{json}");
    assert!(
        json["error"]
            .as_str()
            .unwrap()
            .contains("POST /api/devices/{device}/read"),
        "{json}"
    );
    // What a form of another page sends: a POST of text.
    let form = Request::post("/api/devices/head/read")
        .header("host", ADDRESS)
        .header("content-type", "text/plain")
        .body(Body::from(r#"{"register": "light_power"}"#))
        .unwrap();
    let (status, json) = call(&router, form).await;
    assert_eq!(status, StatusCode::UNSUPPORTED_MEDIA_TYPE, "{json}");
    assert_eq!(read_frames(&running, "light_power"), 0, "nothing was read");
    let (status, json) = call(
        &router,
        post("/api/devices/head/read", r#"{"register": "light_power"}"#),
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{json}");
    assert_eq!(read_frames(&running, "light_power"), 1);

    // Off the loopback: no token file, no reads; with one, only with its token.
    let body = r#"{"register": "light_power"}"#;
    let open = HttpConfig::new("0.0.0.0:8080".parse().unwrap());
    let router = console(&running, &open).router();
    let (status, json) = call(&router, post("/api/devices/head/read", body)).await;
    assert_eq!(status, StatusCode::FORBIDDEN, "{json}");
    let token = std::env::temp_dir().join(format!("optobus-reads-{}.token", std::process::id()));
    std::fs::write(&token, "correct-horse-battery-staple\n").unwrap();
    let mut guarded = open.clone();
    guarded.token_file = Some(token.clone());
    let router = console(&running, &guarded).router();
    let (status, json) = call(&router, post("/api/devices/head/read", body)).await;
    assert_eq!(status, StatusCode::UNAUTHORIZED, "{json}");
    assert_eq!(
        json["error"],
        "writes and reads of the line need the console's token (Authorization: Bearer …)"
    );
    assert_eq!(
        read_frames(&running, "light_power"),
        1,
        "nothing more was read"
    );
    let mut right = post("/api/devices/head/read", body);
    right.headers_mut().insert(
        "authorization",
        "Bearer correct-horse-battery-staple".parse().unwrap(),
    );
    let (status, json) = call(&router, right).await;
    assert_eq!(status, StatusCode::OK, "{json}");
    assert_eq!(read_frames(&running, "light_power"), 2);
    let _ = std::fs::remove_file(token);
}

/// Point 3 of issue 28: 16 clients reading through the console as fast as they can get `429`
/// with `Retry-After` beyond the console's queue on the line, counted, and the polls go on.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flood_of_console_reads_is_answered_429_and_the_polls_go_on() {
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    use std::sync::Arc;
    let running = start(
        "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 500ms, poll: [{ read: distance_1, every: 100ms }] }
",
    );
    let router = console(&running, &loopback()).router();
    let mut events = running.subscribe();
    let stop = Arc::new(AtomicBool::new(false));
    let busy = Arc::new(AtomicU64::new(0));
    let mut clients = Vec::new();
    for _ in 0..16 {
        let (router, stop, busy) = (router.clone(), Arc::clone(&stop), Arc::clone(&busy));
        clients.push(tokio::spawn(async move {
            while !stop.load(Ordering::Relaxed) {
                let request = post("/api/devices/head/read", r#"{"register": "distance_1"}"#);
                let response = router.clone().oneshot(request).await.unwrap();
                match response.status() {
                    StatusCode::OK => {}
                    StatusCode::TOO_MANY_REQUESTS => {
                        assert_eq!(response.headers()["retry-after"], "1");
                        let body = axum::body::to_bytes(response.into_body(), 4096)
                            .await
                            .unwrap();
                        let json: Value = serde_json::from_slice(&body).unwrap();
                        let error = json["error"].as_str().unwrap();
                        assert!(error.starts_with("line `rs485` is busy"), "{error}");
                        busy.fetch_add(1, Ordering::Relaxed);
                        tokio::task::yield_now().await;
                    }
                    other => panic!("a read answered {other}"),
                }
            }
        }));
    }
    // Poll samples keep coming while the flood goes on (reads send no samples).
    let mut polled = 0;
    let deadline = tokio::time::Instant::now() + Duration::from_secs(60);
    while polled < 20 || busy.load(Ordering::Relaxed) == 0 {
        match tokio::time::timeout_at(deadline, events.recv()).await {
            Ok(Ok(optobus_bus::Event::Sample(_))) => polled += 1,
            Ok(_) => {}
            Err(_) => panic!(
                "{polled} poll samples and {} refusals within 60 s of the flood",
                busy.load(Ordering::Relaxed)
            ),
        }
    }
    stop.store(true, Ordering::Relaxed);
    for client in clients {
        client.await.unwrap();
    }
    let (_, status) = call(&router, get("/api/status")).await;
    assert_eq!(
        status["busy_refusals"].as_u64(),
        Some(busy.load(Ordering::Relaxed)),
        "every 429 is counted: {status}"
    );
}

/// Point 8 of issue 28: a client of the live stream that stops reading loses its oldest
/// batches, counted as they are dropped (not when it reads again), and is told how many when
/// it reads.
#[tokio::test]
async fn a_stalled_stream_client_counts_its_drops_as_they_happen() {
    use futures_util::StreamExt;
    let running = start(TWO);
    let console = console(&running, &loopback());
    let router = console.router();
    // A client that never reads its stream.
    let stalled = router.clone().oneshot(get("/api/stream")).await.unwrap();
    assert_eq!(stalled.status(), StatusCode::OK);
    let status = until(&router, "/api/status", |json| {
        json["dropped_batches"].as_u64().is_some_and(|n| n >= 3)
    })
    .await;
    assert_eq!(status["stream_clients"], 1);
    // It reads again: first told what it lost, as the console counted it.
    let mut body = stalled.into_body().into_data_stream();
    let chunk = tokio::time::timeout(Duration::from_secs(5), body.next())
        .await
        .expect("the stream answers")
        .unwrap()
        .unwrap();
    let text = std::str::from_utf8(&chunk).unwrap();
    let told: u64 = text
        .strip_prefix("event: dropped\ndata: ")
        .unwrap_or_else(|| panic!("told of its drops first: {text}"))
        .trim()
        .parse()
        .unwrap();
    assert!(told >= 3, "{text}");
    assert!(told <= console.dropped_batches());
    let chunk = tokio::time::timeout(Duration::from_secs(5), body.next())
        .await
        .expect("then a batch")
        .unwrap()
        .unwrap();
    assert!(std::str::from_utf8(&chunk).unwrap().starts_with("data: {"));
    drop(body);
    let status = until(&router, "/api/status", |json| json["stream_clients"] == 0).await;
    assert!(status["dropped_batches"].as_u64().unwrap() >= told);
}

/// Point 7 of issue 28: a down device's last values are not presented as current; its next
/// sample is.
#[tokio::test]
async fn a_down_devices_values_are_not_current_on_the_console() {
    let running = start(TWO);
    let router = console(&running, &loopback()).router();
    let current = |json: &Value, device: &str| -> Vec<Value> {
        json[device]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v["current"].clone())
            .collect()
    };
    let json = until(&router, "/api/values", |json| {
        json["head"].as_array().is_some_and(|v| !v.is_empty())
    })
    .await;
    assert!(current(&json, "head").iter().all(|c| *c == true), "{json}");
    running.simulator("head").unwrap().set_silent(true);
    let json = until(&router, "/api/devices", |json| {
        json["devices"][0]["health"] == "offline"
    })
    .await;
    assert_eq!(json["devices"][0]["device"], "head");
    let (_, json) = call(&router, get("/api/values")).await;
    let head = current(&json, "head");
    assert!(
        !head.is_empty() && head.iter().all(|c| *c == false),
        "{json}"
    );
    assert!(current(&json, "confocal").iter().all(|c| *c == true));
    running.simulator("head").unwrap().set_silent(false);
    until(&router, "/api/values", |json| {
        current(json, "head").iter().all(|c| *c == true)
    })
    .await;
}

// ---- the listener's limits, over real sockets (point 4 of issue 28) ----

/// Short limits, so that the tests wait little.
fn short(max_connections: usize) -> optobus_http::Limits {
    optobus_http::Limits {
        header_read: Duration::from_millis(300),
        idle: Duration::from_millis(300),
        request: Duration::from_millis(500),
        max_connections,
    }
}

/// Reads until the server closes the connection (or 20 s pass): what it sent.
async fn until_closed(stream: &mut tokio::net::TcpStream) -> String {
    use tokio::io::AsyncReadExt;
    let mut reply = Vec::new();
    let read = tokio::time::timeout(Duration::from_secs(20), stream.read_to_end(&mut reply));
    match read.await {
        Ok(Ok(_)) => {}
        Ok(Err(error)) if error.kind() == std::io::ErrorKind::ConnectionReset => {}
        Ok(Err(error)) => panic!("{error}"),
        Err(_) => panic!("the server kept the connection open for 20 s"),
    }
    String::from_utf8_lossy(&reply).into_owned()
}

/// One request on a new connection; the reply's text.
async fn over_socket(address: SocketAddr, request: &str) -> String {
    use tokio::io::AsyncWriteExt;
    let mut stream = tokio::net::TcpStream::connect(address).await.unwrap();
    stream.write_all(request.as_bytes()).await.unwrap();
    until_closed(&mut stream).await
}

fn status_request(address: SocketAddr) -> String {
    format!("GET /api/status HTTP/1.1\r\nHost: {address}\r\nConnection: close\r\n\r\n")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn silent_http_connections_are_closed_after_the_header_timeout() {
    use tokio::io::AsyncWriteExt;
    let running = start(TWO);
    let config = HttpConfig::new("127.0.0.1:0".parse().unwrap());
    let server = optobus_console::serve_with_limits(&running, &config, short(16))
        .await
        .unwrap();
    let address = server.address();
    // Says nothing.
    let mut silent = tokio::net::TcpStream::connect(address).await.unwrap();
    assert_eq!(until_closed(&mut silent).await, "");
    // Half a head, never finished.
    let mut half = tokio::net::TcpStream::connect(address).await.unwrap();
    half.write_all(format!("GET /api/status HTTP/1.1\r\nHost: {address}\r\n").as_bytes())
        .await
        .unwrap();
    assert_eq!(until_closed(&mut half).await, "");
    // A kept-alive connection, idle after its answer.
    let mut idle = tokio::net::TcpStream::connect(address).await.unwrap();
    idle.write_all(format!("GET /api/status HTTP/1.1\r\nHost: {address}\r\n\r\n").as_bytes())
        .await
        .unwrap();
    assert!(until_closed(&mut idle).await.starts_with("HTTP/1.1 200"));
    let counts = server.connections();
    assert_eq!(counts.header_timeouts, 2, "{counts:?}");
    assert_eq!(counts.idle_closed, 1, "{counts:?}");
    // The live stream is long-lived: it outlasts the request timeout.
    let mut stream = tokio::net::TcpStream::connect(address).await.unwrap();
    stream
        .write_all(format!("GET /api/stream HTTP/1.1\r\nHost: {address}\r\n\r\n").as_bytes())
        .await
        .unwrap();
    let mut seen = Vec::new();
    let deadline = tokio::time::Instant::now() + Duration::from_secs(3);
    while tokio::time::Instant::now() < deadline {
        use tokio::io::AsyncReadExt;
        let mut buffer = [0; 4096];
        match tokio::time::timeout_at(deadline, stream.read(&mut buffer)).await {
            Ok(Ok(0)) => panic!("the stream was closed"),
            Ok(Ok(n)) => seen.extend_from_slice(&buffer[..n]),
            Ok(Err(error)) => panic!("{error}"),
            Err(_) => break,
        }
    }
    let seen = String::from_utf8_lossy(&seen);
    assert!(seen.starts_with("HTTP/1.1 200"), "{seen}");
    assert!(seen.matches("data: {").count() >= 3, "{seen}");
    let status = over_socket(address, &status_request(address)).await;
    let body: Value = serde_json::from_str(status.split_once("\r\n\r\n").unwrap().1).unwrap();
    assert_eq!(body["connections"]["header_timeouts"], 2, "{body}");
    assert_eq!(body["connections"]["request_timeouts"], 0, "{body}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_request_not_answered_in_time_is_answered_408() {
    let running = start(
        "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 3s }
",
    );
    running.simulator("head").unwrap().set_silent(true);
    let config = HttpConfig::new("127.0.0.1:0".parse().unwrap());
    let server = optobus_console::serve_with_limits(&running, &config, short(16))
        .await
        .unwrap();
    let address = server.address();
    let body = r#"{"register": "light_power"}"#;
    let reply = over_socket(
        address,
        &format!(
            "POST /api/devices/head/read HTTP/1.1\r\nHost: {address}\r\ncontent-type: application/json\r\ncontent-length: {}\r\n\r\n{body}",
            body.len()
        ),
    )
    .await;
    assert!(reply.starts_with("HTTP/1.1 408"), "{reply}");
    assert!(
        reply.ends_with(r#"{"error": "the request was not answered within 0.5 s"}"#),
        "{reply}"
    );
    assert_eq!(server.connections().request_timeouts, 1);
}

/// The descriptors this process has open.
fn descriptors() -> usize {
    std::fs::read_dir("/proc/self/fd").map_or(0, |dir| dir.count())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn http_connections_beyond_the_cap_do_not_exhaust_descriptors() {
    let running = start(TWO);
    let config = HttpConfig::new("127.0.0.1:0".parse().unwrap());
    let mut limits = short(4);
    limits.header_read = Duration::from_secs(60);
    let server = optobus_console::serve_with_limits(&running, &config, limits)
        .await
        .unwrap();
    let address = server.address();
    let before = descriptors();
    let mut silent = Vec::new();
    for _ in 0..40 {
        silent.push(tokio::net::TcpStream::connect(address).await.unwrap());
    }
    for _ in 0..1000 {
        let counts = server.connections();
        if counts.accepted + counts.refused == 40 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let counts = server.connections();
    // 40 client sockets of the test, 4 on the server's side: the refused are closed.
    let held = descriptors() - before;
    assert!(held <= 40 + 4 + 4, "{held} descriptors for 40 connections");
    assert_eq!((counts.open, counts.refused), (4, 36), "{counts:?}");
    let refused = until_closed(silent.last_mut().unwrap()).await;
    assert!(refused.starts_with("HTTP/1.1 503"), "{refused}");
    assert!(refused.contains("retry-after: 1"), "{refused}");
    drop(silent);
    // Once they are gone, a client is served again.
    for _ in 0..1000 {
        if server.connections().open == 0 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let status = over_socket(address, &status_request(address)).await;
    assert!(status.starts_with("HTTP/1.1 200"), "{status}");
}

// ---- issue 29, points 5 and 6: numbers as written, the token's scheme, `Host` off the
// loopback; over real sockets, against a console served by the test ----

/// One request to the console at `address` on a new connection, `Host` and other headers as
/// given: the status and the JSON body of its reply.
async fn exchange(
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

/// Point 5 of issue 29: a JSON number is the text written in the body, never a float's
/// rounding of it: `0.49999999999999999999` and `100.00000000000000001` are refused for
/// `light_power` (0.5 % to 100 %) with the message their strings get, as `optobus set` refuses
/// them; an exact number and a string with its unit still go through.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn json_numbers_reach_the_value_parser_exactly_as_written() {
    let running = start(WRITABLE);
    let config = HttpConfig::new("127.0.0.1:0".parse().unwrap());
    let server = optobus_console::serve(&running, &config).await.unwrap();
    let address = server.address();
    let host = address.to_string();
    let set = |value: String| {
        let host = host.clone();
        async move {
            let body = format!(r#"{{"register": "light_power", "value": {value}}}"#);
            exchange(
                address,
                "POST",
                "/api/devices/head/set",
                &[("host", &host)],
                &body,
            )
            .await
        }
    };
    let before = light_power(&running);
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    for written in ["0.49999999999999999999", "100.00000000000000001"] {
        let as_string = set(format!("\"{written}\"")).await;
        let as_number = set(written.to_owned()).await;
        assert_eq!(as_string.0, 422, "{written} as a string: {}", as_string.1);
        assert_eq!(as_number, as_string, "{written} as a number");
        let error = optobus_inspect::parse_value(power, written).unwrap_err();
        assert_eq!(
            as_number.1["error"],
            optobus_inspect::Error::from(error).to_string()
        );
    }
    assert_eq!(light_power(&running), before);
    assert!(!wrote(&running), "nothing refused reaches the line");
    // Neither text nor a number: refused as before.
    for other in ["true", "null", "[0.5]", r#"{"value": 0.5}"#] {
        let (status, json) = set(other.to_owned()).await;
        assert_eq!(status, 422, "{other}: {json}");
        assert!(
            json["error"]
                .as_str()
                .unwrap()
                .starts_with(r#"`value` is text such as "12.5 %" or a number, not "#),
            "{other}: {json}"
        );
    }
    let (status, json) = set("0.5".to_owned()).await;
    assert_eq!(status, 200, "{json}");
    assert_eq!(json["text"], "0.5 %");
    assert_eq!(light_power(&running), Some(vec![5]));
    let (status, json) = set("\"12.5 %\"".to_owned()).await;
    assert_eq!(status, 200, "{json}");
    assert_eq!(light_power(&running), Some(vec![125]));
}

/// A token file with `token` in it, removed when dropped.
struct TokenFile(std::path::PathBuf);

impl TokenFile {
    fn new(name: &str, token: &str) -> Self {
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

/// Point 6 of issue 29: the scheme of `Authorization` is case-insensitive (RFC 9110, 11.1):
/// `bearer` and `BEARER` are the console's scheme, with one space or more before the token;
/// a wrong token and another scheme are still refused.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_authorization_scheme_is_taken_in_any_case() {
    let running = start(WRITABLE);
    let token = TokenFile::new("scheme", "correct-horse-battery-staple");
    let mut config = HttpConfig::new("127.0.0.1:0".parse().unwrap());
    config.token_file = Some(token.0.clone());
    let server = optobus_console::serve(&running, &config).await.unwrap();
    let address = server.address();
    let host = address.to_string();
    let set = |authorization: &'static str, value: &'static str| {
        let host = host.clone();
        async move {
            let body = format!(r#"{{"register": "light_power", "value": "{value}"}}"#);
            exchange(
                address,
                "POST",
                "/api/devices/head/set",
                &[("host", &host), ("authorization", authorization)],
                &body,
            )
            .await
        }
    };
    let needs = json!({"error": "writes and reads of the line need the console's token \
                                 (Authorization: Bearer …)"});
    let not_its = json!({"error": "the token is not the console's"});
    for (authorization, value, answer) in [
        (
            "Basic dXNlcjpjb3JyZWN0LWhvcnNl",
            "20 %",
            (401, needs.clone()),
        ),
        ("Bearer correct-horse", "20 %", (401, not_its.clone())),
        ("bearer correct-horse", "20 %", (401, not_its.clone())),
        (
            "Bearercorrect-horse-battery-staple",
            "20 %",
            (401, needs.clone()),
        ),
    ] {
        assert_eq!(set(authorization, value).await, answer, "{authorization}");
    }
    assert!(!wrote(&running), "nothing refused reaches the line");
    for (authorization, value, words) in [
        ("bearer correct-horse-battery-staple", "20 %", 200),
        ("BEARER   correct-horse-battery-staple", "30 %", 300),
        ("Bearer correct-horse-battery-staple", "40 %", 400),
    ] {
        let (status, json) = set(authorization, value).await;
        assert_eq!(status, 200, "{authorization}: {json}");
        assert_eq!(light_power(&running), Some(vec![words]), "{authorization}");
    }
}

/// Point 6 of issue 29: a console bound beyond the loopback answers only the `Host` names it
/// is told, so that a page whose name was made to resolve to it (DNS rebinding) is refused.
/// Bound to 0.0.0.0 without `hosts:`, any IP address with its port; with `hosts:`, those.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn off_loopback_the_console_answers_only_the_hosts_it_is_told() {
    let bus = "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 50ms }
";
    let running = start(bus);
    let open = HttpConfig::new("0.0.0.0:0".parse().unwrap());
    let server = optobus_console::serve(&running, &open).await.unwrap();
    let address = server.address();
    let port = address.port();
    let get = |host: String| async move {
        exchange(address, "GET", "/api/devices", &[("host", &host)], "").await
    };
    let refused = |host: &str| {
        let named = if host.is_empty() {
            "without a `Host`".to_owned()
        } else {
            format!("for `{host}`")
        };
        (
            421,
            json!({"error": format!(
                "the console does not answer requests {named}: a name it answers is listed \
                 in `hosts:` of the bus file's `http:` (against DNS rebinding)"
            )}),
        )
    };
    let evil = format!("evil.example:{port}");
    assert_eq!(get(evil.clone()).await, refused(&evil));
    for host in [
        format!("127.0.0.1:{port}"),
        format!("192.0.2.7:{port}"),
        format!("[::1]:{port}"),
        format!("[2001:db8::7]:{port}"),
        format!("localhost:{port}"),
    ] {
        let (status, json) = get(host.clone()).await;
        assert_eq!(status, 200, "{host}: {json}");
    }
    for host in [
        "127.0.0.1:1".to_owned(),
        "127.0.0.1".to_owned(),
        format!("plant-gw.example:{port}"),
        String::new(),
    ] {
        assert_eq!(get(host.clone()).await, refused(&host), "{host}");
    }
    // A long `Host` is not echoed whole.
    let long = format!("{}.example:{port}", "a".repeat(200));
    let (status, json) = get(long.clone()).await;
    assert_eq!(status, 421);
    let cut: String = long.chars().take(40).collect();
    assert_eq!(json, refused(&format!("{cut}…")).1);
    // A read of the line from a rebound page is refused before the token is asked for.
    let (status, json) = exchange(
        address,
        "POST",
        "/api/devices/head/read",
        &[("host", &evil)],
        r#"{"register": "light_power"}"#,
    )
    .await;
    assert_eq!((status, json), refused(&evil));
    drop(server);

    // `hosts:` from the bus file: those names only, at the console's port unless they say.
    let file = BusFile::parse(
        "bus.yaml",
        &format!("{bus}outputs:\n  http: {{ listen: 0.0.0.0:0, hosts: [plant-gw.example, \"192.0.2.7:80\"] }}\n"),
        Path::new("."),
        &Catalogue::new([&optobus_p_series::DEVICE]),
    )
    .unwrap_or_else(|e| panic!("{}", e.render()));
    let config = file.outputs.http.clone().unwrap();
    let server = optobus_console::serve(&running, &config).await.unwrap();
    let address = server.address();
    let port = address.port();
    let get = |host: String| async move {
        exchange(address, "GET", "/api/devices", &[("host", &host)], "").await
    };
    for host in [
        format!("plant-gw.example:{port}"),
        format!("Plant-GW.example:{port}"),
        "192.0.2.7".to_owned(),
        "192.0.2.7:80".to_owned(),
        // The loopback's names are answered always: no other site's page is named so.
        format!("127.0.0.1:{port}"),
        format!("localhost:{port}"),
    ] {
        let (status, json) = get(host.clone()).await;
        assert_eq!(status, 200, "{host}: {json}");
    }
    for host in [
        format!("evil.example:{port}"),
        "plant-gw.example".to_owned(),
        "plant-gw.example:1".to_owned(),
        format!("192.0.2.7:{port}"),
        format!("[::2]:{port}"),
    ] {
        assert_eq!(get(host.clone()).await, refused(&host), "{host}");
    }
    drop(server);
    // A configuration made in code is checked too.
    let mut malformed = config.clone();
    malformed.hosts = vec!["plant-gw.example:http".into()];
    let error = Console::new(&running, &malformed, "0.0.0.0:8080".parse().unwrap()).unwrap_err();
    assert!(
        error
            .to_string()
            .starts_with("the console's `hosts:` entry `plant-gw.example:http` is no host name"),
        "{error}"
    );
}
