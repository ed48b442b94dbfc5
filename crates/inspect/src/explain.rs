//! One PDU explained: read request, read reply, write or echo, exception, or other.

use optobus_codec::value::split_u32;
use optobus_codec::{
    exception_function, function_name, ExceptionCode, ExceptionShape, Request, WriteValue,
    MAX_READ_WORDS, WRITE_SINGLE,
};
use optobus_device::{DeviceInfo, Invalid, LongWrites, RegisterInfo, Table, WordOrder, WriteOrder};

use crate::frame::{Field, FrameKind, RegisterValue};
use crate::layout::{address_text, guess_start, layout, span_text, Held};
use crate::value::{decode_value, range_text};

/// A request seen earlier in the same input, to pair its reply with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Sent {
    /// Slave address, or unit id.
    pub(crate) slave: u8,
    /// MBAP transaction id (TCP only).
    pub(crate) transaction: Option<u16>,
    pub(crate) request: Request,
}

/// What decoding a frame knows from outside it.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Context {
    /// The request just before, if the previous frame was one.
    pub(crate) previous: Option<Sent>,
    /// Where a lone read reply starts, if the caller knows.
    pub(crate) address: Option<u16>,
}

/// How to explain a PDU: what it is, judged from its function code (and length). Not the
/// codec's request and reply types: a guess that the CRC and the pairing then confirm.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ExplainAs {
    ReadRequest,
    ReadReply,
    Write,
    Exception(ExceptionShape),
    Other,
}

/// A PDU explained (the body of an [`crate::ExplainedFrame`], before its framing is added).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ExplainedPdu {
    pub(crate) kind: FrameKind,
    pub(crate) summary: String,
    pub(crate) fields: Vec<Field>,
    pub(crate) registers: Vec<RegisterValue>,
    pub(crate) notes: Vec<String>,
    /// The request this PDU is, to pair the next frame with.
    pub(crate) request: Option<Request>,
}

/// The standard name of a function code, or `no standard function`.
fn name_of(function: u8) -> &'static str {
    function_name(function).unwrap_or("no standard function")
}

/// `03, 04, 06`: the function codes `device` answers.
pub(crate) fn function_list(device: &DeviceInfo) -> String {
    let codes: Vec<String> = device
        .functions
        .iter()
        .map(|f| format!("{f:02X}"))
        .collect();
    codes.join(", ")
}

/// What exception code `code` means on `device`: the spec's meaning, else the standard name.
fn exception_meaning(device: &DeviceInfo, code: u16) -> String {
    if let Some(info) = device
        .exception_codes
        .iter()
        .find(|c| c.code == u32::from(code))
    {
        return format!("{} ({})", info.name, info.doc.trim_end_matches('.'));
    }
    match ExceptionCode(code).standard_name() {
        Some(name) => name.to_owned(),
        None => "a code the manual does not define".to_owned(),
    }
}

/// A PDU (function code and data) explained.
pub(crate) fn explain_pdu(
    device: &DeviceInfo,
    kind: ExplainAs,
    pdu: &[u8],
    context: &Context,
) -> ExplainedPdu {
    match kind {
        ExplainAs::ReadRequest => read_request(device, pdu),
        ExplainAs::ReadReply => read_reply(device, pdu, context),
        ExplainAs::Write => write(device, pdu, context),
        ExplainAs::Exception(shape) => exception(device, pdu, shape, context),
        ExplainAs::Other => other(device, pdu, None),
    }
}

/// A PDU shown as function code and data, with `why` it is not decoded further.
fn other(device: &DeviceInfo, pdu: &[u8], why: Option<String>) -> ExplainedPdu {
    let Some((&function, data)) = pdu.split_first() else {
        return ExplainedPdu {
            kind: FrameKind::Other,
            summary: "empty PDU".to_owned(),
            fields: Vec::new(),
            registers: Vec::new(),
            notes: why.into_iter().collect(),
            request: None,
        };
    };
    let failed = exception_function(function);
    let name = match failed {
        Some(failed) => format!(
            "exception reply to function {failed:02X} ({})",
            name_of(failed)
        ),
        None => name_of(function).to_owned(),
    };
    let mut fields = vec![Field::new(
        &[function],
        format!("function {function:02X}: {name}"),
    )];
    if !data.is_empty() {
        fields.push(Field::new(data, format!("data, {} bytes", data.len())));
    }
    let mut notes: Vec<String> = why.into_iter().collect();
    if !device.functions.contains(&failed.unwrap_or(function)) {
        notes.push(format!(
            "{} answers functions {} only",
            device.family,
            function_list(device)
        ));
    }
    ExplainedPdu {
        kind: FrameKind::Other,
        summary: format!("function {function:02X} ({name}): not decoded"),
        fields,
        registers: Vec::new(),
        notes,
        request: None,
    }
}

