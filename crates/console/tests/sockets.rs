//! Over real sockets, against a console served by the test (issue 29, points 5 and 6): JSON
//! numbers exactly as written, the token's scheme in any case, `Host` off the loopback.

mod common;

use common::*;

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
    let mut http: Option<HttpConfig> = None;
    BusFile::parse_with(
        "bus.yaml",
        &format!("{bus}outputs:\n  http: {{ listen: 0.0.0.0:0, hosts: [plant-gw.example, \"192.0.2.7:80\"] }}\n"),
        Path::new("."),
        &Catalogue::new([&optobus_p_series::DEVICE]),
        &mut http,
    )
    .unwrap_or_else(|e| panic!("{}", e.render()));
    let config = http.unwrap();
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
