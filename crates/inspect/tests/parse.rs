//! What people type, read as the library reads it: hex bytes, register names and values.

use optobus_device::{DeviceInfo, RegisterInfo};
use optobus_inspect::{
    decode_value, parse_hex, parse_value, resolve, values_text, Error, HexError, ParseError,
    ResolveError,
};

const P: &DeviceInfo = &optobus_p_series::DEVICE;
const RANGEFINDER: &DeviceInfo = &optobus_rangefinder::DEVICE;
const CCF: &DeviceInfo = &optobus_ccf::DEVICE;

fn register(device: &'static DeviceInfo, name: &str) -> &'static RegisterInfo {
    device.register(name).expect("register")
}

/// The words of `text` in `name`, or the one-line refusal.
fn parsed(device: &'static DeviceInfo, name: &str, text: &str) -> Result<Vec<u16>, String> {
    parse_value(register(device, name), text).map_err(|e| e.to_string())
}

fn names(registers: &[&RegisterInfo]) -> Vec<&'static str> {
    registers.iter().map(|r| r.name).collect()
}

#[test]
fn hex_is_read_with_or_without_spaces_and_prefixes() {
    let expected = vec![0x01, 0x04, 0x00, 0x00, 0x00, 0x02, 0x71, 0xCB];
    for text in [
        "01 04 00 00 00 02 71 CB",
        "010400000002 71CB",
        "0x01 0x04 0x00 0x00 0x00 0x02 0x71 0xcb",
        "0x01040000 0x000271cb",
        "01,04,00,00,00,02,71,CB",
        "1 4 0 0 0 2 71 cb",
        "01 04\n0000;0x0002:71CB",
    ] {
        assert_eq!(parse_hex(text), Ok(expected.clone()), "{text}");
    }
}

#[test]
fn bad_hex_is_refused_with_a_reason() {
    let cases = [
        ("01 0G", HexError::NotHex("0G".into()), "`0G` is not hex"),
        ("0x", HexError::NotHex("0x".into()), "`0x` is not hex"),
        (
            "héllo",
            HexError::NotHex("héllo".into()),
            "`héllo` is not hex",
        ),
        (
            "010",
            HexError::OddDigits("010".into()),
            "`010` has an odd number of hex digits",
        ),
        ("   ", HexError::Empty, "no bytes given"),
        ("", HexError::Empty, "no bytes given"),
    ];
    for (text, error, message) in cases {
        assert_eq!(parse_hex(text), Err(error.clone()), "{text:?}");
        assert_eq!(error.to_string(), message);
    }
}

#[test]
fn values_are_read_in_units_codes_and_the_manuals_words() {
    // 5.2.1: sampling interval 100 µs is code us_100 = 20 (0x14).
    for text in ["us_100", "US_100", "100us", "100 us", "20", "0x14"] {
        assert_eq!(
            parsed(P, "sampling_interval", text),
            Ok(vec![0x14]),
            "{text}"
        );
    }
    // Light power in steps of 0.1 %: 42.5 % is 425.
    for text in ["42.5", "42.5%", "42.5 %"] {
        assert_eq!(parsed(P, "light_power", text), Ok(vec![425]), "{text}");
    }
    // A packed register by its fields (rangefinder 3.7: odd parity at 57600 baud).
    let words = parsed(
        RANGEFINDER,
        "serial_parameters",
        "parity=odd,baud_rate=57600",
    );
    assert_eq!(words, Ok(vec![0x0100, 0xE100]));
    // And back: what is parsed decodes to what was meant.
    let light_power = register(P, "light_power");
    let words = parse_value(light_power, "42.5").unwrap_or_default();
    assert_eq!(decode_value(light_power, &words).to_string(), "42.5 %");
}