/// `function 04: read input registers`.
fn function_field(function: u8) -> Field {
    Field::new(
        &[function],
        format!("function {function:02X}: {}", name_of(function)),
    )
}

/// An FC03/FC04 request: address and count.
fn read_request(device: &DeviceInfo, pdu: &[u8]) -> ExplainedPdu {
    let (&[function, a0, a1, c0, c1], Some(table)) =
        (pdu, pdu.first().copied().and_then(Table::of_function_code))
    else {
        return other(
            device,
            pdu,
            Some(format!(
                "a read request PDU has 5 bytes, this one {}",
                pdu.len()
            )),
        );
    };
    let address = u16::from_be_bytes([a0, a1]);
    let count = u16::from_be_bytes([c0, c1]);
    let mut notes = Vec::new();
    if count == 0 || count > MAX_READ_WORDS {
        notes.push(format!(
            "a read asks for 1 to {MAX_READ_WORDS} words: a device answers this with an exception"
        ));
    } else if count > device.max_read_words {
        notes.push(format!(
            "{} answers at most {} words per read",
            device.family, device.max_read_words
        ));
    }
    if !device.functions.contains(&function) {
        notes.push(format!(
            "{} does not answer function {function:02X} (it answers {})",
            device.family,
            function_list(device)
        ));
    }
    let held = layout(device, table, address, usize::from(count));
    for slot in &held {
        if let Held::Whole(r) | Held::Part(r, 0) = slot.held {
            if r.action {
                notes.push(format!(
                    "`{}` is an action register: the manual does not say what a read \
                     returns, so the words it answers have no known meaning",
                    r.name
                ));
            }
        }
    }
    let registers = held
        .iter()
        .filter_map(|slot| match slot.held {
            Held::Whole(r) | Held::Part(r, _) => Some(RegisterValue::new(r, &[], None)),
            Held::Nothing => None,
        })
        .collect();
    ExplainedPdu {
        kind: FrameKind::ReadRequest,
        summary: format!(
            "read request: {}",
            span_text(device, table, address, usize::from(count))
        ),
        fields: vec![
            function_field(function),
            Field::new(&[a0, a1], format!("address {address} (0x{address:04X})")),
            Field::new(
                &[c0, c1],
                format!("count {count} word{}", if count == 1 { "" } else { "s" }),
            ),
        ],
        registers,
        notes,
        request: Some(Request::Read {
            function: table.read_function(),
            address,
            count,
        }),
    }
}

/// Where a read reply starts: from the request before it, or the caller's address; notes
/// say when that is doubtful.
fn reply_start(
    context: &Context,
    function: u8,
    data_len: usize,
    notes: &mut Vec<String>,
) -> Option<u16> {
    match context.previous {
        Some(Sent {
            request:
                Request::Read {
                    function: asked,
                    address,
                    count,
                },
            ..
        }) if asked.code() == function => {
            if usize::from(count) * 2 == data_len {
                Some(address)
            } else {
                notes.push(format!(
                    "the request above asked for {count} words, this reply carries {data_len} bytes"
                ));
                context.address
            }
        }
        _ => context.address,
    }
}

