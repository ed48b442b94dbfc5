//! Writes through the console's API: set and do as `optobus set` and `optobus do` check them,
//! every bad request refused with a 4xx and the tool's one-line message, the token off the
//! loopback, the data buffer, a device going offline.

mod common;

use common::*;

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
