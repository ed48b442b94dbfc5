//! Bus files: what a good one reads as, and every problem of a bad one reported at once with
//! its place.

use std::path::Path;
use std::time::Duration;

use optobus_bus::{BusFile, Catalogue, Port};

fn catalogue() -> Catalogue {
    Catalogue::new([
        &optobus_p_series::DEVICE,
        &optobus_rangefinder::DEVICE,
        &optobus_ccs::DEVICE,
        &optobus_lc_rs::DEVICE,
        &optobus_ccf::DEVICE,
    ])
}

fn parse(text: &str) -> Result<BusFile, String> {
    BusFile::parse("bus.yaml", text, Path::new("."), &catalogue()).map_err(|e| e.render())
}

#[test]
fn a_bus_file_reads_into_lines_devices_and_polls() {
    let bus = parse(
        "
lines:
  - name: rs485
    serial: /dev/ttyUSB0
  - name: plant
    tcp: 192.168.0.10:502
devices:
  - name: left
    model: p-series
    line: rs485
    slave: 1
    timeout: 200ms
    retries: 1
    silence_after: 2ms
    poll:
      - read: measurements
        every: 100ms
        priority: 2
      - read: [distance_1, light_power]
  - name: right
    model: P_Series
    line: rs485
    slave: 2
  - name: remote
    model: p-series
    line: plant
    slave: 1
",
    )
    .expect("the file passes");
    assert_eq!(bus.lines.len(), 2);
    assert_eq!(bus.lines[0].port, Port::Serial("/dev/ttyUSB0".into()));
    let format = bus.lines[0].format.expect("a serial line has a format");
    assert_eq!(
        format.baud,
        optobus_p_series::DEVICE.rtu.unwrap().default_baud,
        "the devices' factory format"
    );
    assert_eq!(
        bus.lines[1].format, None,
        "Modbus TCP has no character format"
    );
    assert_eq!(
        bus.lines[0].broadcast_turnaround,
        Duration::from_millis(100)
    );
    let left = &bus.devices[0];
    assert_eq!((left.line, left.slave, left.retries), (0, 1, 1));
    assert_eq!(left.timeout, Duration::from_millis(200));
    assert_eq!(left.silence_after, Duration::from_millis(2));
    assert_eq!(left.polls[0].every, Some(Duration::from_millis(100)));
    assert_eq!(left.polls[0].priority, 2);
    assert!(left.polls[0]
        .registers
        .iter()
        .any(|r| r.name == "distance_1"));
    assert_eq!(left.polls[1].every, None, "as fast as the line allows");
    let names: Vec<&str> = left.polls[1].registers.iter().map(|r| r.name).collect();
    assert_eq!(names.len(), 2);
    assert!(names.contains(&"distance_1") && names.contains(&"light_power"));
    assert_eq!(
        bus.devices[1].device.family, "p_series",
        "model names in any spelling"
    );
    assert_eq!(bus.devices[2].line, 1);
}

#[test]
fn every_problem_is_reported_at_once_with_its_place() {
    let rendered = parse(
        "
lines:
  - name: a
    serial: /dev/ttyUSB0
  - name: a
    serial: /dev/ttyUSB0
    baud: 12345
devices:
  - name: one
    model: p-series
    line: a
    slave: 1
    poll: [{ read: distanse_1, every: 0ms }]
  - name: one
    model: p-series
    line: a
    slave: 1
  - name: three
    model: no-such-model
    line: a
    slave: 300
  - name: four
    model: ccs
    line: nowhere
    timeout: 25h
",
    )
    .expect_err("the file has problems");
    for expected in [
        "error[duplicate-line]: two lines are called `a`",
        "error[duplicate-port]: two lines use the port `/dev/ttyUSB0`",
        "error[duplicate-device]: two devices are called `one`",
        "error[duplicate-slave]: two devices on line `a` are slave 1",
        "p-series has no register or group `distanse_1`",
        "`every` must be more than",
        "there is no built-in model `no-such-model`",
        "`slave` must be a whole number from 1 to 247, not `300`",
        "there is no line `nowhere`",
        "`timeout` `25h` is too long: at most 24h",
        "--> bus.yaml:",
    ] {
        assert!(
            rendered.contains(expected),
            "missing {expected:?} in:\n{rendered}"
        );
    }
    // Located: the second line name points at line 5 of the file, column 11.
    assert!(rendered.contains("bus.yaml:5:11"), "{rendered}");
}