/// An FC03/FC04 reply: byte count and data, named and decoded when its start is known (from
/// the request before it, or the caller's address).
fn read_reply(device: &DeviceInfo, pdu: &[u8], context: &Context) -> ExplainedPdu {
    let (Some((&function, rest)), Some(table)) = (
        pdu.split_first(),
        pdu.first().copied().and_then(Table::of_function_code),
    ) else {
        return other(device, pdu, None);
    };
    let Some((&byte_count, data)) = rest.split_first() else {
        return other(
            device,
            pdu,
            Some("a read reply needs a byte count".to_owned()),
        );
    };
    let mut notes = Vec::new();
    if data.len() != usize::from(byte_count) {
        notes.push(format!(
            "byte count {byte_count}, but {} data bytes follow",
            data.len()
        ));
    }
    let (pairs, odd) = data.as_chunks::<2>();
    let words: Vec<u16> = pairs.iter().map(|pair| u16::from_be_bytes(*pair)).collect();
    let start = reply_start(context, function, data.len(), &mut notes).or_else(|| {
        let guess = guess_start(device, table, words.len())?;
        notes.push(format!(
            "assumed to answer a read from {table} {guess}, the first address where {} words \
             are whole registers: a reply does not carry its start address (put the request's \
             bytes before it, or give --address N)",
            words.len(),
            table = table.as_str()
        ));
        Some(guess)
    });
    let mut fields = vec![
        function_field(function),
        Field::new(
            &[byte_count],
            format!(
                "byte count {byte_count} ({} word{})",
                byte_count / 2,
                if byte_count / 2 == 1 { "" } else { "s" }
            ),
        ),
    ];
    let mut registers = Vec::new();
    let summary = match start {
        Some(start) => {
            for slot in layout(device, table, start, words.len()) {
                let end = slot.offset + slot.len;
                let slot_words = words.get(slot.offset..end).unwrap_or_default();
                let slot_bytes = data.get(slot.offset * 2..end * 2).unwrap_or_default();
                let at = address_text(device, table, slot.address, slot.len);
                let meaning = match slot.held {
                    Held::Whole(r) => {
                        let value = decode_value(r, slot_words);
                        let text = format!("{at}: {} = {value}", r.name);
                        registers.push(RegisterValue::new(r, slot_words, Some(value)));
                        text
                    }
                    Held::Part(r, inner) => {
                        format!(
                            "{at}: {} of {}'s {} words, not decoded (the read cuts the register)",
                            raw_words(slot_words),
                            r.name,
                            r.words
                        ) + if inner > 0 { ", from its middle" } else { "" }
                    }
                    Held::Nothing => {
                        format!("{at}: no register defined ({})", raw_words(slot_words))
                    }
                };
                fields.push(Field::new(slot_bytes, meaning));
            }
            format!(
                "read reply: {}",
                span_text(device, table, start, words.len())
            )
        }
        None => {
            for (i, (word, pair)) in words.iter().zip(pairs).enumerate() {
                fields.push(Field::new(pair, format!("word {i}: 0x{word:04X} = {word}")));
            }
            if !words.is_empty() {
                notes.push(
                    "a reply does not say where it starts: put the request's bytes before it, \
                     or give --address N, to name and decode the registers"
                        .to_owned(),
                );
            }
            format!(
                "read reply: {} word{} of {} registers",
                words.len(),
                if words.len() == 1 { "" } else { "s" },
                table.as_str()
            )
        }
    };
    if !odd.is_empty() {
        fields.push(Field::new(odd, "odd byte: not a whole register"));
    }
    ExplainedPdu {
        kind: FrameKind::ReadReply,
        summary,
        fields,
        registers,
        notes,
        request: None,
    }
}

/// `0x0036 0xB0BE`.
fn raw_words(words: &[u16]) -> String {
    let shown: Vec<String> = words.iter().map(|w| format!("0x{w:04X}")).collect();
    shown.join(" ")
}

/// An FC06 request or its echo: the register written and the value, decoded.
fn write(device: &DeviceInfo, pdu: &[u8], context: &Context) -> ExplainedPdu {
    let (address_bytes, value) = match *pdu {
        [_, a0, a1, high, low] => ([a0, a1], WriteValue::Word(u16::from_be_bytes([high, low]))),
        [_, a0, a1, b3, b2, b1, b0] => (
            [a0, a1],
            WriteValue::DoubleWord(u32::from_be_bytes([b3, b2, b1, b0])),
        ),
        _ => {
            return other(
                device,
                pdu,
                Some(format!(
                    "an FC06 PDU has 2 data bytes (4 on the rangefinder), this one {}",
                    pdu.len().saturating_sub(3)
                )),
            )
        }
    };
    let address = u16::from_be_bytes(address_bytes);
    let request = Request::Write { address, value };
    let data = pdu.get(3..).unwrap_or_default();
    let meaning = write_meaning(device, address, value);
    let mut notes = meaning.notes;
    let wide = device.frame_shape.write_width(address).bytes() == 4;
    match (value, wide) {
        (WriteValue::DoubleWord(_), false) => notes.push(format!(
            "4 data bytes: {} takes 2 at address {address}",
            device.family
        )),
        (WriteValue::Word(_), true) => notes.push(format!(
            "2 data bytes: {} takes 4 at address {address} (one FC06 for the 32-bit value)",
            device.family
        )),
        _ => {}
    }
    let (kind, role, sent) = match context.previous {
        Some(previous) if previous.request == request => {
            (FrameKind::WriteEcho, "write reply (echo)", None)
        }
        Some(Sent {
            request: Request::Write { .. },
            ..
        }) => {
            notes.push(
                "not the echo of the write above: an FC06 reply repeats the request byte for \
                 byte"
                    .to_owned(),
            );
            (
                FrameKind::Write,
                "write request, or its echo",
                Some(request),
            )
        }
        _ => (
            FrameKind::Write,
            "write request, or its echo",
            Some(request),
        ),
    };
    if kind == FrameKind::WriteEcho {
        notes.push("identical to the request above: the device took the write".to_owned());
    } else {
        notes.push(
            "an FC06 reply echoes the request byte for byte, so request and reply look the same"
                .to_owned(),
        );
    }
    let value_text = match value {
        WriteValue::Word(word) => format!("value 0x{word:04X} = {word}"),
        WriteValue::DoubleWord(long) => format!("value 0x{long:08X} = {long} (4 data bytes)"),
    };
    ExplainedPdu {
        kind,
        summary: format!("{role}: holding {address}: {}", meaning.text),
        fields: vec![
            function_field(WRITE_SINGLE),
            Field::new(
                &address_bytes,
                format!("address {address} (0x{address:04X}): {}", meaning.target),
            ),
            Field::new(data, format!("{value_text}: {}", meaning.text)),
        ],
        registers: meaning.registers,
        notes,
        request: sent,
    }
}

