//! `outputs: http:` read into [`HttpConfig`](optobus_console::HttpConfig) as the bus file is
//! read: the console's address, token file, origins and `Host` names, a bad one located.
//! (Moved from the bus crate's tests with the settings.)

use std::path::Path;

use optobus_bus::{BusFile, Catalogue};
use optobus_console::HttpConfig;

/// The file's console settings, or every problem of the file rendered.
fn parse(text: &str) -> Result<Option<HttpConfig>, String> {
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
    let mut http = None;
    BusFile::parse_with("bus.yaml", text, Path::new("."), &catalogue, &mut http)
        .map_err(|e| e.render())?;
    Ok(http)
}

#[test]
fn the_console_listens_on_loopback_unless_told_and_takes_a_token_file_and_origins() {
    let one_device = "
lines: [{ name: a, simulated: true }]
devices: [{ name: head, model: p-series }]
";
    let short = parse(&format!("{one_device}outputs: {{ http: 8081 }}\n")).expect("a port alone");
    let http = short.expect("http given");
    assert_eq!(http.listen, "127.0.0.1:8081".parse().unwrap());
    assert_eq!(http.token_file, None);
    let full = parse(&format!(
        "{one_device}outputs:\n  http: {{ listen: 0.0.0.0:9000, token_file: secret/console.token, \
         origins: [\"https://scada.example:8443/\"] }}\n"
    ))
    .expect("a full mapping");
    let http = full.expect("http given");
    assert_eq!(http.listen, "0.0.0.0:9000".parse().unwrap());
    assert_eq!(
        http.token_file.as_deref(),
        Some(Path::new("./secret/console.token"))
    );
    assert_eq!(http.origins, ["https://scada.example:8443"]);
    assert_eq!(parse(one_device).expect("no outputs"), None);
}

/// Point 6 of issue 29: the `Host` names a console answers (`hosts:`), checked as the file is
/// read; a malformed one is located at its line and column.
#[test]
fn the_consoles_hosts_are_read_and_a_malformed_one_is_located() {
    let one_device = "
lines: [{ name: a, simulated: true }]
devices: [{ name: head, model: p-series }]
";
    let bus = parse(&format!(
        "{one_device}outputs:\n  http: {{ listen: 0.0.0.0:8080, hosts: [Plant-GW.example, \
         \"192.0.2.7:80\", \"[2001:db8::7]\", \"gw-2.plant.example:8443\"] }}\n"
    ))
    .expect("good hosts");
    let http = bus.expect("http given");
    assert_eq!(
        http.hosts,
        [
            "plant-gw.example",
            "192.0.2.7:80",
            "[2001:db8::7]",
            "gw-2.plant.example:8443"
        ]
    );
    let rendered = parse(&format!(
        "{one_device}outputs:\n  http:\n    listen: 0.0.0.0:8080\n    hosts:\n      - plant-gw.example\n      - \"http://plant-gw.example/\"\n      - \"plant gw\"\n      - \"plant-gw.example:99999\"\n      - \"2001:db8::7\"\n      - \"*.example\"\n"
    ))
    .expect_err("malformed hosts");
    for (entry, line) in [
        ("http://plant-gw.example/", 9),
        ("plant gw", 10),
        ("plant-gw.example:99999", 11),
        ("2001:db8::7", 12),
        ("*.example", 13),
    ] {
        assert!(
            rendered.contains(&format!("`{entry}` is no host name")),
            "{entry}: {rendered}"
        );
        assert!(
            rendered.contains(&format!("bus.yaml:{line}:9")),
            "{entry} at line {line}: {rendered}"
        );
    }
    assert!(!rendered.contains("`plant-gw.example` is no"), "{rendered}");
    let empty = parse(&format!("{one_device}outputs:\n  http: {{ hosts: [] }}\n"));
    assert!(
        empty
            .expect_err("an empty list")
            .contains("`hosts` lists no name"),
        "an empty list would answer no one"
    );
}