#[test]
fn a_line_format_the_manual_does_not_list_is_refused() {
    let rendered = parse(
        "
lines:
  - { name: a, serial: /dev/ttyUSB0, baud: 12345 }
devices:
  - { name: one, model: p-series, slave: 1 }
",
    )
    .expect_err("12345 baud is no rate of the P series");
    assert!(
        rendered.contains("error[line-format]: line `a` runs 12345 baud"),
        "{rendered}"
    );
    assert!(rendered.contains("any_format: true"), "{rendered}");
    let allowed = parse(
        "
lines:
  - { name: a, serial: /dev/ttyUSB0, baud: 12345, any_format: true }
devices:
  - { name: one, model: p-series, slave: 1 }
",
    );
    assert!(allowed.is_ok(), "{allowed:?}");
}

#[test]
fn devices_with_different_factory_formats_need_the_line_format() {
    let formats: Vec<_> = [
        &optobus_p_series::DEVICE,
        &optobus_ccs::DEVICE,
        &optobus_lc_rs::DEVICE,
        &optobus_rangefinder::DEVICE,
        &optobus_ccf::DEVICE,
    ]
    .iter()
    .filter_map(|d| {
        d.rtu
            .map(|r| (d.family, r.default_baud, r.parity, r.data_bits, r.stop_bits))
    })
    .collect();
    let differing = formats
        .iter()
        .find(|f| (f.1, f.2, f.3, f.4) != (formats[0].1, formats[0].2, formats[0].3, formats[0].4))
        .expect("two models differ at the factory");
    let text = format!(
        "
lines:
  - {{ name: a, serial: /dev/ttyUSB0 }}
devices:
  - {{ name: one, model: {}, slave: 1 }}
  - {{ name: two, model: {}, slave: 2 }}
",
        formats[0].0, differing.0
    );
    let rendered = parse(&text).expect_err("no common format");
    assert!(
        rendered.contains("have different factory formats"),
        "{rendered}"
    );
}

#[test]
fn unknown_keys_and_wrong_shapes_are_located() {
    let rendered = parse(
        "
lines:
  - name: a
    serial: /dev/ttyUSB0
    bauds: 9600
devices: {}
",
    )
    .expect_err("bad keys");
    assert!(rendered.contains("a line has no key `bauds`"), "{rendered}");
    assert!(rendered.contains("bus.yaml:5:5"), "{rendered}");
    assert!(
        rendered.contains("`devices` must be a list, not a mapping"),
        "{rendered}"
    );
}

#[test]
fn a_register_whose_read_changes_the_device_is_not_polled() {
    let side_effect = optobus_p_series::DEVICE
        .registers
        .iter()
        .find(|r| r.readable() && !r.read_is_repeatable())
        .expect("the P series' buffer page");
    let rendered = parse(&format!(
        "
lines: [{{ name: a, simulated: true }}]
devices:
  - {{ name: one, model: p-series, slave: 1, poll: [{{ read: {} }}] }}
",
        side_effect.name
    ))
    .expect_err("never polled");
    assert!(
        rendered.contains("changes the device, so it is not polled"),
        "{rendered}"
    );
}

#[test]
fn text_that_is_not_yaml_or_empty_is_refused() {
    assert!(parse("lines: [").unwrap_err().contains("error[yaml]"));
    assert!(parse("").unwrap_err().contains("the bus file is empty"));
}

#[test]
fn a_bus_file_with_anchors_and_aliases_is_refused_at_its_first_anchor() {
    // Nine aliases a level, twelve levels: expanded, billions of nodes; refused, none.
    let mut text = String::from("a: &a [x, x, x, x, x, x, x, x, x]\n");
    let mut previous = 'a';
    for name in "bcdefghijklm".chars() {
        text += &format!("{name}: &{name} [*{previous}, *{previous}, *{previous}, *{previous}, *{previous}, *{previous}, *{previous}, *{previous}, *{previous}]\n");
        previous = name;
    }
    text += "lines: *m\n";
    let rendered = parse(&text).expect_err("aliases are refused");
    assert!(rendered.contains("error[yaml-alias]"), "{rendered}");
    assert!(rendered.contains("bus.yaml:1:4"), "{rendered}");
}

