//! The generator's output for every spec compiles with `#![deny(missing_docs, warnings)]`
//! (`tests/build.rs` generates each spec of `specs/`), its `DEVICE` is the runtime description
//! a tool builds from the same file, and it agrees with the spec's JSON dump and the golden
//! frames.
//!
//! The emitter prints `DEVICE` from that very description (`optobus_spec::description`), so
//! the comparisons below no longer check two computations against each other: they are the
//! printer's round trip (printed, compiled, equal to the value printed), a cheap check that
//! no printer drops or alters a field.

use optobus_device::{DeviceInfo, Table, ValueKind};
use optobus_tests::generated::{self, ccf, lc_rs, mini, p_series, rangefinder};
use optobus_tests::specs;

fn spec_json(family: &str) -> serde_json::Value {
    optobus_codegen::json::dump(&specs::model(family))
}

/// The static description lists exactly the registers of the JSON dump, with the same table,
/// address, words and access.
fn matches_dump(device: &DeviceInfo) {
    let dump = spec_json(device.family);
    let registers = dump["registers"].as_array().expect("registers");
    assert_eq!(device.registers.len(), registers.len(), "{}", device.family);
    for (info, json) in device.registers.iter().zip(registers) {
        assert_eq!(json["name"], info.name);
        assert_eq!(json["address"], u64::from(info.address), "{}", info.name);
        assert_eq!(json["words"], u64::from(info.words), "{}", info.name);
        let table = match info.table {
            Table::Holding => "holding",
            Table::Input => "input",
        };
        assert_eq!(json["table"], table, "{}", info.name);
    }
    assert_eq!(
        device.commands.len(),
        dump["commands"].as_array().map_or(0, Vec::len)
    );
    assert_eq!(
        device.groups.len(),
        dump["groups"].as_array().map_or(0, Vec::len)
    );
    let buffer = &dump["buffer"];
    match device.buffer {
        Some(info) => {
            assert_eq!(buffer["count"], info.count, "{}", device.family);
            assert_eq!(buffer["most"], u64::from(info.most), "{}", device.family);
            assert_eq!(buffer["page"], info.page, "{}", device.family);
            assert_eq!(buffer["values"], info.values, "{}", device.family);
        }
        None => assert!(buffer.is_null(), "{}", device.family),
    }
}

/// `generated_code::<family>`: the compiled `DEVICE` equals the runtime description it was
/// printed from, field for field, and lists what the JSON dump lists.
fn compiled_and_described_agree(family: &str) {
    let compiled = generated::device(family).expect("build.rs generated every spec");
    let described = specs::describe(family);
    assert_eq!(compiled, described, "{family}");
    assert!(!described.registers.is_empty(), "{family}: no registers");
    matches_dump(compiled);
}

optobus_tests::family_cases!(generated_code, compiled_and_described_agree);

#[test]
fn family_crates_carry_the_runtime_description() {
    for crate_device in [
        &optobus_p_series::DEVICE,
        &optobus_rangefinder::DEVICE,
        &optobus_ccs::DEVICE,
        &optobus_lc_rs::DEVICE,
        &optobus_ccf::DEVICE,
    ] {
        assert_eq!(crate_device, specs::describe(crate_device.family));
    }
}

#[test]
fn mini_runtime_description_matches_its_generated_code() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../codegen/tests/fixtures/mini.yaml");
    let model = optobus_spec::check_file(&path).unwrap_or_else(|r| panic!("{}", r.render()));
    assert_eq!(&mini::DEVICE, optobus_spec::describe(&model));
}

#[test]
fn p_series_types_decode_manual_values() {
    let distance = p_series::DEVICE.register("distance_1").expect("distance_1");
    assert_eq!(
        (distance.table, distance.address, distance.words),
        (Table::Input, 0, 2)
    );
    assert_eq!(distance.sentinel, Some(0x7FFF_FFFF));
    assert_eq!(distance.scale.map(|s| s.to_string()), Some("1e-6".into()));
    // §5.2.1: sampling interval code 0x14 is 100 µs.
    let interval = p_series::DEVICE
        .register("sampling_interval")
        .expect("sampling_interval");
    let code = interval
        .codes
        .iter()
        .find(|c| c.code == 0x14)
        .expect("code 0x14");
    assert!(code.meaning.contains("100"), "{code:?}");
    // The IP address is one register of four octet words.
    let ip = p_series::DEVICE.register("ip_address").expect("ip_address");
    assert_eq!((ip.address, ip.words, ip.kind), (150, 4, ValueKind::Ipv4));
}

#[test]
fn quirks_are_data() {
    use optobus_device::{Addressing, ExceptionShape, LongWrites};
    assert_eq!(
        lc_rs::DEVICE.frame_shape.exception,
        ExceptionShape::CountedWord
    );
    assert_eq!(lc_rs::DEVICE.max_read_words, 8);
    assert!(lc_rs::DEVICE.needs_save_and_power_cycle);
    assert_eq!(rangefinder::DEVICE.addressing, Addressing::Field);
    assert_eq!(rangefinder::DEVICE.long_writes, LongWrites::Wide);
    // Every 4-byte write in the rangefinder manual goes to an address the shape marks wide.
    let golden = optobus_tests::golden::load("rangefinder").expect("golden");
    for entry in golden
        .frames
        .iter()
        .filter_map(|e| e.write.filter(|w| w.width == 4))
    {
        assert!(
            rangefinder::DEVICE
                .frame_shape
                .four_byte_writes
                .contains(&entry.address),
            "address {:#X}",
            entry.address
        );
    }
    assert_eq!(p_series::DEVICE.frame_shape.four_byte_writes, &[] as &[u16]);
}

#[test]
fn ccf_channels_are_one_block() {
    assert_eq!(ccf::Channel::COUNT, 4);
    assert_eq!(ccf::Channel::all().count(), 4);
    assert!(ccf::Channel::new(0).is_none() && ccf::Channel::new(5).is_none());
    // The address of `member` in each channel's copy.
    let addresses = |member: &str| -> Vec<u16> {
        let address = |n| {
            let name = format!("channel_{n}_{member}");
            ccf::DEVICE.register(&name).expect("copy").address
        };
        (1..=4).map(address).collect()
    };
    assert_eq!(addresses("exposure_time"), [2, 10, 18, 26]);
    assert_eq!(addresses("peak_1_height"), [32, 34, 36, 38]);
}

#[test]
fn mini_enums_and_structs_behave() {
    use mini::{Source, StatisticConfig, StatisticConfigKind};
    assert_eq!(Source::from_raw(1), Source::Thickness);
    assert_eq!(Source::from_raw(7), Source::Unknown(7));
    assert_eq!(Source::Unknown(7).raw(), 7);
    assert_eq!(Source::Thickness.to_string(), "thickness");
    let config = StatisticConfig::from_raw(0x0101);
    assert_eq!(config.source, Source::Thickness);
    assert_eq!(config.kind, StatisticConfigKind::Minimum);
    assert_eq!(config.to_raw(), Some(0x0101));
    let wide = StatisticConfig {
        source: Source::Unknown(0x1FF),
        kind: StatisticConfigKind::Maximum,
    };
    assert_eq!(wide.to_raw(), None);
    let version = mini::FirmwareVersion::from_words([0x0001, 0x0203]);
    assert_eq!(version.to_string(), "1.2.3");
}
