//! optobus-inspect on real bytes: the manuals' frames encoded from the driver's plans, and
//! captured frames decoded, however broken.

use optobus_codec::value::Fixed;
use optobus_device::{DeviceInfo, RegisterInfo};
use optobus_driver::Encode;
use optobus_inspect::{
    decode, encode_read, encode_write, hex, CrcCheck, ExplainedFrame, FrameKind, Framing, Value,
};
use proptest::prelude::*;

const P: &DeviceInfo = &optobus_p_series::DEVICE;
const RANGEFINDER: &DeviceInfo = &optobus_rangefinder::DEVICE;
const LC_RS: &DeviceInfo = &optobus_lc_rs::DEVICE;
const CCF: &DeviceInfo = &optobus_ccf::DEVICE;

fn bytes(text: &str) -> Vec<u8> {
    text.split_whitespace()
        .filter_map(|b| u8::from_str_radix(b, 16).ok())
        .collect()
}

fn register(device: &'static DeviceInfo, name: &str) -> &'static RegisterInfo {
    device.register(name).expect("register")
}

fn group(device: &'static DeviceInfo, name: &str) -> Vec<&'static RegisterInfo> {
    let group = device.group(name).expect("group");
    group
        .registers
        .iter()
        .flat_map(|member| {
            device
                .registers
                .iter()
                .filter(move |r| r.name == *member || r.member_name() == Some(member))
        })
        .collect()
}

fn rtu(device: &'static DeviceInfo, text: &str) -> Vec<ExplainedFrame> {
    decode(device, &bytes(text), Framing::Rtu, None).expect("decodes")
}

#[test]
fn a_read_of_a_register_is_one_request() {
    let frames = encode_read(P, &[register(P, "distance_1")], 1, Framing::Rtu).expect("encodes");
    let shown: Vec<(String, &str)> = frames
        .iter()
        .map(|f| (hex(&f.bytes), f.description.as_str()))
        .collect();
    assert_eq!(
        shown,
        [(
            "01 04 00 00 00 02 71 CB".to_owned(),
            "read input 0-1 (distance_1)"
        )]
    );
}

#[test]
fn a_group_is_read_in_the_manuals_request() {
    // P series 5.4: the buffer page, 122 registers from input 16.
    let frames = encode_read(P, &group(P, "buffer_page"), 1, Framing::Rtu).expect("encodes");
    let shown: Vec<String> = frames.iter().map(|f| hex(&f.bytes)).collect();
    assert_eq!(shown, ["01 04 00 10 00 7A 70 2C"]);
    let frames = encode_read(P, &group(P, "measurements"), 1, Framing::Rtu).expect("encodes");
    assert_eq!(
        frames.first().map(|f| f.description.as_str()),
        Some("read input 0-9 (distance_1 .. statistic_2, 5 registers)")
    );
    // With one address per field, every field is a request of its own.
    let frames = encode_read(
        RANGEFINDER,
        &group(RANGEFINDER, "measurements"),
        25,
        Framing::Rtu,
    )
    .expect("encodes");
    assert!(frames.len() > 1);
}

#[test]
fn tcp_frames_count_transactions_from_one() {
    let frames = encode_read(P, &group(P, "laser"), 1, Framing::Tcp).expect("encodes");
    let shown: Vec<String> = frames.iter().map(|f| hex(&f.bytes)).collect();
    assert_eq!(shown, ["00 01 00 00 00 06 01 03 00 00 00 03"]);
    assert!(frames
        .iter()
        .all(|f| f.description.ends_with("transaction 1, unit 1")));
}

#[test]
fn a_split_write_comes_low_word_first_where_the_spec_says() {
    // P series 4.1.2 note 4: slope 2.0 goes to register 28 (low word) first, then 27.
    let slope = register(P, "position_1_slope");
    let words = "2"
        .parse::<Fixed>()
        .expect("number")
        .encode(slope)
        .expect("valid");
    let frames = encode_write(P, slope, &words, 1, Framing::Rtu).expect("encodes");
    let shown: Vec<String> = frames.iter().map(|f| hex(&f.bytes)).collect();
    assert_eq!(
        shown,
        ["01 06 00 1C 00 00 48 0C", "01 06 00 1B 00 20 F8 15"]
    );
    assert!(frames
        .first()
        .is_some_and(|f| f.description.contains("low word of position_1_slope")));
}

#[test]
fn a_wide_write_is_one_four_byte_fc06() {
    // Rangefinder 3.7: odd parity, 57600 baud, as one FC06 with four data bytes.
    let serial = register(RANGEFINDER, "serial_parameters");
    let frames =
        encode_write(RANGEFINDER, serial, &[0x0100, 0xE100], 25, Framing::Rtu).expect("encodes");
    let shown: Vec<String> = frames.iter().map(|f| hex(&f.bytes)).collect();
    assert_eq!(shown, ["19 06 00 04 01 00 E1 00 5F 01"]);
    assert!(frames
        .first()
        .is_some_and(|f| f.description.contains("one FC06 with 4 data bytes")));
}

#[test]
fn a_one_word_write_is_the_manuals_frame() {
    // P series 5.2.1: sampling interval 100 us (code 20).
    let interval = register(P, "sampling_interval");
    let frames = encode_write(P, interval, &[20], 1, Framing::Rtu).expect("encodes");
    let shown: Vec<String> = frames.iter().map(|f| hex(&f.bytes)).collect();
    assert_eq!(shown, ["01 06 00 06 00 14 69 C4"]);
}

#[test]
fn a_golden_rtu_request_and_reply_are_paired_and_decoded() {
    let frames = rtu(
        P,
        "01 04 00 00 00 06 70 08 01 04 0C 00 36 B0 BE 00 20 24 5C 00 56 D3 04 41 47",
    );
    let kinds: Vec<FrameKind> = frames.iter().map(|f| f.kind).collect();
    assert_eq!(kinds, [FrameKind::ReadRequest, FrameKind::ReadReply]);
    let reply = frames.get(1).expect("reply");
    assert!(reply
        .fields
        .iter()
        .any(|f| f.meaning == "input 0-1: distance_1 = 3.584190 mm"));
    assert!(reply.crc.is_some_and(|c| c.ok()));
    let names: Vec<&str> = reply.registers.iter().map(|r| r.name).collect();
    assert_eq!(names, ["distance_1", "distance_2", "thickness"]);
    assert!(reply
        .registers
        .first()
        .is_some_and(|r| matches!(r.value, Some(Value::Quantity(..)))));
}

#[test]
fn a_golden_tcp_pair_is_paired_by_its_header() {
    let input = bytes(
        "00 00 00 00 00 06 01 04 00 00 00 06 \
         00 00 00 00 00 0F 01 04 0C 00 35 CB 69 00 1F 3A 6C 00 2A 05 D5",
    );
    let frames = decode(P, &input, Framing::Tcp, None).expect("decodes");
    assert_eq!(frames.len(), 2);
    assert!(frames.iter().all(|f| f.crc.is_none()));
    assert!(frames.get(1).is_some_and(|f| f
        .fields
        .iter()
        .any(|field| field.meaning == "input 0-1: distance_1 = 3.525481 mm")));
}

#[test]
fn a_wrong_crc_is_flagged_with_the_right_one() {
    let frames = rtu(P, "01 04 00 00 00 02 71 CC");
    let frame = frames.first().expect("frame");
    assert_eq!(
        frame.crc,
        Some(CrcCheck {
            received: 0xCC71,
            computed: 0xCB71
        })
    );
    assert!(frame.notes.iter().any(|n| n.contains("71 CB")));
    assert_eq!(frame.kind, FrameKind::ReadRequest);
}

#[test]
fn lc_rs_exceptions_have_seven_bytes_and_the_specs_meaning() {
    let frames = rtu(LC_RS, "01 83 02 00 01 50 44");
    let frame = frames.first().expect("frame");
    assert_eq!((frame.kind, frame.bytes.len()), (FrameKind::Exception, 7));
    assert!(frame.summary.contains("register_address_error"));
    // A standard-shaped exception: the standard name.
    let standard = rtu(P, "01 83 02 C0 F1");
    assert!(standard
        .first()
        .is_some_and(|f| f.summary.contains("illegal_data_address")));
}

#[test]
fn ccs_and_ccf_exceptions_carry_the_meaning_of_their_table_3_10() {
    for device in [&optobus_ccs::DEVICE, CCF] {
        let codes: Vec<(u32, &str)> = device
            .exception_codes
            .iter()
            .map(|c| (c.code, c.name))
            .collect();
        assert_eq!(
            codes,
            [
                (1, "illegal_function"),
                (2, "illegal_data_address"),
                (3, "illegal_data_value")
            ],
            "{}",
            device.family
        );
        // 3.3 table 3-10: "02 非法的数据地址 指定的地址超出从机的范围".
        let frames = rtu(device, "01 83 02 C0 F1");
        let frame = frames.first().expect("frame");
        assert_eq!(frame.kind, FrameKind::Exception);
        assert!(
            frame
                .summary
                .contains("illegal_data_address (The address is outside the device's range)"),
            "{}: {}",
            device.family,
            frame.summary
        );
    }
}

#[test]
fn a_wide_write_and_a_split_half_are_named() {
    let frames = rtu(RANGEFINDER, "19 06 00 04 01 00 E1 00 5F 01");
    let frame = frames.first().expect("frame");
    assert!(frame.bytes.len() == 10 && frame.crc.is_some_and(|c| c.ok()));
    assert!(frame.summary.contains("serial_parameters") && frame.summary.contains("57600"));
    let frames = rtu(P, "01 06 00 1C 00 00 48 0C");
    assert!(frames
        .first()
        .is_some_and(|f| f.summary.contains("low word of position_1_slope")));
}

#[test]
fn a_write_and_its_echo() {
    let frames = rtu(P, "01 06 00 06 00 14 69 C4 01 06 00 06 00 14 69 C4");
    let kinds: Vec<FrameKind> = frames.iter().map(|f| f.kind).collect();
    assert_eq!(kinds, [FrameKind::Write, FrameKind::WriteEcho]);
}

#[test]
fn a_refused_value_gets_a_note() {
    // light_power 0 (allowed 0.5 % ..= 100 %): the device answers exception 03.
    let power = register(P, "light_power");
    let mut frame = vec![1, 6];
    frame.extend(power.address.to_be_bytes());
    frame.extend([0, 0]);
    let crc = optobus_codec::crc::crc16(&frame).to_le_bytes();
    frame.extend(crc);
    let frames = decode(P, &frame, Framing::Rtu, None).expect("decodes");
    assert!(frames.first().is_some_and(|f| f
        .notes
        .iter()
        .any(|n| n.contains("outside the allowed range"))));
}

#[test]
fn short_and_foreign_input_is_refused_with_a_reason() {
    let message = |device, text: &str, framing| {
        decode(device, &bytes(text), framing, None)
            .err()
            .map(|e| format!("{e} {:?}", e.hint))
            .unwrap_or_default()
    };
    assert!(message(P, "01 04", Framing::Rtu).contains("too short"));
    assert!(message(P, "01 04 00 00 00 02", Framing::Rtu).contains("too short for a read request"));
    assert!(message(P, "00 00 00 00 00 06 01 03 00 00 00 03", Framing::Rtu).contains("--mbap"));
    assert!(message(P, "01 03 00 00 00 03 05 CB", Framing::Tcp).contains("leave out --mbap"));
    assert!(message(CCF, "00 01 00 00 00 06 01", Framing::Tcp).contains("too short"));
}

#[test]
fn every_prefix_and_corruption_of_real_frames_decodes_without_panicking() {
    let frames = [
        "01 04 00 00 00 06 70 08 01 04 0C 00 36 B0 BE 00 20 24 5C 00 56 D3 04 41 47",
        "19 06 00 04 01 00 E1 00 5F 01",
        "01 83 02 00 01 50 44",
        "00 00 00 00 00 0F 01 04 0C 00 35 CB 69 00 1F 3A 6C 00 2A 05 D5",
        "19 03 04 00 00 3D 9B 33 09",
    ];
    for text in frames {
        let original = bytes(text);
        for end in 0..=original.len() {
            for flip in (0..=u8::MAX).step_by(15) {
                let mut input = original.get(..end).unwrap_or_default().to_vec();
                if let Some(byte) = input.get_mut(end.saturating_sub(1)) {
                    *byte ^= flip;
                }
                decode_everywhere(&input);
            }
        }
    }
}

/// Decodes `input` for several devices, both framings, with and without a start address, and
/// renders what it gives as JSON and as text.
fn decode_everywhere(input: &[u8]) {
    for device in [P, RANGEFINDER, LC_RS, CCF] {
        for framing in [Framing::Rtu, Framing::Tcp] {
            for address in [None, Some(0), Some(u16::MAX)] {
                if let Ok(frames) = decode(device, input, framing, address) {
                    assert!(!frames.is_empty() || input.is_empty());
                    let used: usize = frames.iter().map(|f| f.bytes.len()).sum();
                    assert!(used <= input.len());
                    let _ = serde_json::to_string(&frames);
                    let _: Vec<String> = frames.iter().map(ToString::to_string).collect();
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    #[test]
    fn arbitrary_bytes_never_panic(input in proptest::collection::vec(any::<u8>(), 0..300)) {
        decode_everywhere(&input);
    }

    #[test]
    fn plausible_frames_never_panic(
        slave in 0u8..4,
        function in prop::sample::select(vec![0x03u8, 0x04, 0x06, 0x83, 0x84, 0x86, 0x90, 0x10]),
        tail in proptest::collection::vec(any::<u8>(), 0..260),
    ) {
        let mut input = vec![slave, function];
        input.extend(tail);
        decode_everywhere(&input);
        let mut tcp = vec![0, 1, 0, 0];
        tcp.extend(u16::try_from(input.len()).unwrap_or(u16::MAX).to_be_bytes());
        tcp.extend(&input);
        decode_everywhere(&tcp);
    }
}

#[test]
fn an_unlisted_value_gets_a_note_in_units() {
    // light_power made to accept only 0.5 % and 1.0 % (raw 5 and 10): raw 7 is in range but
    // not listed.
    let mut registers = P.registers.to_vec();
    let power = registers
        .iter_mut()
        .find(|r| r.name == "light_power")
        .expect("light_power");
    power.allowed_values = &[5, 10];
    let device: &'static DeviceInfo = Box::leak(Box::new(DeviceInfo {
        registers: Box::leak(registers.into_boxed_slice()),
        ..*P
    }));
    let frames = rtu(device, "01 06 00 02 00 07 69 C8");
    let note = frames[0]
        .notes
        .iter()
        .find(|n| n.contains("not a value"))
        .expect("a note");
    assert!(
        note.contains("`light_power` accepts (only 0.5, 1.0)"),
        "{note}"
    );
}

#[test]
fn reading_an_action_register_gets_a_note() {
    // LC-RS factory reset (0089H): the manual does not say what a read returns.
    let frames = rtu(LC_RS, "01 03 00 89 00 01 55 E0");
    assert!(
        frames[0]
            .notes
            .iter()
            .any(|n| n.contains("`factory_reset` is an action register")),
        "{:?}",
        frames[0].notes
    );
    // Encoding a read leaves it out.
    let frames =
        encode_read(LC_RS, &[register(LC_RS, "factory_reset")], 1, Framing::Rtu).expect("encodes");
    assert!(frames.is_empty());
}

#[test]
fn a_value_is_a_number_to_draw_only_when_it_is_a_quantity_or_an_integer() {
    let quantity = Value::Quantity("3.584190".parse::<Fixed>().unwrap(), Some("mm"));
    assert_eq!(quantity.number(), Some(3.58419));
    assert_eq!(Value::Integer(-42).number(), Some(-42.0));
    assert_eq!(Value::Bool(true).number(), None);
    assert_eq!(Value::Invalid.number(), None);
    assert_eq!(Value::Code(2, Some("fast")).number(), None);
}