#[test]
fn devices_and_oversized_files_are_refused_before_they_are_read() {
    let error = BusFile::load(Path::new("/dev/zero"), &catalogue()).unwrap_err();
    assert!(error.to_string().contains("not a regular file"), "{error}");
    let big = std::env::temp_dir().join(format!("optobus-big-bus-{}.yaml", std::process::id()));
    let file = std::fs::File::create(&big).unwrap();
    // Sparse: 17 MiB long, nothing written.
    file.set_len(17 * 1024 * 1024).unwrap();
    let error = BusFile::load(&big, &catalogue()).unwrap_err();
    let _ = std::fs::remove_file(&big);
    assert!(
        error
            .to_string()
            .contains("larger than the limit of 16 MiB"),
        "{error}"
    );
}

#[test]
fn writable_lists_what_the_network_may_write_and_all_leaves_out_drastic_commands() {
    let bus = parse(
        "
lines: [{ name: a, simulated: true }]
devices:
  - { name: open, model: p-series, slave: 1, writable: all }
  - { name: listed, model: p-series, slave: 2, writable: [light_power, laser, save_parameters] }
  - { name: closed, model: p-series, slave: 3 }
",
    )
    .unwrap();
    let device = &optobus_p_series::DEVICE;
    let [open, listed, closed] = [0, 1, 2].map(|i| &bus.devices[i].writable);
    let power = device.register("light_power").unwrap();
    let save = device.command("save_parameters").unwrap();
    let zero = device.command("zero_position_1").unwrap();
    // `all`: every writable register and harmless command, no drastic one, never the address.
    assert!(open.allows_register(power) && open.allows_command(zero));
    assert!(!open.allows_command(save) && !open.allows_command(device.command("reboot").unwrap()));
    for name in [
        "save_parameters",
        "network_reset_or_reboot",
        "slave_address",
    ] {
        assert!(
            !open.allows_register(device.register(name).unwrap()),
            "{name}"
        );
    }
    // A list: what it names (a group gives its writable members), a drastic command included.
    assert!(listed.allows_register(power) && listed.allows_command(save));
    assert!(listed.allows_register(device.register("laser_enabled").unwrap()));
    assert!(!listed.allows_command(zero));
    assert_eq!(listed.commands.len(), 1);
    // Nothing by default.
    assert!(closed.is_empty());
}

#[test]
fn writable_names_that_cannot_be_written_are_located() {
    let rendered = parse(
        "
lines: [{ name: a, simulated: true }]
devices:
  - name: head
    model: p-series
    slave: 1
    writable: [distance_1, slave_address, warp_drive]
",
    )
    .expect_err("three bad names");
    for (message, column) in [
        ("`distance_1` of p-series cannot be written", "7:16"),
        (
            "`slave_address` cannot be writable on a bus: the bus addresses the device by it",
            "7:28",
        ),
        (
            "p-series has no register, group or command `warp_drive`",
            "7:43",
        ),
    ] {
        assert!(rendered.contains(message), "{message}\n{rendered}");
        assert!(
            rendered.contains(&format!("bus.yaml:{column}")),
            "{column}\n{rendered}"
        );
    }
}

#[test]
fn a_gateways_idle_time_and_queue_are_read_with_their_defaults_and_bad_ones_located() {
    let bus = parse(
        "
lines:
  - { name: a, simulated: true, gateway: 5020 }
  - { name: b, simulated: true, gateway: { listen: 5021, clients: 4, queue: 2, idle: 1m 30s } }
devices: [{ name: head, model: p-series, line: a }]
",
    )
    .expect("the file passes");
    let defaults = bus.lines[0].gateway.as_ref().expect("a gateway");
    assert_eq!(
        (defaults.clients, defaults.queue, defaults.idle),
        (8, 8, Duration::from_secs(60)),
        "the queue holds a request per client; idle clients go after a minute"
    );
    let given = bus.lines[1].gateway.as_ref().expect("a gateway");
    assert_eq!(
        (given.clients, given.queue, given.idle),
        (4, 2, Duration::from_secs(90))
    );
    let rendered = parse(
        "
lines:
  - { name: a, simulated: true, gateway: { listen: 5020, clients: 0, queue: 0, idle: 0s } }
  - { name: b, simulated: true, gateway: { listen: 5021, idle: 60 } }
devices: [{ name: head, model: p-series, line: a }]
",
    )
    .expect_err("bad limits");
    for expected in [
        "`clients` must be a whole number from 1 to 1024, not `0`",
        "bus.yaml:3:67",
        "`queue` must be a whole number from 1 to 1024, not `0`",
        "bus.yaml:3:77",
        "`idle` must be more than 0s",
        "bus.yaml:3:86",
        "`idle` `60` needs a unit (ms, s, m, h)",
        "bus.yaml:4:64",
    ] {
        assert!(rendered.contains(expected), "{expected}: {rendered}");
    }
}