/// What an FC06 to some holding address does.
struct WriteMeaning {
    /// The register (or half of it) written.
    target: String,
    /// `sampling_interval = us_100 (20)`.
    text: String,
    registers: Vec<RegisterValue>,
    notes: Vec<String>,
}

/// Why the device would refuse writing `words` to `register`, if it would.
fn write_problem(register: &RegisterInfo, words: &[u16]) -> Option<String> {
    if !register.access.writable() {
        return Some(format!(
            "`{}` is read-only: the device will refuse this write",
            register.name
        ));
    }
    let name = register.name;
    Some(match register.check(register.raw(words)).err()? {
        Invalid::UndefinedCode { field: None, code } => {
            format!("{code} is no code `{name}` defines")
        }
        Invalid::UndefinedCode {
            field: Some(field),
            code,
        } => format!("{code} is no code `{name}.{}` defines", field.name),
        Invalid::OutOfRange {
            field: None,
            min,
            max,
            ..
        } => format!(
            "outside the allowed range {}",
            range_text(register).unwrap_or_else(|| format!("{min} ..= {max}"))
        ),
        Invalid::OutOfRange {
            field: Some(field),
            min,
            max,
            ..
        } => format!(
            "`{name}.{}` outside its allowed range {min} ..= {max}",
            field.name
        ),
        Invalid::Unlisted { allowed, .. } => {
            let shown: Vec<String> = allowed
                .iter()
                .map(|&raw| match register.scale {
                    Some(scale) => optobus_codec::value::Fixed::new(raw, scale).to_string(),
                    None => raw.to_string(),
                })
                .collect();
            format!(
                "not a value `{name}` accepts (only {}): the device will refuse this write",
                shown.join(", ")
            )
        }
        Invalid::StrayBits { bits } => {
            format!("bits 0x{bits:X} lie outside every field of `{name}`")
        }
    })
}

/// What writing `value` to holding `address` of `device` means.
fn write_meaning(device: &DeviceInfo, address: u16, value: WriteValue) -> WriteMeaning {
    let whole = |register: &'static RegisterInfo, words: &[u16]| {
        let decoded = decode_value(register, words);
        let mut text = format!("{} = {decoded}", register.name);
        if let Some(command) = device.command_writing(register, register.raw(words)) {
            text.push_str(&format!(" (command `{}`)", command.name));
        }
        WriteMeaning {
            target: register.name.to_owned(),
            text,
            notes: write_problem(register, words).into_iter().collect(),
            registers: vec![RegisterValue::new(register, words, Some(decoded))],
        }
    };
    match (device.register_at(Table::Holding, address), value) {
        (Some((register, 0)), WriteValue::Word(word)) if register.words <= 1 => {
            whole(register, &[word])
        }
        (Some((register, 0)), WriteValue::DoubleWord(wide)) => {
            let words = split_u32(wide, WordOrder::HighFirst);
            let mut meaning = whole(register, &words);
            if register.words != 2 {
                meaning.notes.push(format!(
                    "`{}` is {} word{}, this write carries 2",
                    register.name,
                    register.words,
                    if register.words == 1 { "" } else { "s" }
                ));
            }
            meaning
        }
        (Some((register, inner)), WriteValue::Word(word)) => {
            half_write(device, register, usize::from(inner), word)
        }
        (_, _) => nothing_at(address),
    }
}

