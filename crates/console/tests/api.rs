//! The console's JSON API, asked through its router: real values from a simulated bus, the
//! register map from the spec, frames as they went, the page and the live stream.

mod common;

use common::*;

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
