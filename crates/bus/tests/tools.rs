//! What tools ask of a bus file beyond reading it: the one catalogue of models a tool and its
//! bus files share, and the gateway a tool moves to another address.

use std::path::Path;

use optobus_bus::{BusFile, Catalogue};

fn parse(text: &str) -> Result<BusFile, String> {
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
    BusFile::parse("bus.yaml", text, Path::new("."), &catalogue).map_err(|e| e.render())
}

/// Issue 31, one catalogue: the spec files a tool is given (`--spec`) and those its bus files
/// name are read once each, each path is its own model, and a bus file gets the very model
/// the tool got from the same catalogue (the tool and the bus kept a catalogue each, and the
/// tool's kept the first path's model for any other). Moved here from the tool's models.
#[test]
fn one_catalogue_reads_each_spec_file_once_for_the_tool_and_its_bus_files() {
    const SPECS: &[(&str, &str)] = &[
        (
            "ccs.yaml",
            include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/../../specs/ccs.yaml")),
        ),
        (
            "p_series.yaml",
            include_str!(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../../specs/p_series.yaml"
            )),
        ),
    ];
    let catalogue = Catalogue::of_specs(SPECS);
    let dir = std::env::temp_dir().join(format!("optobus-catalogue-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch directory");
    let [(first_name, first), (second_name, second)] = SPECS else {
        panic!("two specs");
    };
    let (first_path, second_path) = (dir.join(first_name), dir.join(second_name));
    std::fs::write(&first_path, first).expect("written");
    std::fs::write(&second_path, second).expect("written");

    let from_first = catalogue.load(&first_path).expect("the spec passes");
    let from_second = catalogue.load(&second_path).expect("the spec passes");
    assert_ne!(
        from_first.family, from_second.family,
        "each path is its own model"
    );
    let again = catalogue.load(&first_path).expect("the spec passes");
    assert!(std::ptr::eq(from_first, again), "a path is read once");

    let text = format!(
        "lines:\n  - {{ name: sim, simulated: true }}\n\
         devices:\n  - {{ name: d, spec: {first_name}, slave: 1 }}\n"
    );
    let file = BusFile::parse("bus.yaml", &text, &dir, &catalogue)
        .unwrap_or_else(|rejected| panic!("{rejected}"));
    assert!(
        std::ptr::eq(file.devices[0].device, from_first),
        "the bus file's model is the one the tool read"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Issue 31, the gateway a tool moves (`optobus run --gateway`) is picked by the bus file, not
/// by the tool: the one gateway moves keeping its settings, else the one RTU line gets a
/// read-only one, and which one is meant must be plain.
#[test]
fn a_gateway_moves_to_the_one_it_can_mean_and_several_are_refused_by_name() {
    use optobus_bus::GatewayMoveError;
    let address: std::net::SocketAddr = "127.0.0.1:6020".parse().expect("an address");
    // A bus file holds a device; on the first line.
    let parse = |lines: &str| {
        let line = lines
            .split("name: ")
            .nth(1)
            .and_then(|rest| rest.split(',').next())
            .unwrap_or("a");
        parse(&format!(
            "{lines}devices:\n  - {{ name: d, model: p-series, line: {line}, slave: 1 }}\n"
        ))
    };

    let mut one_rtu = parse(
        "lines:\n  - { name: a, serial: /dev/ttyUSB0 }\n  - { name: t, tcp: 10.0.0.1:502 }\n",
    )
    .expect("passes");
    one_rtu.move_gateway(address).expect("moved");
    let gateway = one_rtu.lines[0]
        .gateway
        .as_ref()
        .expect("a gateway on the RTU line");
    assert_eq!((gateway.listen, gateway.writes), (address, false));
    assert!(one_rtu.lines[1].gateway.is_none());

    let mut given = parse(
        "lines:\n  - { name: a, serial: /dev/ttyUSB0 }\n  - { name: b, serial: /dev/ttyUSB1, gateway: { listen: 5021, clients: 4 } }\n",
    )
    .expect("passes");
    given.move_gateway(address).expect("moved");
    let gateway = given.lines[1].gateway.as_ref().expect("its gateway");
    assert_eq!((gateway.listen, gateway.clients), (address, 4));
    assert!(given.lines[0].gateway.is_none());

    let mut two_rtu = parse(
        "lines:\n  - { name: a, serial: /dev/ttyUSB0 }\n  - { name: b, serial: /dev/ttyUSB1 }\n",
    )
    .expect("passes");
    let refused = two_rtu.move_gateway(address).unwrap_err();
    assert_eq!(
        refused,
        GatewayMoveError::SeveralRtuLines {
            lines: vec!["a".into(), "b".into()]
        }
    );
    assert_eq!(
        refused.to_string(),
        "which line should it serve? The bus file has RTU lines `a`, `b`"
    );

    let mut tcp_only = parse("lines:\n  - { name: t, tcp: 10.0.0.1:502 }\n").expect("passes");
    assert_eq!(
        tcp_only.move_gateway(address),
        Err(GatewayMoveError::NoRtuLine)
    );
}