/// A write to an address no register is at.
fn nothing_at(address: u16) -> WriteMeaning {
    WriteMeaning {
        target: "no register".to_owned(),
        text: "no register defined there".to_owned(),
        registers: Vec::new(),
        notes: vec![format!(
            "no register at holding {address}: the device will likely answer exception 02"
        )],
    }
}

/// One word of a register of several (a split 32-bit write sends each half in its own FC06).
fn half_write(
    device: &DeviceInfo,
    register: &'static RegisterInfo,
    inner: usize,
    word: u16,
) -> WriteMeaning {
    let part = if register.words == 2 {
        let high = u16::try_from(inner).ok() == Some(register.word_order.high_offset());
        format!("{} word", if high { "high" } else { "low" })
    } else {
        format!("word {} of {}", inner + 1, register.words)
    };
    let mut notes = Vec::new();
    if device.long_writes == LongWrites::Wide {
        notes.push(format!(
            "{} takes a 32-bit value in one FC06 with 4 data bytes",
            device.family
        ));
    } else if register.words == 2 {
        let first = match register.write_order {
            WriteOrder::HighWordFirst => "high",
            WriteOrder::LowWordFirst => "low",
        };
        notes.push(format!(
            "`{}` is written as two FC06, the {first} word first (address {}..{})",
            register.name,
            register.address,
            u32::from(register.address) + 1
        ));
    }
    let mut registers = RegisterValue::new(register, &[word], None);
    registers.part = Some(part.clone());
    WriteMeaning {
        target: format!("{part} of {}", register.name),
        text: format!("{part} of {} = 0x{word:04X}", register.name),
        registers: vec![registers],
        notes,
    }
}

/// An exception reply: the function that failed and why.
fn exception(
    device: &DeviceInfo,
    pdu: &[u8],
    shape: ExceptionShape,
    context: &Context,
) -> ExplainedPdu {
    let mut fields = Vec::new();
    let mut notes = Vec::new();
    let (function, code) = match (shape, pdu) {
        (ExceptionShape::Standard, &[function, code]) => {
            fields.push(Field::new(&[function], String::new()));
            fields.push(Field::new(&[code], String::new()));
            (function, u16::from(code))
        }
        (ExceptionShape::CountedWord, &[function, count, high, low]) => {
            fields.push(Field::new(&[function], String::new()));
            fields.push(Field::new(
                &[count],
                if count == 2 {
                    "byte count 2".to_owned()
                } else {
                    format!("byte count {count} (LC-RS-style exceptions carry 2)")
                },
            ));
            fields.push(Field::new(&[high, low], String::new()));
            (function, u16::from_be_bytes([high, low]))
        }
        _ => {
            return other(
                device,
                pdu,
                Some("an exception reply of unexpected length".to_owned()),
            )
        }
    };
    let failed = exception_function(function).unwrap_or(function);
    let meaning = exception_meaning(device, code);
    if let Some(first) = fields.first_mut() {
        first.meaning = format!(
            "function {function:02X}: exception reply to function {failed:02X} ({})",
            name_of(failed)
        );
    }
    if let Some(last) = fields.last_mut() {
        last.meaning = match shape {
            ExceptionShape::Standard => format!("exception code {code:02X}: {meaning}"),
            ExceptionShape::CountedWord => format!("error code 0x{code:04X}: {meaning}"),
        };
    }
    if shape != device.frame_shape.exception {
        notes.push(match device.frame_shape.exception {
            ExceptionShape::Standard => format!(
                "{} sends standard exceptions (one code byte); this one has a byte count and a \
                 16-bit code (as LC-RS sends)",
                device.family
            ),
            ExceptionShape::CountedWord => format!(
                "{} sends exceptions with a byte count and a 16-bit code; this one is standard \
                 (one code byte)",
                device.family
            ),
        });
    }
    if let Some(previous) = context.previous {
        if previous.request.function_code() == failed {
            notes.push("answers the request above: the device refused it".to_owned());
        }
    }
    ExplainedPdu {
        kind: FrameKind::Exception,
        summary: format!(
            "exception reply: function {failed:02X} ({}) failed: {meaning}",
            name_of(failed)
        ),
        fields,
        registers: Vec::new(),
        notes,
        request: None,
    }
}
