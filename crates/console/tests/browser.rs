//! The page in a real browser: headless Chromium driven through chromedriver (WebDriver), one
//! session for every step to keep CI short. The page loads with no console error, values
//! change live, a record register's fields are rows of their own inside its card, an
//! out-of-range edit shows the server's refusal and leaves the simulator's
//! register as it was, a drastic command asks before it acts, a screenshot is written, and
//! the page's stream reconnects by itself when the server comes back after a stop; a
//! measurement shows its value, judgement badge, chart with limits and axes, and statistics.
//!
//! `.ci/run` installs `chromium` and `chromium-driver` and sets `OPTOBUS_REQUIRE_INTEROP=1`, so
//! there a missing browser fails the test; elsewhere it says it was skipped.
//! `OPTOBUS_UPDATE_SCREENSHOT=1` also writes the screenshot README shows.

use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use fantoccini::wd::{Capabilities, WebDriverCompatibleCommand};
use fantoccini::{Client, ClientBuilder, Locator};
use optobus_bus::{Bus, BusFile, Catalogue, Direction, Running};
use optobus_console::HttpConfig;
use optobus_device::Table;
use serde_json::{json, Value};

const CHROMIUM: &str = "/usr/bin/chromium";
const DRIVER: &str = "chromedriver";

const BUS: &str = "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 50ms, writable: [light_power, save_parameters], poll: [{ read: measurements, every: 50ms }] }
  - { name: confocal, model: ccs, slave: 2, timeout: 50ms, poll: [{ read: measurements, every: 100ms }] }
  - { name: ranger, model: rangefinder, slave: 3, timeout: 50ms, poll: [{ read: measurements, every: 100ms }] }
  - { name: bottom, model: p-series, slave: 4, timeout: 50ms, poll: [{ read: distance_1, every: 50ms }] }
measurements:
  - name: gap
    expr: 20mm - head.distance_1 - bottom.distance_1
    limits: { ll: 9.9mm, lo: 10mm, hi: 10.2mm, hh: 10.3mm }
    stats: 200
    max_skew: 1s
";

/// chromedriver on a free port, ended when dropped.
struct Driver(Child, u16);

impl Driver {
    fn start() -> Self {
        let port = TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let child = Command::new(DRIVER)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start chromedriver");
        Self(child, port)
    }
}

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Chrome's console log since the last call (chromedriver's `se/log`).
#[derive(Debug)]
struct BrowserLog;

impl WebDriverCompatibleCommand for BrowserLog {
    fn endpoint(
        &self,
        base: &url::Url,
        session: Option<&str>,
    ) -> Result<url::Url, url::ParseError> {
        base.join(&format!("session/{}/se/log", session.unwrap_or_default()))
    }

    fn method_and_body(&self, _: &url::Url) -> (http::Method, Option<String>) {
        (
            http::Method::POST,
            Some(json!({"type": "browser"}).to_string()),
        )
    }
}

async fn session(port: u16) -> Client {
    let mut capabilities = Capabilities::new();
    capabilities.insert("browserName".into(), json!("chrome"));
    capabilities.insert(
        "goog:chromeOptions".into(),
        json!({
            "binary": CHROMIUM,
            "args": ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--window-size=1400,1000"],
        }),
    );
    capabilities.insert("goog:loggingPrefs".into(), json!({"browser": "ALL"}));
    let connector = hyper_util::client::legacy::connect::HttpConnector::new();
    let address = format!("http://127.0.0.1:{port}");
    // chromedriver takes a moment to listen.
    for _ in 0..100 {
        match ClientBuilder::new(connector.clone())
            .capabilities(capabilities.clone())
            .connect(&address)
            .await
        {
            Ok(client) => return client,
            Err(_) => tokio::time::sleep(Duration::from_millis(100)).await,
        }
    }
    panic!("chromedriver did not start a session");
}