/// Issue 31, point 2: the bus reads no output's settings; it checks that `outputs` is a
/// mapping and leaves its sections to the outputs' crates (`optobus-service` reads them all).
#[test]
fn the_bus_alone_leaves_the_outputs_sections_unread_but_checks_their_shape() {
    let one_device = "
lines: [{ name: a, simulated: true }]
devices: [{ name: head, model: p-series }]
";
    let bus = parse(&format!(
        "{one_device}outputs:\n  mqtt: {{ qos: 7 }}\n  ftp: 21\n"
    ))
    .expect("sections the bus does not read");
    assert_eq!(bus.devices[0].name, "head");
    let rendered = parse(&format!("{one_device}outputs: [mqtt]\n")).expect_err("not a mapping");
    assert!(
        rendered.contains("`outputs` must be a mapping, not a list")
            && rendered.contains("bus.yaml:4:10"),
        "{rendered}"
    );
}

/// The diagnostics of a rejected file, for counting them.
fn rejected(text: &str) -> Box<optobus_bus::Rejected> {
    BusFile::parse("bus.yaml", text, Path::new("."), &catalogue()).expect_err("refused")
}

/// Point 4 of issue 30: a device whose model is misspelt stays in the checks across devices
/// and in its own: the slave it takes from another device and its `every: fast` are reported
/// with the model, not only once the model is mended.
#[test]
fn a_device_with_a_misspelt_model_does_not_drop_out_of_the_checks() {
    let text = "
lines:
  - name: rs485
    serial: /dev/ttyUSB0
devices:
  - name: top
    model: p-series
    slave: 1
  - name: range
    model: rangefinde
    slave: 1
    poll:
      - read: measurements
        every: fast
";
    let refused = rejected(text);
    let rendered = refused.render();
    assert_eq!(refused.diagnostics.len(), 3, "{rendered}");
    for expected in [
        "there is no built-in model `rangefinde`",
        "bus.yaml:10:12",
        "two devices on line `rs485` are slave 1",
        "bus.yaml:11:12",
        "`every` `fast`",
        "bus.yaml:14:16",
    ] {
        assert!(rendered.contains(expected), "{expected}: {rendered}");
    }
}

/// Point 4 of issue 30: a misspelt model, key, register, line or command name gets a "did you
/// mean" with the nearest names, as the command line gives for registers.
#[test]
fn misspelt_models_keys_and_names_get_a_did_you_mean() {
    let rendered = parse(
        "
lines:
  - name: rs485
    serial: /dev/ttyUSB0
    boud: 9600
devices:
  - name: range
    model: rangefinde
    timout: 200ms
  - name: top
    model: p-series
    line: rs458
    slave: 2
    poll: [{ read: [distanse_1, temprature], evry: 100ms }]
    writable: [light_powr]
",
    )
    .expect_err("misspelt");
    for expected in [
        "there is no built-in model `rangefinde`",
        "did you mean `rangefinder`?",
        "a device has no key `timout`",
        "did you mean `timeout`?",
        "a line has no key `boud`",
        "did you mean `baud`?",
        "there is no line `rs458`",
        "did you mean `rs485`?",
        "p-series has no register or group `distanse_1`",
        "did you mean `distance_1`, `distance_2`?",
        "p-series has no register or group `temprature`",
        "did you mean `temperature`?",
        "a poll has no key `evry`",
        "did you mean `every`?",
        "p-series has no register, group or command `light_powr`",
        "did you mean `light_power`?",
    ] {
        assert!(rendered.contains(expected), "{expected}: {rendered}");
    }
}

/// Point 4 of issue 30: `every` that is no duration says what else it takes: `fastest`.
#[test]
fn every_that_is_no_duration_mentions_fastest() {
    let rendered = parse(
        "
lines: [{ name: a, simulated: true }]
devices: [{ name: head, model: p-series, poll: [{ read: measurements, every: fast }] }]
",
    )
    .expect_err("`fast` is no period");
    assert!(rendered.contains("`every` `fast`"), "{rendered}");
    assert!(rendered.contains("`fastest`"), "{rendered}");
    assert!(rendered.contains("did you mean `fastest`?"), "{rendered}");
}