#[test]
fn bad_values_are_refused_in_one_line() {
    let cases = [
        (
            "light_power",
            "100.1",
            "`light_power` does not take `100.1`: allowed 0.5 % ..= 100.0 %",
        ),
        (
            "light_power",
            "50.05",
            "`light_power` does not take `50.05`: it holds whole steps of 0.1 %",
        ),
        (
            "light_power",
            "lots",
            "`light_power` does not take `lots`: not a number in %",
        ),
        // Digits beyond what 64 bits hold: the register's steps, not "not a number".
        (
            "light_power",
            "0.49999999999999999999",
            "`light_power` does not take `0.49999999999999999999`: it holds whole steps of 0.1 %",
        ),
        (
            "light_power",
            "1e1",
            "`light_power` does not take `1e1`: write the number as a plain decimal (`10`, `0.001`), not with an exponent (`1e1`)",
        ),
        ("distance_1", "1", "`distance_1` is read-only"),
    ];
    for (name, text, message) in cases {
        assert_eq!(
            parsed(P, name, text),
            Err(message.to_owned()),
            "{name} {text}"
        );
    }
    let refused = parse_value(register(P, "light_power"), "lots");
    assert!(matches!(
        refused,
        Err(ParseError::Refused {
            register: "light_power",
            ..
        })
    ));
    let codes = parsed(P, "sampling_interval", "fast")
        .err()
        .unwrap_or_default();
    assert!(
        codes.contains("codes are ") && codes.contains("us_100 (20)"),
        "{codes}"
    );
    let fields = parsed(RANGEFINDER, "serial_parameters", "parity=odd")
        .err()
        .unwrap_or_default();
    assert!(
        fields.contains("give every field as name=value"),
        "{fields}"
    );
}

#[test]
fn names_resolve_to_registers_copies_and_groups() {
    let found = |device, name, copy| resolve(device, name, copy).map(|r| names(&r));
    assert_eq!(found(P, "distance_1", None), Ok(vec!["distance_1"]));
    // A copy number for a name that holds no repeat member names nothing: refused.
    assert!(matches!(
        resolve(P, "distance_1", Some(3)),
        Err(ResolveError::NoRepeats { number: 3, .. })
    ));
    let every = found(CCF, "exposure_time", None).unwrap_or_default();
    assert_eq!(every.len(), 4);
    let second = found(CCF, "exposure_time", Some(2)).unwrap_or_default();
    assert_eq!(second.len(), 1);
    assert_eq!(
        CCF.register(second[0])
            .and_then(|r| r.copy)
            .map(|c| c.number),
        Some(2)
    );
    let group = found(P, "measurements", None).unwrap_or_default();
    assert_eq!(group.first(), Some(&"distance_1"));
    assert_eq!(group.len(), 5);
}

#[test]
fn unknown_names_and_copies_are_refused_with_near_names() {
    let error = resolve(P, "distance", None).err();
    let Some(ResolveError::Unknown { near, family, .. }) = &error else {
        panic!("{error:?}");
    };
    assert_eq!(*family, "p_series");
    assert!(near.contains(&"distance_1") && near.len() <= 5, "{near:?}");
    assert_eq!(
        error.map(|e| e.to_string()).unwrap_or_default(),
        "`distance` is no register or group of p-series"
    );
    let error = resolve(CCF, "exposure_time", Some(5)).err();
    assert_eq!(
        error.map(|e| e.to_string()).unwrap_or_default(),
        "`exposure_time` has no channel 5: channels are numbered 1 to 4"
    );
    let nothing_near = resolve(P, "zzz", None).err();
    assert!(matches!(nothing_near, Some(ResolveError::Unknown { near, .. }) if near.is_empty()));
}

#[test]
fn point_7_a_misspelt_name_suggests_the_nearest_names() {
    let error = resolve(P, "distanse_1", None).err();
    let Some(ResolveError::Unknown { near, .. }) = &error else {
        panic!("{error:?}");
    };
    // One edit away first, then two.
    assert_eq!(near, &["distance_1", "distance_2"]);
    let error = Error::from(error.expect("refused"));
    assert_eq!(
        error.to_string(),
        "`distanse_1` is no register or group of p-series (did you mean distance_1, distance_2?)"
    );
    // A repeat member by its name, of the model as users type it.
    let error = resolve(CCF, "exposure_tme", None).err();
    let Some(ResolveError::Unknown { near, .. }) = &error else {
        panic!("{error:?}");
    };
    assert_eq!(near.first(), Some(&"exposure_time"), "{near:?}");
    let error = Error::from(resolve(P, "zzzzzzzz", None).expect_err("refused"));
    assert!(
        error
            .to_string()
            .ends_with("(see `optobus registers p-series`)"),
        "{error}"
    );
}