/// The console errors the page logged.
async fn console_errors(client: &Client) -> Vec<Value> {
    let log = client
        .issue_cmd(BrowserLog)
        .await
        .expect("the browser's log");
    log.as_array()
        .cloned()
        .unwrap_or_default()
        .into_iter()
        .filter(|entry| entry["level"] == "SEVERE")
        .collect()
}

async fn text_of(client: &Client, css: &str) -> String {
    let element = client.wait().for_element(Locator::Css(css)).await.unwrap();
    element.text().await.unwrap()
}

/// Clicks the element at `locator`.
async fn click(client: &Client, locator: Locator<'_>) {
    client
        .find(locator)
        .await
        .unwrap_or_else(|e| panic!("{locator:?} to click: {e}"))
        .click()
        .await
        .unwrap();
}

/// Waits until the text at `css` is one `ready` accepts.
async fn until_text(client: &Client, css: &str, ready: impl Fn(&str) -> bool) -> String {
    for _ in 0..100 {
        let text = text_of(client, css).await;
        if ready(&text) {
            return text;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    panic!("`{css}` never showed what was expected");
}

fn start_bus() -> Running {
    let catalogue = Catalogue::new([
        &optobus_p_series::DEVICE,
        &optobus_ccs::DEVICE,
        &optobus_rangefinder::DEVICE,
    ]);
    let file = BusFile::parse("bus.yaml", BUS, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()));
    Bus::new(file).start().unwrap()
}

async fn values_change_live(client: &Client) {
    let css = "[data-value='head/distance_1']";
    let first = until_text(client, css, |t| t.ends_with(" mm")).await;
    let later = until_text(client, css, |t| t != first && t.ends_with(" mm")).await;
    assert_ne!(first, later);
}

/// Issue 30, point 5: the rangefinder's `measurement_results` (a record) shows a row per
/// field of its spec, each with its unit, and nothing overflows the card or hides the
/// `error_status` row beside it.
async fn point_5_a_records_fields_are_rows_of_their_own_inside_its_card(client: &Client) {
    until_text(client, "[data-value='ranger/error_status']", |t| {
        !t.is_empty()
    })
    .await;
    let (card_width, content_width, status_right, card_right): (f64, f64, f64, f64) = {
        let measured = client
            .execute(
                "const card = document.querySelector(\"article[data-device='ranger']\");
                 const status = document.querySelector(\"[data-value='ranger/error_status']\");
                 return [card.clientWidth, card.scrollWidth,
                         status.getBoundingClientRect().right, card.getBoundingClientRect().right];",
                vec![],
            )
            .await
            .unwrap();
        serde_json::from_value(measured).unwrap()
    };
    assert!(
        content_width <= card_width && status_right <= card_right,
        "the ranger's card overflows: {content_width} px of content in {card_width} px, \
         error_status ends at {status_right} px, the card at {card_right} px"
    );
    for (field, unit) in [
        ("distance", " mm"),
        ("signal_strength", " uV"),
        ("temperature", " degC"),
    ] {
        let css = format!("[data-value='ranger/measurement_results.{field}']");
        until_text(client, &css, |t| t.ends_with(unit) || t == "invalid").await;
    }
    let group = text_of(client, "article[data-device='ranger'] tr.group").await;
    assert_eq!(group, "measurement_results");
}

async fn an_out_of_range_edit_shows_the_refusal_and_changes_nothing(
    client: &Client,
    running: &Running,
) {
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    let head = running.simulator("head").unwrap();
    let before = head.peek(Table::Holding, power.address);
    // The head's card's Registers button.
    click(
        client,
        Locator::XPath("//article[@data-device='head']//button[text()='Registers']"),
    )
    .await;
    let row = "tr[data-register='light_power']";
    let input = client
        .wait()
        .for_element(Locator::Css(&format!("{row} input")))
        .await
        .unwrap();
    input.send_keys("150 %").await.unwrap();
    click(
        client,
        Locator::Css(&format!("{row} button[data-action='set']")),
    )
    .await;
    let refusal = until_text(client, &format!("{row} .refusal"), |t| !t.is_empty()).await;
    assert!(refusal.contains("light_power"), "{refusal}");
    assert_eq!(head.peek(Table::Holding, power.address), before);
    // A valid value goes through and is the device's afterwards.
    input.clear().await.unwrap();
    input.send_keys("12.5").await.unwrap();
    click(
        client,
        Locator::Css(&format!("{row} button[data-action='set']")),
    )
    .await;
    let accepted = until_text(client, &format!("{row} .accepted"), |t| !t.is_empty()).await;
    assert_eq!(accepted, "set: 12.5 %");
    assert_eq!(head.peek(Table::Holding, power.address), Some(vec![125]));
}

/// The page reads a register now with a POST (a line read is no simple cross-site request).
async fn a_register_is_read_with_a_post(client: &Client) {
    let row = "tr[data-register='light_power']";
    click(
        client,
        Locator::Css(&format!("{row} button[data-action='read']")),
    )
    .await;
    let read = until_text(client, &format!("{row} td.num"), |t| !t.is_empty()).await;
    assert_eq!(read, "12.5 %");
}

/// The class of the element at `css`.
async fn class_of(client: &Client, css: &str) -> String {
    let element = client.wait().for_element(Locator::Css(css)).await.unwrap();
    element.attr("class").await.unwrap().unwrap_or_default()
}

/// Point 7 of issue 28: a down device's last values stay on screen marked as not current,
/// until it answers again.
async fn a_down_devices_values_are_marked_not_current(client: &Client, running: &Running) {
    let value = "[data-value='head/distance_1']";
    assert!(!class_of(client, value).await.contains("stale"));
    let head = running.simulator("head").unwrap();
    head.set_silent(true);
    until_text(client, "article[data-device='head'] .health", |t| {
        t == "offline"
    })
    .await;
    let class = class_of(client, value).await;
    assert!(class.contains("stale"), "{class}");
    // Another device's values are current still.
    let other = class_of(client, "[data-value='confocal/distance_1']").await;
    assert!(!other.contains("stale"), "{other}");
    head.set_silent(false);
    for _ in 0..100 {
        if !class_of(client, value).await.contains("stale") {
            return;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    panic!("the head's values never became current again");
}

/// Whether the head's frames hold a write of the command register of `command`.
fn wrote_command(running: &Running, command: &str) -> bool {
    let info = optobus_p_series::DEVICE
        .commands
        .iter()
        .find(|c| c.name == command)
        .unwrap();
    let register = optobus_p_series::DEVICE.register(info.register).unwrap();
    let [high, low] = register.address.to_be_bytes();
    running
        .handle()
        .frames("head")
        .unwrap()
        .iter()
        .any(|f| f.direction == Direction::Sent && f.bytes[1] == 6 && f.bytes[2..4] == [high, low])
}

async fn a_drastic_command_asks_before_it_acts(client: &Client, running: &Running) {
    click(client, Locator::Css("button[data-tab='commands']")).await;
    let save = "button[data-command='save_parameters']";
    click(client, Locator::Css(save)).await;
    let question = client.get_alert_text().await.expect("a confirmation");
    assert!(question.contains("save_parameters"), "{question}");
    client.dismiss_alert().await.unwrap();
    until_text(client, "#command-result", |t| {
        t == "save_parameters: not done"
    })
    .await;
    assert!(!wrote_command(running, "save_parameters"));
    click(client, Locator::Css(save)).await;
    client.accept_alert().await.unwrap();
    until_text(client, "#command-result", |t| t == "save_parameters: done").await;
    assert!(wrote_command(running, "save_parameters"));
}

/// The texts of the elements at `css`.
async fn texts(client: &Client, css: &str) -> Vec<String> {
    let found = client
        .execute(
            "return [...document.querySelectorAll(arguments[0])].map((e) => e.textContent);",
            vec![json!(css)],
        )
        .await
        .unwrap();
    serde_json::from_value(found).unwrap()
}

/// Whether `text` is a clock time, `14:05:09`.
fn is_clock(text: &str) -> bool {
    let bytes = text.as_bytes();
    bytes.len() == 8
        && bytes.iter().enumerate().all(|(i, b)| {
            if i == 2 || i == 5 {
                *b == b':'
            } else {
                b.is_ascii_digit()
            }
        })
}

/// Issue 32, point 5: a measurement shows its value with its unit, its judgement as a badge
/// (a colour and a text), a chart with its limits and axes (values in its unit, clock times),
/// and its statistics; the devices' charts have axes and a time scale too. Then a screenshot
/// of it (`OPTOBUS_UPDATE_SCREENSHOT=1`: `docs/measurements.png`, which the README shows).
async fn a_measurement_shows_its_value_badge_limits_axes_and_statistics(client: &Client) {
    let value = until_text(client, "[data-measurement-value='gap']", |t| {
        t.ends_with(" mm")
    })
    .await;
    let number: f64 = value.trim_end_matches(" mm").parse().expect("a number");
    assert!((9.0..11.0).contains(&number), "{value}");
    let badge = until_text(client, "[data-badge='gap']", |t| !t.is_empty()).await;
    assert!(
        ["LL ▼▼", "LO ▼", "GO ✓", "HI ▲", "HH ▲▲"].contains(&badge.as_str()),
        "{badge}"
    );
    let class = class_of(client, "[data-badge='gap']").await;
    assert!(class.contains("judgement-"), "{class}");
    // Enough values for a line and three clock times apart.
    tokio::time::sleep(Duration::from_secs(3)).await;
    let chart = "[data-chart='measurement:gap']";
    let limits = client
        .execute(
            "return [...document.querySelectorAll(arguments[0] + ' [data-limit]')]
                 .map((l) => l.dataset.limit);",
            vec![json!(chart)],
        )
        .await
        .unwrap();
    assert_eq!(limits, json!(["ll", "lo", "hi", "hh"]));
    let times = texts(client, &format!("{chart} [data-axis='time']")).await;
    assert_eq!(times.len(), 3, "{times:?}");
    assert!(times.iter().all(|t| is_clock(t)), "{times:?}");
    let values = texts(client, &format!("{chart} [data-axis='value']")).await;
    assert_eq!(values.len(), 3, "{values:?}");
    assert!(values.iter().all(|v| v.ends_with(" mm")), "{values:?}");
    let path = texts(client, &format!("{chart} path.values")).await;
    assert_eq!(path.len(), 1);
    // The statistics as the bus computed them.
    let stat = |name: &str| format!("[data-measurement='gap'] [data-stat='{name}']");
    let count = until_text(client, &stat("count"), |t| t.parse::<u64>().is_ok()).await;
    assert!(count.parse::<u64>().unwrap() >= 1);
    for name in ["mean", "min", "max", "range"] {
        let text = text_of(client, &stat(name)).await;
        assert!(text.ends_with(" mm"), "{name}: {text}");
    }
    let cpk = text_of(client, &stat("cpk")).await;
    assert!(cpk == "—" || cpk.parse::<f64>().is_ok(), "{cpk}");
    let counts = until_text(client, "[data-counts='gap']", |t| t.starts_with("OK ")).await;
    assert!(counts.contains("NG "), "{counts}");
    // A device's chart: a time scale and a value axis too.
    let device = "[data-chart='head/distance_1']";
    let times = texts(client, &format!("{device} [data-axis='time']")).await;
    assert!(
        times.len() >= 2 && times.iter().all(|t| is_clock(t)),
        "{times:?}"
    );
    assert_eq!(
        texts(client, &format!("{device} [data-axis='value']"))
            .await
            .len(),
        3
    );

    client
        .execute("window.scrollTo(0, 0)", vec![])
        .await
        .unwrap();
    // Taken while it has a value (the simulator's heads now and then read invalid).
    until_text(client, "[data-measurement-value='gap']", |t| {
        t.ends_with(" mm")
    })
    .await;
    let png = client.screenshot().await.unwrap();
    assert_eq!(png[..8], *b"\x89PNG\r\n\x1a\n");
    let artifact = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("measurements.png");
    std::fs::write(&artifact, &png).unwrap();
    eprintln!("screenshot: {}", artifact.display());
    if std::env::var_os("OPTOBUS_UPDATE_SCREENSHOT").is_some() {
        let docs = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs");
        std::fs::create_dir_all(&docs).unwrap();
        std::fs::write(docs.join("measurements.png"), &png).unwrap();
    }
}

async fn a_screenshot_is_written(client: &Client) {
    click(client, Locator::Css("button[data-tab='registers']")).await;
    client
        .execute("window.scrollTo(0, 0)", vec![])
        .await
        .unwrap();
    let png = client.screenshot().await.unwrap();
    assert_eq!(png[..8], *b"\x89PNG\r\n\x1a\n");
    let artifact = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("console.png");
    std::fs::write(&artifact, &png).unwrap();
    eprintln!("screenshot: {}", artifact.display());
    if std::env::var_os("OPTOBUS_UPDATE_SCREENSHOT").is_some() {
        std::fs::write(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("screenshot.png"),
            &png,
        )
        .unwrap();
    }
}

async fn the_stream_reconnects_after_the_server_restarts(
    client: &Client,
    server: optobus_console::Server,
    running: &Running,
) -> optobus_console::Server {
    let address = server.address();
    drop(server);
    until_text(client, "#link", |t| t == "stream: reconnecting…").await;
    let config = HttpConfig::new(address);
    let server = optobus_console::serve(running, &config).await.unwrap();
    until_text(client, "#link", |t| t == "stream: live").await;
    values_change_live(client).await;
    server
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(all(peer_chromium, peer_chromedriver)),
    ignore = "chromium or chromedriver is not installed (Debian packages chromium, chromium-driver)"
)]
async fn the_page_in_a_real_browser() {
    let running = start_bus();
    let config = HttpConfig::new("127.0.0.1:0".parse().unwrap());
    let server = optobus_console::serve(&running, &config).await.unwrap();
    let driver = Driver::start();
    let client = session(driver.1).await;
    client.goto(&server.url()).await.unwrap();
    assert_eq!(client.title().await.unwrap(), "optobus console");
    values_change_live(&client).await;
    point_5_a_records_fields_are_rows_of_their_own_inside_its_card(&client).await;
    a_measurement_shows_its_value_badge_limits_axes_and_statistics(&client).await;
    let errors = console_errors(&client).await;
    assert!(errors.is_empty(), "the page logged errors: {errors:?}");
    an_out_of_range_edit_shows_the_refusal_and_changes_nothing(&client, &running).await;
    a_register_is_read_with_a_post(&client).await;
    a_drastic_command_asks_before_it_acts(&client, &running).await;
    a_screenshot_is_written(&client).await;
    // Chromium logs the refused edit's 422 as a failed resource: that one is expected.
    let errors: Vec<Value> = console_errors(&client)
        .await
        .into_iter()
        .filter(|e| {
            let message = e["message"].as_str().unwrap_or_default();
            !(e["source"] == "network"
                && message.contains("/api/devices/head/set")
                && message.contains("422"))
        })
        .collect();
    assert!(errors.is_empty(), "the page logged errors: {errors:?}");
    a_down_devices_values_are_marked_not_current(&client, &running).await;
    // Last, as the browser logs the refused connections while the server is away.
    let server = the_stream_reconnects_after_the_server_restarts(&client, server, &running).await;
    client.close().await.unwrap();
    drop(server);
    drop(driver);
}
