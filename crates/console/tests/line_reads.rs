//! Reads on the line through the console (issue 28, points 3, 7 and 8): no simple cross-site
//! request, `429` beyond the console's queue, a stalled stream client's drops counted, a down
//! device's values not shown as current.

mod common;

use common::*;

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