#[test]
fn other_si_prefixes_of_the_registers_unit_convert_exactly() {
    // CCF exposure_time, channel 1: steps of 0.1 µs.
    let channel_1 = resolve(CCF, "exposure_time", Some(1)).expect("channel 1")[0];
    let exposure = |text: &str| parse_value(channel_1, text).map_err(|e| e.to_string());
    assert_eq!(exposure("0.2ms"), Ok(vec![2000]));
    assert_eq!(exposure("0.2 ms"), Ok(vec![2000]));
    assert_eq!(exposure("200us"), Ok(vec![2000]));
    assert_eq!(exposure("200000 ns"), Ok(vec![2000]));
    assert_eq!(exposure("0.0002s"), Ok(vec![2000]));
    // 0.00001 ms is 10 ns: not a whole 0.1 µs step, refused rather than rounded.
    let error = exposure("0.00001ms").unwrap_err();
    assert!(error.contains("whole steps of 0.1 us"), "{error}");
    // P-series position_1_offset: steps of 1 nm in mm.
    let offset = |text: &str| parsed(P, "position_1_offset", text);
    assert_eq!(offset("1.5 mm"), offset("1500um"));
    assert_eq!(offset("-1500 um"), offset("-1.5"));
    assert_eq!(offset("0.0015 m"), offset("1.5"));
    let error = offset("0.5 nm").unwrap_err();
    assert!(error.contains("whole steps"), "{error}");
    // Another base unit is no conversion.
    let error = exposure("2 mm").unwrap_err();
    assert!(
        error.contains("`mm` is not a unit of the register: it is in us"),
        "{error}"
    );
}

#[test]
fn a_channel_given_to_a_model_without_repeats_is_refused() {
    let error = optobus_inspect::resolve(&optobus_p_series::DEVICE, "measurements", Some(2))
        .expect_err("the P series repeats no register");
    assert_eq!(
        error.to_string(),
        "`measurements` of p-series holds no repeated register, so copy 2 (a channel) names nothing"
    );
    // Without a copy number the group reads as before.
    assert!(optobus_inspect::resolve(&optobus_p_series::DEVICE, "measurements", None).is_ok());
}

#[test]
fn quantities_convert_to_their_base_units_by_prefix() {
    use optobus_codec::value::{Fixed, Scale};
    let mm = Fixed::new(4_969_234, Scale::Decimal { exponent: -6 });
    assert_eq!(
        optobus_inspect::in_base_unit(mm, "mm"),
        Some((0.004969234, "m"))
    );
    let us = Fixed::new(250, Scale::ONE);
    assert_eq!(
        optobus_inspect::in_base_unit(us, "us"),
        Some((0.000250, "s"))
    );
    let percent = Fixed::new(505, Scale::Decimal { exponent: -1 });
    assert_eq!(
        optobus_inspect::in_base_unit(percent, "%"),
        Some((0.505, ""))
    );
    let celsius = Fixed::new(-125, Scale::Decimal { exponent: -1 });
    assert_eq!(
        optobus_inspect::in_base_unit(celsius, "degC"),
        Some((-12.5, "degC"))
    );
    assert_eq!(optobus_inspect::base_unit("uV"), Some((-6, "V")));
    assert_eq!(
        optobus_inspect::base_unit("counts"),
        None,
        "no base unit known"
    );
}

#[test]
fn values_are_shown_a_line_each_aligned_after_the_longest_name() {
    let light_power = register(P, "light_power");
    let words = parse_value(light_power, "42.5").unwrap_or_default();
    let distance = register(P, "distance_1");
    let values = [
        (light_power, decode_value(light_power, &words)),
        (distance, decode_value(distance, &[0, 0])),
    ];
    let value = decode_value(distance, &[0, 0]);
    assert_eq!(
        values_text(&values),
        format!("light_power  42.5 %\ndistance_1   {value}\n")
    );
    assert_eq!(values_text(&[]), "");
}
