//! Every example frame printed in the five manuals, checked byte for byte against our encoder,
//! decoded back (whole and byte by byte), and decoded to the values the manual's text gives.

use optobus_codec::value::{join_u32, BytePair, Fixed, Scale, WordOrder};
use optobus_codec::{
    rtu, tcp, DecodeError, Decoded, ExceptionCode, ExceptionShape, FrameShape, ReadFunction,
    Request, Response, WriteValue,
};
use optobus_tests::golden::{
    self as files, Direction, Entry, Origin, Transport, ValueSpec, ValueType, WordOrderName,
};

/// How many frames each manual prints (and how many we completed from its templates). A
/// change here means a frame was added to or dropped from the golden files.
const EXPECTED_COUNTS: [(&str, usize, usize); 5] = [
    ("p_series", 13, 0),
    ("rangefinder", 90, 0),
    ("ccs", 6, 0),
    ("lc_rs", 6, 15),
    ("ccf", 6, 0),
];

/// The PDU an entry describes, as the codec sees it.
enum Expected {
    Request(Request),
    Reply(Request, ExpectedReply),
}

enum ExpectedReply {
    Words(ReadFunction, Vec<u16>),
    Echo(u16, WriteValue),
    Exception(u8, ExceptionCode),
}

fn expected(entry: &Entry) -> Result<Expected, String> {
    let keys = [
        entry.read.is_some(),
        entry.write.is_some(),
        entry.words.is_some(),
        entry.echo.is_some(),
        entry.exception.is_some(),
    ];
    if keys.iter().filter(|k| **k).count() != 1 {
        return Err("needs exactly one of read / write / words / echo / exception".into());
    }
    match entry.direction {
        Direction::Request => {
            if entry.request.is_some() {
                return Err("a request has no `request:`".into());
            }
            match (entry.read, entry.write) {
                (Some(read), _) => Ok(Expected::Request(read.to_request()?)),
                (_, Some(write)) => Ok(Expected::Request(write.to_request()?)),
                _ => Err("a request needs read / write".into()),
            }
        }
        Direction::Response => {
            let request = entry
                .request
                .ok_or("a response needs `request:`")?
                .to_request()?;
            let reply = if let Some(words) = &entry.words {
                let function = ReadFunction::from_code(words.function)
                    .ok_or_else(|| format!("words: function {} is not a read", words.function))?;
                ExpectedReply::Words(function, words.values.clone())
            } else if let Some(echo) = entry.echo {
                ExpectedReply::Echo(echo.address, echo.to_value()?)
            } else if let Some(exception) = entry.exception {
                ExpectedReply::Exception(exception.function, ExceptionCode(exception.code))
            } else {
                return Err("a response needs words / echo / exception".into());
            };
            Ok(Expected::Reply(request, reply))
        }
    }
}

/// A frame shape in which this entry's FC06 width is declared, as a device would know it.
fn four_byte_writes(expected: &Expected) -> Vec<u16> {
    let request = match expected {
        Expected::Request(request) | Expected::Reply(request, _) => request,
    };
    match request {
        Request::Write {
            address,
            value: WriteValue::DoubleWord(_),
        } => vec![*address],
        _ => Vec::new(),
    }
}

fn tcp_header(entry: &Entry) -> Result<tcp::Header, String> {
    Ok(tcp::Header {
        transaction: entry
            .transaction
            .ok_or("a TCP frame needs `transaction:`")?,
        unit: entry.slave,
    })
}

/// Our encoder's bytes for the entry's fields.
fn encode(entry: &Entry, expected: &Expected, shape: ExceptionShape) -> Result<Vec<u8>, String> {
    let mut out = [0u8; tcp::MAX_FRAME_LEN];
    let data;
    let len = match expected {
        Expected::Request(request) => match entry.transport {
            Transport::Rtu => rtu::encode_request(&mut out, entry.slave, request),
            Transport::Tcp => tcp::encode_request(&mut out, tcp_header(entry)?, request),
        },
        Expected::Reply(_, ExpectedReply::Exception(function, code)) => match entry.transport {
            Transport::Rtu => rtu::encode_exception(&mut out, entry.slave, *function, *code, shape),
            Transport::Tcp => {
                tcp::encode_exception(&mut out, tcp_header(entry)?, *function, *code, shape)
            }
        },
        Expected::Reply(_, reply) => {
            let response = match reply {
                ExpectedReply::Words(function, words) => {
                    data = words
                        .iter()
                        .flat_map(|w| w.to_be_bytes())
                        .collect::<Vec<u8>>();
                    Response::Read {
                        function: *function,
                        words: optobus_codec::Words::from_bytes(&data).ok_or("odd data")?,
                    }
                }
                ExpectedReply::Echo(address, value) => Response::Write {
                    address: *address,
                    value: *value,
                },
                ExpectedReply::Exception(..) => unreachable!("handled above"),
            };
            match entry.transport {
                Transport::Rtu => rtu::encode_response(&mut out, entry.slave, &response),
                Transport::Tcp => tcp::encode_response(&mut out, tcp_header(entry)?, &response),
            }
        }
    }
    .map_err(|e| format!("encode: {e}"))?;
    Ok(out[..len].to_vec())
}

