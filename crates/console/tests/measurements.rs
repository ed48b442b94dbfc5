//! Issue 32 on the console: the bus file's measurements through the JSON API on a running
//! simulated bus (`GET /api/measurements`, and the live stream), each value as the bus computed
//! it, with its limits, judgement, statistics and recent values.

use std::path::Path;
use std::time::Duration;

use axum::body::Body;
use axum::http::{Request, StatusCode};
use axum::Router;
use optobus_bus::{Bus, BusFile, Catalogue, Running};
use optobus_console::HttpConfig;
use serde_json::Value;
use tower::ServiceExt;

fn start() -> Running {
    let gap = optobus_testkit::bus_files::two_heads_gap()
        .timeout("50ms")
        .unit("mm")
        .limits("{ lo: 9.9mm, hi: 10.1mm, hh: 12mm, hysteresis: 0.001mm }")
        .stats(50)
        .text();
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
    let file = BusFile::parse("bus.yaml", &gap, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()));
    Bus::new(file).start().unwrap()
}

fn router(running: &Running) -> Router {
    let config = HttpConfig::new("127.0.0.1:8080".parse().unwrap());
    optobus_console::Console::new(running, &config, config.listen)
        .unwrap()
        .router()
}

fn get(path: &str) -> Request<Body> {
    Request::get(path)
        .header("host", "127.0.0.1:8080")
        .body(Body::empty())
        .unwrap()
}

async fn measurements(router: &Router) -> Value {
    let response = router
        .clone()
        .oneshot(get("/api/measurements"))
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    let bytes = axum::body::to_bytes(response.into_body(), 1 << 22)
        .await
        .unwrap();
    serde_json::from_slice(&bytes).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_measurements_json_has_each_value_with_its_limits_judgement_statistics_and_history() {
    let running = start();
    let router = router(&running);
    let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
    let json = loop {
        let json = measurements(&router).await;
        let gap = &json["measurements"][0];
        if gap["history"].as_array().is_some_and(|h| h.len() >= 5)
            && gap["latest"]["value"].is_string()
        {
            break json;
        }
        assert!(tokio::time::Instant::now() < deadline, "no values: {json}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    let list = json["measurements"].as_array().unwrap();
    assert_eq!(list.len(), 1);
    let gap = &list[0];
    assert_eq!(gap["measurement"], "gap");
    assert_eq!(gap["unit"], "mm");
    assert_eq!(
        gap["limits"],
        serde_json::json!({ "ll": null, "lo": 9.9, "hi": 10.1, "hh": 12.0 })
    );
    let latest = &gap["latest"];
    assert_eq!(latest["measurement"], "gap");
    assert_eq!(latest["unit"], "mm");
    let text = latest["value"].as_str().unwrap();
    let number = latest["number"].as_f64().unwrap();
    assert_eq!(text.parse::<f64>().unwrap(), number, "{latest}");
    assert!(latest["reason"].is_null());
    let judgement = latest["judgement"].as_str().unwrap();
    assert!(["lo", "go", "hi", "hh"].contains(&judgement), "{latest}");
    assert!(latest["skew_us"].is_u64());
    let stats = &latest["stats"];
    let count = stats["count"].as_u64().unwrap();
    assert!((1..=50).contains(&count), "{stats}");
    let (min, max) = (
        stats["min"].as_f64().unwrap(),
        stats["max"].as_f64().unwrap(),
    );
    assert!(min <= number && number <= max, "{latest}");
    for key in ["mean", "range"] {
        assert!(stats[key].is_f64(), "{stats}");
    }
    // Cp and Cpk where both lo and hi are given (null only without spread).
    assert!(stats.get("cp").is_some() && stats.get("cpk").is_some());
    // The recent values end with the latest.
    let history = gap["history"].as_array().unwrap();
    let last = history.last().unwrap();
    assert_eq!(last[0].as_f64(), latest["time"].as_f64());
    assert_eq!(last[1].as_f64(), Some(number));
    assert!(history
        .windows(2)
        .all(|w| w[0][0].as_f64() <= w[1][0].as_f64()));
    // The judgement counts, as the bus's handle gives them.
    let counts = &gap["counts"];
    let total: u64 = ["ll", "lo", "go", "hi", "hh"]
        .iter()
        .map(|k| counts[k].as_u64().unwrap())
        .sum();
    assert!(total >= history.len() as u64, "{counts}");
    eprintln!("gap {text} {judgement} stats {stats}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_stream_carries_each_measurement_value() {
    use futures_util::StreamExt;
    let running = start();
    let router = router(&running);
    let response = router.oneshot(get("/api/stream")).await.unwrap();
    let mut body = response.into_body().into_data_stream();
    let mut heard = Vec::new();
    while heard.len() < 3 {
        let chunk = tokio::time::timeout(Duration::from_secs(10), body.next())
            .await
            .expect("a batch within 10 s")
            .unwrap()
            .unwrap();
        let text = std::str::from_utf8(&chunk).unwrap();
        for data in text.lines().filter_map(|l| l.strip_prefix("data: ")) {
            let batch: Value = serde_json::from_str(data).unwrap();
            heard.extend(batch["measurements"].as_array().unwrap().iter().cloned());
        }
    }
    for value in heard {
        assert_eq!(value["measurement"], "gap");
        assert_eq!(value["unit"], "mm");
        match value["value"].as_str() {
            Some(text) => assert_eq!(text.parse::<f64>().ok(), value["number"].as_f64()),
            None => assert!(value["reason"].is_string(), "{value}"),
        }
    }
}