/// Point 4 of issue 30: YAML errors in a bus file speak of the bus file, not of a spec.
#[test]
fn yaml_errors_in_a_bus_file_say_the_bus_file_is_not_valid_yaml() {
    for text in [
        "lines: [",
        "lines: []\n---\ndevices: []\n",
        "a: &a [x]\nlines: *a\n",
    ] {
        let rendered = parse(text).expect_err("not a bus file");
        assert!(!rendered.contains("spec"), "{rendered}");
        assert!(
            rendered.contains("the bus file is not valid YAML")
                || rendered.contains("a bus file is one YAML document")
                || rendered.contains("bus files use no anchors or aliases"),
            "{rendered}"
        );
    }
    assert!(parse("lines: [")
        .unwrap_err()
        .contains("help: the bus file is not valid YAML"));
}

#[test]
fn typed_constructors_give_what_the_file_they_stand_for_reads_into() {
    use optobus_bus::{DeviceConfig, LineConfig, PollConfig};
    let file = parse(
        "lines: [{ name: line, simulated: true, baud: 9600, parity: none, data_bits: 8, stop_bits: 1 }]
devices: [{ name: head, model: p-series, slave: 7, poll: [{ read: measurements, every: 100ms }] }]
",
    )
    .unwrap();
    let device = &optobus_p_series::DEVICE;
    let mut format = file.lines[0].format.expect("a serial format");
    let line = LineConfig::new("line", Port::Simulated, format);
    assert_eq!(line, file.lines[0]);
    let mut head = DeviceConfig::new("head", device, 0, 7);
    head.polls
        .push(PollConfig::new(device, "measurements", Some(Duration::from_millis(100))).unwrap());
    let read = &file.devices[0];
    assert_eq!(
        (&head.name, &head.model, head.line, head.slave, head.timeout),
        (&read.name, &read.model, read.line, read.slave, read.timeout)
    );
    assert_eq!(
        (
            head.retries,
            head.silence_before,
            head.silence_after,
            head.power_up
        ),
        (
            read.retries,
            read.silence_before,
            read.silence_after,
            read.power_up
        )
    );
    assert!(head.faults.is_none() && read.faults.is_none());
    assert_eq!(head.writable.is_empty(), read.writable.is_empty());
    let names =
        |poll: &PollConfig| -> Vec<&str> { poll.registers.iter().map(|r| r.name).collect() };
    assert_eq!(head.polls.len(), read.polls.len());
    assert_eq!(names(&head.polls[0]), names(&read.polls[0]));
    assert!(!head.polls[0].registers.is_empty());
    assert_eq!(
        (
            &head.polls[0].names,
            head.polls[0].every,
            head.polls[0].priority
        ),
        (
            &read.polls[0].names,
            read.polls[0].every,
            read.polls[0].priority
        )
    );
    // A Modbus TCP line has no serial format, and its address needs a port, as in a file.
    format.baud = 19200;
    let tcp = LineConfig::new("plc", Port::tcp("10.0.0.5:502").unwrap(), format);
    assert_eq!(tcp.format, None);
    assert_eq!(
        Port::tcp("10.0.0.5").unwrap_err(),
        "`tcp` needs host:port, not `10.0.0.5`"
    );
    assert!(PollConfig::new(device, "no_such_register", None).is_err());
}

#[test]
fn a_one_device_bus_polls_the_measurements_group_as_the_file_it_stands_for() {
    use optobus_bus::{DeviceConfig, LineConfig};
    let file = parse(
        "lines: [{ name: line, simulated: true, baud: 9600, parity: none, data_bits: 8, stop_bits: 1 }]
devices: [{ name: head, model: p-series, slave: 7, poll: [{ read: measurements, every: 100ms }] }]
",
    )
    .unwrap();
    let device = &optobus_p_series::DEVICE;
    let format = file.lines[0].format.expect("a serial format");
    let head = DeviceConfig::new("head", device, 3, 7)
        .polling_measurements(Duration::from_millis(100))
        .unwrap();
    let one = BusFile::one_device(LineConfig::new("line", Port::Simulated, format), head);
    assert_eq!(one.lines, file.lines);
    let (built, read) = (&one.devices[0], &file.devices[0]);
    assert_eq!(built.line, 0);
    let names = |device: &DeviceConfig| -> Vec<(Vec<String>, Vec<&str>)> {
        let polls = device.polls.iter();
        let names = |p: &optobus_bus::PollConfig| p.registers.iter().map(|r| r.name).collect();
        polls.map(|p| (p.names.clone(), names(p))).collect()
    };
    assert_eq!(names(built), names(read));
    assert_eq!(built.polls[0].every, Some(Duration::from_millis(100)));
    assert!(one.measurements.plan.formulas.is_empty());
}