/// What decoding `bytes` yields, reduced to comparable data.
#[derive(Debug, PartialEq)]
enum Outcome {
    Request(Request),
    Words(ReadFunction, Vec<u16>),
    Echo(u16, WriteValue),
    Exception(u8, ExceptionCode),
}

type Step = Result<Decoded<Outcome>, DecodeError>;

fn decode(
    bytes: &[u8],
    entry: &Entry,
    expected: &Expected,
    shape: ExceptionShape,
    wide: &[u16],
) -> Result<Step, String> {
    let frame_shape = FrameShape {
        exception: shape,
        four_byte_writes: wide,
    };
    Ok(match (expected, entry.transport) {
        (Expected::Request(_), Transport::Rtu) => rtu::decode_request(bytes, &frame_shape)
            .map(|d| d.map(|frame| Outcome::Request(frame.pdu))),
        (Expected::Request(_), Transport::Tcp) => tcp::decode_request(bytes, &frame_shape)
            .map(|d| d.map(|frame| Outcome::Request(frame.pdu))),
        (Expected::Reply(request, _), transport) => {
            let result = match transport {
                Transport::Rtu => rtu::decode_response(bytes, entry.slave, request, shape),
                Transport::Tcp => tcp::decode_response(bytes, tcp_header(entry)?, request, shape),
            };
            match result {
                Ok(decoded) => Ok(decoded.map(|response| match response {
                    Response::Read { function, words } => {
                        Outcome::Words(function, words.iter().collect())
                    }
                    Response::Write { address, value } => Outcome::Echo(address, value),
                })),
                Err(DecodeError::Exception { function, code }) => Ok(Decoded::Frame {
                    frame: Outcome::Exception(function, code),
                    // An exception frame is as long as its shape says.
                    consumed: shape.pdu_len()
                        + match transport {
                            Transport::Rtu => 3,
                            Transport::Tcp => tcp::HEADER_LEN,
                        },
                }),
                Err(other) => Err(other),
            }
        }
    })
}

fn expected_outcome(expected: &Expected) -> Outcome {
    match expected {
        Expected::Request(request) => Outcome::Request(*request),
        Expected::Reply(_, ExpectedReply::Words(f, w)) => Outcome::Words(*f, w.clone()),
        Expected::Reply(_, ExpectedReply::Echo(a, v)) => Outcome::Echo(*a, *v),
        Expected::Reply(_, ExpectedReply::Exception(f, c)) => Outcome::Exception(*f, *c),
    }
}

/// The 16-bit words a value index refers to: reply data, the written word, or the code.
fn value_words(expected: &Expected) -> Vec<u16> {
    match expected {
        Expected::Reply(_, ExpectedReply::Words(_, words)) => words.clone(),
        Expected::Request(Request::Write { value, .. })
        | Expected::Reply(_, ExpectedReply::Echo(_, value)) => match value {
            WriteValue::Word(word) => vec![*word],
            WriteValue::DoubleWord(double) => vec![(double >> 16) as u16, *double as u16],
        },
        Expected::Reply(_, ExpectedReply::Exception(_, code)) => vec![code.0],
        Expected::Request(Request::Read { .. }) => Vec::new(),
    }
}

fn parse_scale(text: &str) -> Result<Scale, String> {
    if let Some((num, den)) = text.split_once('/') {
        let num = num
            .trim()
            .parse()
            .map_err(|e| format!("scale {text}: {e}"))?;
        let den = den
            .trim()
            .parse()
            .map_err(|e| format!("scale {text}: {e}"))?;
        return Scale::ratio(num, den).ok_or_else(|| format!("scale {text}: zero denominator"));
    }
    let exponent = text
        .strip_prefix("1e")
        .and_then(|e| e.parse().ok())
        .ok_or_else(|| format!("scale {text}: expected 1e<exp> or n/d"))?;
    Ok(Scale::Decimal { exponent })
}

fn check_value(value: &ValueSpec, words: &[u16]) -> Result<(), String> {
    let word = |i: usize| {
        words
            .get(i)
            .copied()
            .ok_or_else(|| format!("{}: no word {i}", value.what))
    };
    let order = match value.word_order {
        Some(WordOrderName::LowFirst) => WordOrder::LowFirst,
        _ => WordOrder::HighFirst,
    };
    let raw: i64 = match value.kind {
        ValueType::U16 => word(value.word)?.into(),
        ValueType::I16 => i64::from(word(value.word)? as i16),
        ValueType::U8High => BytePair::from_word(word(value.word)?).high.into(),
        ValueType::U8Low => BytePair::from_word(word(value.word)?).low.into(),
        ValueType::U32 | ValueType::I32 | ValueType::U32Bytes => {
            let first = if value.kind == ValueType::U32Bytes {
                0
            } else {
                value.word
            };
            let joined = join_u32([word(first)?, word(first + 1)?], order);
            if value.kind == ValueType::I32 {
                i64::from(joined as i32)
            } else {
                joined.into()
            }
        }
    };
    if raw != value.raw {
        return Err(format!(
            "{}: decoded {raw}, manual says {}",
            value.what, value.raw
        ));
    }
    if let Some(text) = &value.text {
        let scale = parse_scale(value.scale.as_deref().unwrap_or("1e0"))?;
        let shown = Fixed::new(raw, scale).to_string();
        if &shown != text {
            return Err(format!("{}: shows {shown}, manual says {text}", value.what));
        }
        let parsed = Fixed::parse(text, scale).map_err(|e| format!("{}: {e}", value.what))?;
        if parsed.raw() != raw {
            return Err(format!("{}: {text} parses to {}", value.what, parsed.raw()));
        }
    }
    Ok(())
}

fn check_entry(entry: &Entry, shape: ExceptionShape) -> Result<(), String> {
    let expected = expected(entry)?;
    let wide = four_byte_writes(&expected);
    let bytes = &entry.bytes.0;

    let encoded = encode(entry, &expected, shape)?;
    if &encoded != bytes {
        return Err(format!(
            "encoder gives {:?}, manual has {:?}",
            files::Hex(encoded),
            entry.bytes
        ));
    }

    match decode(bytes, entry, &expected, shape, &wide)? {
        Ok(Decoded::Frame { frame, consumed }) if consumed == bytes.len() => {
            let want = expected_outcome(&expected);
            if frame != want {
                return Err(format!("decoded {frame:?}, expected {want:?}"));
            }
        }
        other => return Err(format!("decoding the whole frame gave {other:?}")),
    }

    // Byte by byte, as a serial port delivers it: every prefix is "need more".
    for cut in 0..bytes.len() {
        match decode(&bytes[..cut], entry, &expected, shape, &wide)? {
            Ok(Decoded::NeedMore { at_least })
                if at_least >= 1 && cut + at_least <= bytes.len() => {}
            other => return Err(format!("prefix of {cut} bytes gave {other:?}")),
        }
    }

    // Followed by the start of another frame: the decoder takes exactly its own bytes.
    let mut longer = bytes.clone();
    longer.extend_from_slice(&[0x01, 0x03]);
    match decode(&longer, entry, &expected, shape, &wide)? {
        Ok(Decoded::Frame { consumed, .. }) if consumed == bytes.len() => {}
        other => return Err(format!("frame plus trailing bytes gave {other:?}")),
    }

    let words = value_words(&expected);
    for value in &entry.values {
        check_value(value, &words)?;
    }

    if let Some(printed) = &entry.printed {
        if printed == &entry.bytes {
            return Err("`printed` equals `bytes`: drop it or correct the frame".into());
        }
        // What the manual printed must not decode to the corrected frame.
        if let Ok(Ok(Decoded::Frame { frame, .. })) =
            decode(&printed.0, entry, &expected, shape, &wide)
        {
            if frame == expected_outcome(&expected) {
                return Err("`printed` decodes to the same frame as `bytes`".into());
            }
        }
        if entry.note.is_none() {
            return Err("a corrected frame needs a `note` saying what the manual printed".into());
        }
    }
    Ok(())
}

fn check_family(family: &str) {
    let file = files::load(family).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(file.family, family, "family field of {family}.yaml");
    let shape = ExceptionShape::from(file.exception_shape);

    let mut ids = std::collections::HashSet::new();
    let mut failures = Vec::new();
    for entry in &file.frames {
        if !ids.insert(entry.id.as_str()) {
            failures.push(format!("{}: duplicate id", entry.id));
        }
        if let Err(problem) = check_entry(entry, shape) {
            failures.push(format!("{} (§{}): {problem}", entry.id, entry.section));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} golden frames of {} fail:\n{}",
        failures.len(),
        file.frames.len(),
        file.manual,
        failures.join("\n")
    );

    let derived = file
        .frames
        .iter()
        .filter(|e| e.origin == Some(Origin::Derived))
        .count();
    let printed = file.frames.len() - derived;
    // The counts of the files reviewed against their manuals; a new family's file is checked
    // frame by frame above until its counts are recorded here.
    if let Some((_, want_printed, want_derived)) =
        EXPECTED_COUNTS.iter().find(|(name, ..)| *name == family)
    {
        assert_eq!(
            (printed, derived),
            (*want_printed, *want_derived),
            "{family}: (printed, derived) frame counts changed"
        );
    }
    let corrected = file.frames.iter().filter(|e| e.printed.is_some()).count();
    eprintln!(
        "{family}: {printed} printed + {derived} derived golden frames pass ({corrected} corrected errata)"
    );
}

optobus_tests::golden_cases!(golden, check_family);

#[test]
fn every_golden_file_names_a_spec() {
    let files = std::fs::read_dir(files::directory()).expect("tests/golden");
    let mut checked = 0;
    for path in files.filter_map(|e| e.ok().map(|e| e.path())) {
        if path.extension().is_some_and(|e| e == "yaml") {
            let family = path
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or_default();
            assert!(
                optobus_tests::specs::path(family).exists(),
                "{} has no spec",
                path.display()
            );
            checked += 1;
        }
    }
    assert!(checked > 0, "no golden file found");
}
