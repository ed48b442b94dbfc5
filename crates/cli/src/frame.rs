//! `optobus frame`: request bytes for a PLC programmer, and captured frames explained.
//!
//! `frame encode` prints the exact bytes the drivers send for a read (a register or a group, in
//! the fewest requests) or a validated write (a 32-bit value as two FC06 in the order the
//! device needs, or the rangefinder's single 4-byte FC06). `frame decode` explains bytes
//! captured on the wire field by field: request, reply or exception, CRC checked, registers
//! named and values decoded. Nothing here does I/O, and no input makes it panic.

use clap::{Args, Subcommand};
use optobus_codec::crc::crc16;
use optobus_codec::value::{join_u32, split_u32, u32_writes, WordOrder};
use optobus_codec::{rtu, tcp, ExceptionShape, ReadFunction, Request, WriteValue};
use optobus_device::{
    Addressing, CommandInfo, DeviceInfo, LongWrites, RegisterInfo, Table, ValueKind,
};
use serde_json::{json, Value as Json};

use crate::error::CliError;
use crate::link::hex;
use crate::models;
use crate::values::{self, Value};

/// `optobus frame …`.
#[derive(Debug, Subcommand)]
pub(crate) enum FrameCommand {
    /// Print the exact request bytes of a read or a write, one frame per line, in the order
    /// they must be sent.
    Encode {
        /// Sensor family: p-series, rangefinder, ccs, lc-rs, ccf.
        #[arg(value_name = "MODEL")]
        family: String,
        /// What to encode.
        #[command(subcommand)]
        request: EncodeRequest,
    },
    /// Explain captured bytes field by field: request, reply or exception, CRC checked,
    /// registers named and values decoded.
    ///
    /// A request followed by its reply (as captured on the line) is decoded as a pair, so the
    /// reply's registers are named.
    Decode {
        /// Sensor family: p-series, rangefinder, ccs, lc-rs, ccf.
        #[arg(value_name = "MODEL")]
        family: String,
        /// The bytes in hex: one string or several, spaces optional, `0x` prefixes allowed.
        #[arg(required = true, value_name = "HEX")]
        hex: Vec<String>,
        /// Modbus TCP framing (MBAP header, no CRC) instead of RTU; `--tcp HOST` implies it.
        #[arg(long)]
        mbap: bool,
        /// Start address of the read a lone reply answers (a reply does not carry it).
        #[arg(long, value_parser = parse_address)]
        address: Option<u16>,
    },
}

/// `optobus frame encode MODEL …`.
#[derive(Debug, Subcommand)]
pub(crate) enum EncodeRequest {
    /// Read a register or a group, in the fewest requests.
    Read {
        /// Register or group name (`optobus registers MODEL` lists them).
        name: String,
        #[command(flatten)]
        options: EncodeOptions,
    },
    /// Write a register: engineering units (`100us`, `42.5`) or code names.
    Set {
        /// Register name.
        name: String,
        /// The value.
        #[arg(allow_hyphen_values = true)]
        value: String,
        #[command(flatten)]
        options: EncodeOptions,
    },
}

/// Options of `frame encode read` and `frame encode set`.
#[derive(Debug, Args)]
pub(crate) struct EncodeOptions {
    /// Copy of a per-channel register (CCF channels 1 to 4).
    #[arg(long)]
    channel: Option<u8>,
    /// Modbus TCP framing (MBAP header, transaction ids from 1, unit id = slave) instead of
    /// RTU; `--tcp HOST` implies it.
    #[arg(long)]
    mbap: bool,
}

/// Runs `command`; gives the text to print (JSON when `json`). `slave` is the global
/// `--slave` (default: the model's factory address); `tcp` says the global `--tcp` was given,
/// which implies Modbus TCP framing like `--mbap`.
pub(crate) fn run(
    command: &FrameCommand,
    json: bool,
    slave: Option<u8>,
    tcp: bool,
) -> Result<String, CliError> {
    match command {
        FrameCommand::Encode { family, request } => {
            let device = models::find(family)?;
            let slave = slave.unwrap_or(device.default_slave);
            let (planned, options) = match request {
                EncodeRequest::Read { .. } if slave == 0 => {
                    return Err(CliError::new(
                        "a read sent to slave 0, the broadcast address, gets no reply",
                    )
                    .hint("give the device's address, 1 to 247, with --slave"))
                }
                EncodeRequest::Read { name, options } => {
                    (plan_read(device, name, options.channel)?, options)
                }
                EncodeRequest::Set {
                    name,
                    value,
                    options,
                } => (plan_write(device, name, value, options.channel)?, options),
            };
            let framing = if options.mbap || tcp {
                Framing::Tcp
            } else {
                Framing::Rtu
            };
            let frames = encode(&planned, slave, framing)?;
            Ok(render_encoded(&frames, json))
        }
        FrameCommand::Decode {
            family,
            hex,
            mbap,
            address,
        } => {
            let device = models::find(family)?;
            let bytes = parse_hex(hex)?;
            let framing = if *mbap || tcp {
                Framing::Tcp
            } else {
                Framing::Rtu
            };
            let frames = decode(device, &bytes, framing, *address)?;
            Ok(render_decoded(&frames, json))
        }
    }
}

/// `16`, or `0x10`.
fn parse_address(text: &str) -> Result<u16, String> {
    let text = text.trim();
    let parsed = match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(digits) => u16::from_str_radix(digits, 16),
        None => text.parse(),
    };
    parsed.map_err(|_| {
        format!("`{text}` is not a register address (0 to 65535, or 0x0000 to 0xFFFF)")
    })
}

/// RTU (slave, PDU, CRC) or Modbus TCP (MBAP header, PDU).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Framing {
    Rtu,
    Tcp,
}

// ---------------------------------------------------------------------------------- encode

/// A request to send, and what it does in words.
#[derive(Clone, Debug, PartialEq)]
struct Planned {
    request: Request,
    description: String,
}

/// The read function of a table.
fn read_function(table: Table) -> ReadFunction {
    match table {
        Table::Holding => ReadFunction::Holding,
        Table::Input => ReadFunction::Input,
    }
}

/// The requests that read `name` (a register, a repeat member or a group).
fn plan_read(
    device: &'static DeviceInfo,
    name: &str,
    channel: Option<u8>,
) -> Result<Vec<Planned>, CliError> {
    let registers = values::resolve(device, name, channel)?;
    let readable: Vec<&'static RegisterInfo> = registers
        .iter()
        .copied()
        .filter(|r| r.access.readable())
        .collect();
    if readable.is_empty() {
        return Err(
            CliError::new(format!("`{name}` is write-only: there is nothing to read")).hint(
                format!(
                    "encode a write instead: `optobus frame encode {} set {name} VALUE`",
                    device.family
                ),
            ),
        );
    }
    Ok(optobus_driver::plan_reads(device, &readable)
        .into_iter()
        .map(|span| Planned {
            request: Request::Read {
                function: read_function(span.table),
                address: span.address,
                count: span.count,
            },
            description: format!(
                "read {}",
                span_text(device, span.table, span.address, usize::from(span.count))
            ),
        })
        .collect())
}

/// The requests that write `text` to register `name`, validated as the drivers do.
fn plan_write(
    device: &'static DeviceInfo,
    name: &str,
    text: &str,
    channel: Option<u8>,
) -> Result<Vec<Planned>, CliError> {
    let registers = values::resolve(device, name, channel)?;
    let register = match registers.as_slice() {
        [one] => *one,
        many if device.group(name).is_some() => {
            let names: Vec<&str> = many.iter().map(|r| r.name).collect();
            return Err(CliError::new(format!(
                "`{name}` is a group: set its registers one at a time ({})",
                names.join(", ")
            )));
        }
        many => {
            return Err(CliError::new(format!(
                "`{name}` has {} copies: choose one with --channel 1 to {}",
                many.len(),
                many.len()
            )))
        }
    };
    let words = values::parse(register, text)?;
    let value = values::decode(register, &words);
    let planned = write_plan(device, register, &words, &value);
    if planned.is_empty() {
        return Err(CliError::new(format!(
            "`{text}` gives no words to write to `{name}`"
        )));
    }
    Ok(planned)
}

/// The FC06 requests that store `words` in `register`, as `optobus_driver::Core` sends them:
/// one per word; a 32-bit value as two in the register's write order, or as one 4-byte FC06
/// on devices that take it (the rangefinder).
fn write_plan(
    device: &DeviceInfo,
    register: &'static RegisterInfo,
    words: &[u16],
    value: &Value,
) -> Vec<Planned> {
    let table = register.table.as_str();
    match *words {
        [word] => vec![Planned {
            request: Request::Write {
                address: register.address,
                value: WriteValue::Word(word),
            },
            description: format!(
                "write {table} {} = 0x{word:04X}: {} = {value}",
                register.address, register.name
            ),
        }],
        [first, second] if device.long_writes == LongWrites::Wide => {
            // The wire carries the words in address order, most significant byte first.
            let wire = join_u32([first, second], WordOrder::HighFirst);
            vec![Planned {
                request: Request::Write {
                    address: register.address,
                    value: WriteValue::DoubleWord(wire),
                },
                description: format!(
                    "write {table} {} = 0x{wire:08X} (one FC06 with 4 data bytes): {} = {value}",
                    register.address, register.name
                ),
            }]
        }
        [first, second] => {
            let joined = join_u32([first, second], register.word_order);
            let high_offset = high_word_offset(register.word_order);
            u32_writes(joined, register.word_order, register.write_order)
                .iter()
                .enumerate()
                .map(|(i, write)| {
                    let address = register.address.wrapping_add(write.offset);
                    let half = if write.offset == high_offset {
                        "high"
                    } else {
                        "low"
                    };
                    Planned {
                        request: Request::Write {
                            address,
                            value: WriteValue::Word(write.value),
                        },
                        description: format!(
                            "write {table} {address} = 0x{:04X}: {half} word of {} = {value} \
                             (frame {} of 2, {half} word {})",
                            write.value,
                            register.name,
                            i + 1,
                            if i == 0 { "first" } else { "last" }
                        ),
                    }
                })
                .collect()
        }
        _ => (register.address..)
            .zip(words)
            .enumerate()
            .map(|(i, (address, word))| Planned {
                request: Request::Write {
                    address,
                    value: WriteValue::Word(*word),
                },
                description: format!(
                    "write {table} {address} = 0x{word:04X}: word {} of {} of {} = {value}",
                    i + 1,
                    words.len(),
                    register.name
                ),
            })
            .collect(),
    }
}

/// The offset (0 or 1) of the high word of a register pair in `order`.
fn high_word_offset(order: WordOrder) -> u16 {
    match order {
        WordOrder::HighFirst => 0,
        WordOrder::LowFirst => 1,
    }
}

/// Bytes of each planned request in `framing`, with its description. TCP frames take
/// transaction ids 1, 2, … and the slave as unit id.
fn encode(
    planned: &[Planned],
    slave: u8,
    framing: Framing,
) -> Result<Vec<(Vec<u8>, String)>, CliError> {
    let mut frames = Vec::with_capacity(planned.len());
    for (i, plan) in planned.iter().enumerate() {
        let mut buf = [0u8; tcp::MAX_FRAME_LEN];
        let (len, description) = match framing {
            Framing::Rtu => (
                rtu::encode_request(&mut buf, slave, &plan.request),
                plan.description.clone(),
            ),
            Framing::Tcp => {
                let transaction = u16::try_from(i + 1).unwrap_or(u16::MAX);
                let header = tcp::Header {
                    transaction,
                    unit: slave,
                };
                (
                    tcp::encode_request(&mut buf, header, &plan.request),
                    format!(
                        "{}; transaction {transaction}, unit {slave}",
                        plan.description
                    ),
                )
            }
        };
        let len = len.map_err(|e| CliError::new(format!("cannot encode the request: {e}")))?;
        let bytes = buf.get(..len).unwrap_or_default().to_vec();
        frames.push((bytes, description));
    }
    Ok(frames)
}

/// One `# description` line above each frame's hex, so a line copies as it is; or JSON.
fn render_encoded(frames: &[(Vec<u8>, String)], json: bool) -> String {
    if json {
        let frames: Vec<Json> = frames
            .iter()
            .map(|(bytes, description)| json!({"hex": hex(bytes), "description": description}))
            .collect();
        return pretty(&json!({ "frames": frames }));
    }
    frames
        .iter()
        .map(|(bytes, description)| format!("# {description}\n{}", hex(bytes)))
        .collect::<Vec<_>>()
        .join("\n")
}

/// JSON text for people and scripts alike.
fn pretty(value: &Json) -> String {
    serde_json::to_string_pretty(value).unwrap_or_else(|_| value.to_string())
}

// ------------------------------------------------------------------------ registers by address

/// What a run of words at some address holds.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Held {
    /// A whole register.
    Whole(&'static RegisterInfo),
    /// Part of a register, from its word `usize` on (the read starts or stops inside it).
    Part(&'static RegisterInfo, usize),
    /// No register is defined there.
    Nothing,
}

/// A run of words of a read and what it holds.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Slot {
    /// Index of the first word in the read.
    offset: usize,
    /// Words.
    len: usize,
    /// Register address of the first word.
    address: u32,
    held: Held,
}

/// The register that starts at `address` of `table`.
fn register_at(device: &DeviceInfo, table: Table, address: u32) -> Option<&'static RegisterInfo> {
    device
        .registers
        .iter()
        .find(|r| r.table == table && u32::from(r.address) == address)
}

/// The register `address` lies inside of (not at its start), and the word it is.
fn register_around(
    device: &DeviceInfo,
    table: Table,
    address: u32,
) -> Option<(&'static RegisterInfo, usize)> {
    device.registers.iter().find_map(|r| {
        let inner = address.checked_sub(u32::from(r.address))?;
        (r.table == table && inner > 0 && inner < u32::from(r.words)).then_some((r, inner as usize))
    })
}

/// What `count` words read from `start` of `table` hold. With one address per field (the
/// rangefinder) each address holds a whole field, whatever its width.
fn layout(device: &DeviceInfo, table: Table, start: u16, count: usize) -> Vec<Slot> {
    let mut slots = Vec::new();
    let mut offset = 0usize;
    let mut address = u32::from(start);
    while offset < count {
        let left = count - offset;
        let (len, held) = match register_at(device, table, address) {
            Some(r) if usize::from(r.words) <= left => {
                (usize::from(r.words).max(1), Held::Whole(r))
            }
            Some(r) => (left, Held::Part(r, 0)),
            None => match (device.addressing, register_around(device, table, address)) {
                (Addressing::Word, Some((r, inner))) => (
                    (usize::from(r.words) - inner).min(left),
                    Held::Part(r, inner),
                ),
                _ => (1, Held::Nothing),
            },
        };
        slots.push(Slot {
            offset,
            len,
            address,
            held,
        });
        offset += len;
        address += match device.addressing {
            Addressing::Word => len as u32,
            Addressing::Field => 1,
        };
    }
    slots
}

/// `input 0-9` (one address per word) or `holding 2, 2 words` (one per field).
fn address_text(device: &DeviceInfo, table: Table, start: u32, count: usize) -> String {
    let table = table.as_str();
    match device.addressing {
        Addressing::Word if count > 1 => {
            format!("{table} {start}-{}", u64::from(start) + count as u64 - 1)
        }
        Addressing::Field if count > 1 => format!("{table} {start}, {count} words"),
        _ => format!("{table} {start}"),
    }
}

/// `input 0-9 (distance_1 .. statistic_2, 5 registers)`: a read's addresses and registers.
fn span_text(device: &DeviceInfo, table: Table, start: u16, count: usize) -> String {
    let mut names: Vec<&str> = Vec::new();
    for slot in layout(device, table, start, count) {
        if let Held::Whole(r) | Held::Part(r, _) = slot.held {
            if names.last() != Some(&r.name) {
                names.push(r.name);
            }
        }
    }
    let list = match names.as_slice() {
        [] => "no register defined there".to_owned(),
        [_] | [_, _] | [_, _, _] => names.join(", "),
        [first, .., last] => format!("{first} .. {last}, {} registers", names.len()),
    };
    format!(
        "{} ({list})",
        address_text(device, table, u32::from(start), count)
    )
}

/// The command that writes `raw` to `register`, if one does.
fn command_for(
    device: &'static DeviceInfo,
    register: &RegisterInfo,
    raw: u32,
) -> Option<&'static CommandInfo> {
    device.commands.iter().find(|c| {
        c.value == raw
            && (c.register == register.name || register.member_name() == Some(c.register))
    })
}

/// A register's decoded value for scripts.
fn register_json(register: &RegisterInfo, words: &[u16], value: Option<&Value>) -> Json {
    let mut entry = json!({
        "name": register.name,
        "table": register.table.as_str(),
        "address": register.address,
        "words": words.iter().map(|w| format!("0x{w:04X}")).collect::<Vec<_>>(),
    });
    if let (Some(value), Some(object)) = (value, entry.as_object_mut()) {
        object.insert("value".into(), value.to_json());
        object.insert("text".into(), json!(value.to_string()));
    }
    entry
}

/// Why a written value would be refused, if the register's range or codes say so.
fn write_problem(register: &RegisterInfo, words: &[u16], value: &Value) -> Option<String> {
    if !register.access.writable() {
        return Some(format!(
            "`{}` is read-only: the device will refuse this write",
            register.name
        ));
    }
    if let Value::Code(code, None) = value {
        return Some(format!("{code} is no code `{}` defines", register.name));
    }
    let (ValueKind::Scalar(scalar), Some((min, max))) = (register.kind, register.range) else {
        return None;
    };
    let bits = optobus_driver::raw_bits(register, words);
    let raw = scalar.extend(bits);
    (!(min..=max).contains(&raw)).then(|| {
        format!(
            "outside the allowed range {}",
            values::range_text(register).unwrap_or_else(|| format!("{min} ..= {max}"))
        )
    })
}

// ---------------------------------------------------------------------------------- decode

/// Bytes given as hex: several arguments or one, spaces (or `,`, `:`, `;`) optional, `0x`
/// prefixes allowed. A token of one or two digits is one byte; longer ones are byte pairs.
fn parse_hex(args: &[String]) -> Result<Vec<u8>, CliError> {
    let mut bytes = Vec::new();
    let separators = |c: char| c.is_whitespace() || matches!(c, ',' | ':' | ';');
    for token in args.iter().flat_map(|a| a.split(separators)) {
        if token.is_empty() {
            continue;
        }
        let digits = token
            .strip_prefix("0x")
            .or_else(|| token.strip_prefix("0X"))
            .unwrap_or(token);
        let nibbles: Option<Vec<u8>> = digits
            .chars()
            .map(|c| c.to_digit(16).and_then(|d| u8::try_from(d).ok()))
            .collect();
        let nibbles = match nibbles {
            Some(n) if !n.is_empty() => n,
            _ => return Err(CliError::new(format!("`{token}` is not hex")).hint(
                "give bytes like `01 04 00 00 00 02 71 CB`, `010400000002 71CB` or `0x01 0x04 …`",
            )),
        };
        match nibbles.as_slice() {
            [low] => bytes.push(*low),
            [high, low] => bytes.push((high << 4) | low),
            _ if nibbles.len() % 2 == 1 => {
                return Err(
                    CliError::new(format!("`{token}` has an odd number of hex digits"))
                        .hint("write every byte as two digits, e.g. `01 04 00 00`"),
                )
            }
            _ => bytes.extend(nibbles.chunks(2).map(|pair| match pair {
                [high, low] => (high << 4) | low,
                _ => 0,
            })),
        }
    }
    if bytes.is_empty() {
        return Err(CliError::new("no bytes given")
            .hint("e.g. `optobus frame decode p-series 01 04 00 00 00 02 71 CB`"));
    }
    Ok(bytes)
}

/// Some bytes of a frame and what they mean.
#[derive(Clone, Debug, PartialEq)]
struct Field {
    bytes: Vec<u8>,
    meaning: String,
}

impl Field {
    fn new(bytes: &[u8], meaning: impl Into<String>) -> Self {
        Self {
            bytes: bytes.to_vec(),
            meaning: meaning.into(),
        }
    }
}

/// An RTU CRC: what the frame carries and what its bytes give.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct CrcCheck {
    received: u16,
    computed: u16,
}

/// One frame explained.
#[derive(Clone, Debug, PartialEq)]
struct Explained {
    bytes: Vec<u8>,
    /// `read_request`, `read_reply`, `write`, `write_echo`, `exception`, `other`, or
    /// `undecoded` for bytes left over after the frames before them.
    kind: &'static str,
    summary: String,
    fields: Vec<Field>,
    crc: Option<CrcCheck>,
    registers: Vec<Json>,
    notes: Vec<String>,
}

/// A request seen earlier in the same input, to pair its reply with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Sent {
    /// Slave address, or unit id.
    slave: u8,
    /// MBAP transaction id (TCP only).
    transaction: Option<u16>,
    request: Request,
}

/// What decoding a frame knows from outside it.
#[derive(Clone, Copy, Debug, Default)]
struct Context {
    /// The request just before, if the previous frame was one.
    previous: Option<Sent>,
    /// `--address`: where a lone read reply starts.
    address: Option<u16>,
}

/// What a PDU is, from its function code (and length).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PduKind {
    ReadRequest,
    ReadReply,
    Write,
    Exception(ExceptionShape),
    Other,
}

/// A PDU explained.
#[derive(Clone, Debug, PartialEq)]
struct Pdu {
    kind: &'static str,
    summary: String,
    fields: Vec<Field>,
    registers: Vec<Json>,
    notes: Vec<String>,
    /// The request this PDU is, to pair the next frame with.
    request: Option<Request>,
}

/// Every frame in `bytes`. Frames after the first that cannot be decoded are kept as one
/// `undecoded` entry saying why; if the first cannot be, that is the error.
fn decode(
    device: &'static DeviceInfo,
    bytes: &[u8],
    framing: Framing,
    address: Option<u16>,
) -> Result<Vec<Explained>, CliError> {
    let mut context = Context {
        previous: None,
        address,
    };
    let mut frames: Vec<Explained> = Vec::new();
    let mut at = 0usize;
    while let Some(rest) = bytes.get(at..).filter(|rest| !rest.is_empty()) {
        let decoded = match framing {
            Framing::Rtu => rtu_frame(device, rest, &context),
            Framing::Tcp => tcp_frame(device, rest, &context),
        };
        match decoded {
            Ok((explained, sent)) => {
                at += explained.bytes.len().max(1);
                context.previous = sent;
                frames.push(explained);
            }
            Err(error) if frames.is_empty() => return Err(error),
            Err(error) => {
                frames.push(Explained {
                    bytes: rest.to_vec(),
                    kind: "undecoded",
                    summary: format!("left over: {error}"),
                    fields: Vec::new(),
                    crc: None,
                    registers: Vec::new(),
                    notes: Vec::new(),
                });
                break;
            }
        }
    }
    Ok(frames)
}

/// A way to read the bytes at the start of an RTU frame, and its length.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Candidate {
    kind: PduKind,
    len: usize,
}

impl Candidate {
    /// `a read request (8 bytes)`, for "too short" messages.
    fn describe(self, rest: &[u8]) -> String {
        let len = self.len;
        match self.kind {
            PduKind::ReadRequest => format!("a read request ({len} bytes)"),
            PduKind::ReadReply => format!(
                "a read reply with byte count {} ({len} bytes)",
                rest.get(2).copied().unwrap_or(0)
            ),
            PduKind::Write if len == 10 => format!("a 4-byte write or its echo ({len} bytes)"),
            PduKind::Write => format!("a write or its echo ({len} bytes)"),
            PduKind::Exception(_) => format!("an exception reply ({len} bytes)"),
            PduKind::Other => format!("a frame ({len} bytes)"),
        }
    }
}

/// The ways to read an RTU frame starting at `rest`, most likely first.
fn rtu_candidates(device: &DeviceInfo, rest: &[u8], context: &Context) -> Vec<Candidate> {
    let function = rest.get(1).copied().unwrap_or(0);
    let device_exception = device.frame_shape.exception;
    let other_exception = match device_exception {
        ExceptionShape::Standard => ExceptionShape::CountedWord,
        ExceptionShape::CountedWord => ExceptionShape::Standard,
    };
    match function {
        0x03 | 0x04 => {
            let request = Candidate {
                kind: PduKind::ReadRequest,
                len: 8,
            };
            let Some(&byte_count) = rest.get(2) else {
                return vec![request];
            };
            let reply = Candidate {
                kind: PduKind::ReadReply,
                len: 5 + usize::from(byte_count),
            };
            let answers_previous = matches!(
                context.previous,
                Some(Sent { request: Request::Read { function: f, .. }, .. }) if f.code() == function
            );
            if answers_previous {
                vec![reply, request]
            } else {
                vec![request, reply]
            }
        }
        0x06 => {
            let address = match (rest.get(2), rest.get(3)) {
                (Some(&high), Some(&low)) => u16::from_be_bytes([high, low]),
                _ => 0,
            };
            let wide = device.frame_shape.write_width(address).bytes() == 4;
            let (first, second) = if wide { (10, 8) } else { (8, 10) };
            [first, second]
                .into_iter()
                .map(|len| Candidate {
                    kind: PduKind::Write,
                    len,
                })
                .collect()
        }
        0x83 | 0x84 | 0x86 => [device_exception, other_exception]
            .into_iter()
            .map(|shape| Candidate {
                kind: PduKind::Exception(shape),
                len: shape.pdu_len() + 3,
            })
            .collect(),
        _ => vec![Candidate {
            kind: PduKind::Other,
            len: rest.len(),
        }],
    }
}

/// True when the last two bytes of `frame` are the CRC of the others.
fn crc_ok(frame: &[u8]) -> bool {
    match frame.split_last_chunk::<2>() {
        Some((body, crc)) if !body.is_empty() => crc16(body) == u16::from_le_bytes(*crc),
        _ => false,
    }
}

/// True when `bytes` start like a Modbus TCP frame (protocol id 0, a length that fits).
fn looks_like_mbap(bytes: &[u8]) -> bool {
    match bytes {
        [_, _, 0, 0, high, low, ..] => {
            let length = usize::from(u16::from_be_bytes([*high, *low]));
            length >= 2 && 6 + length <= bytes.len()
        }
        _ => false,
    }
}

/// The RTU frame at the start of `rest`, and the request it is (for pairing its reply).
fn rtu_frame(
    device: &'static DeviceInfo,
    rest: &[u8],
    context: &Context,
) -> Result<(Explained, Option<Sent>), CliError> {
    let tcp_hint = |error: CliError| {
        if looks_like_mbap(rest) {
            error.hint("these bytes look like Modbus TCP: add --mbap")
        } else {
            error
        }
    };
    if rest.len() < 4 {
        let count = rest.len();
        return Err(tcp_hint(CliError::new(format!(
            "{count} byte{} too short for a Modbus RTU frame (slave, function, data and a \
             2-byte CRC: at least 4 bytes)",
            if count == 1 { " is" } else { "s are" }
        ))));
    }
    let candidates = rtu_candidates(device, rest, context);
    let fitting: Vec<Candidate> = candidates
        .iter()
        .copied()
        .filter(|c| c.len <= rest.len())
        .collect();
    // A good CRC decides; else the reading that uses every byte; else the likeliest one,
    // which must fit (rather than a shorter reading that happens to).
    let chosen = fitting
        .iter()
        .find(|c| rest.get(..c.len).is_some_and(crc_ok))
        .or_else(|| fitting.iter().find(|c| c.len == rest.len()))
        .or_else(|| candidates.first().filter(|c| c.len <= rest.len()))
        .copied();
    let Some(chosen) = chosen else {
        let options: Vec<String> = candidates
            .iter()
            .filter(|c| c.len > rest.len())
            // Other widths of a write or an exception are fallbacks, not worth naming.
            .filter(|c| {
                matches!(c.kind, PduKind::ReadRequest | PduKind::ReadReply)
                    || Some(*c) == candidates.first()
            })
            .map(|c| c.describe(rest))
            .collect();
        return Err(tcp_hint(CliError::new(format!(
            "{} bytes are too short for {}",
            rest.len(),
            options.join(" or ")
        ))));
    };
    let frame = rest.get(..chosen.len).unwrap_or(rest);
    let (Some((&slave, _)), Some((body, crc))) =
        (frame.split_first(), frame.split_last_chunk::<2>())
    else {
        return Err(CliError::new("too short for a Modbus RTU frame"));
    };
    let check = CrcCheck {
        received: u16::from_le_bytes(*crc),
        computed: crc16(body),
    };
    let good_crc = check.received == check.computed;
    if chosen.kind == PduKind::Other && !good_crc {
        let function = body.get(1).copied().unwrap_or(0);
        return Err(tcp_hint(
            CliError::new(format!(
                "not a Modbus RTU frame of {}: function {function:02X} is not one it answers \
                 ({}) and the last two bytes are no CRC of the others",
                device.family,
                function_list(device)
            ))
            .hint("the first byte must be the slave address, the second the function code"),
        ));
    }
    let pdu_bytes = body.get(1..).unwrap_or_default();
    let pdu = explain_pdu(device, chosen.kind, pdu_bytes, context);
    let mut fields = vec![Field::new(&[slave], slave_text(slave))];
    fields.extend(pdu.fields);
    let crc_bytes = check.received.to_le_bytes();
    let right = check.computed.to_le_bytes();
    let mut notes = pdu.notes;
    if good_crc {
        fields.push(Field::new(
            &crc_bytes,
            format!("CRC 0x{:04X} (low byte first): correct", check.computed),
        ));
    } else {
        fields.push(Field::new(
            &crc_bytes,
            format!("CRC wrong: these bytes give {}", hex(&right)),
        ));
        notes.insert(
            0,
            format!(
                "wrong CRC: the frame carries {}, the right CRC is {} (0x{:04X}, low byte \
                 first); a device ignores a frame with a wrong CRC",
                hex(&crc_bytes),
                hex(&right),
                check.computed
            ),
        );
    }
    if let (Some(previous), None) = (context.previous, pdu.request) {
        if previous.slave != slave && previous.slave != 0 {
            notes.push(format!(
                "the request above went to slave {}, this reply is from slave {slave}",
                previous.slave
            ));
        }
    }
    let sent = pdu.request.map(|request| Sent {
        slave,
        transaction: None,
        request,
    });
    Ok((
        Explained {
            bytes: frame.to_vec(),
            kind: pdu.kind,
            summary: pdu.summary,
            fields,
            crc: Some(check),
            registers: pdu.registers,
            notes,
        },
        sent,
    ))
}

/// The Modbus TCP frame at the start of `rest`, and the request it is.
fn tcp_frame(
    device: &'static DeviceInfo,
    rest: &[u8],
    context: &Context,
) -> Result<(Explained, Option<Sent>), CliError> {
    let rtu_hint = |error: CliError| {
        if crc_ok(rest) {
            error.hint("these bytes look like Modbus RTU: leave out --mbap")
        } else {
            error
        }
    };
    let [t0, t1, p0, p1, l0, l1, unit, ..] = *rest else {
        return Err(rtu_hint(CliError::new(format!(
            "{} bytes are too short for a Modbus TCP frame (a 7-byte MBAP header and a PDU)",
            rest.len()
        ))));
    };
    let transaction = u16::from_be_bytes([t0, t1]);
    let protocol = u16::from_be_bytes([p0, p1]);
    let length = u16::from_be_bytes([l0, l1]);
    if protocol != 0 {
        return Err(rtu_hint(CliError::new(format!(
            "not a Modbus TCP frame: the protocol id is 0x{protocol:04X}, Modbus requires 0"
        ))));
    }
    if length < 2 {
        return Err(CliError::new(format!(
            "MBAP length {length} is too short for a unit id and a function code (at least 2)"
        )));
    }
    let total = 6 + usize::from(length);
    let (Some(frame), Some(pdu_bytes)) = (rest.get(..total), rest.get(7..total)) else {
        return Err(rtu_hint(CliError::new(format!(
            "{} bytes are too short for the {total} bytes the MBAP header announces \
             (length {length}: unit id and {} PDU bytes)",
            rest.len(),
            length - 1
        ))));
    };
    let function = pdu_bytes.first().copied().unwrap_or(0);
    let kind = match function {
        0x03 | 0x04 if pdu_bytes.len() == 5 => PduKind::ReadRequest,
        0x03 | 0x04 => PduKind::ReadReply,
        0x06 => PduKind::Write,
        0x83 | 0x84 | 0x86 if pdu_bytes.len() == 4 => {
            PduKind::Exception(ExceptionShape::CountedWord)
        }
        0x83 | 0x84 | 0x86 => PduKind::Exception(ExceptionShape::Standard),
        _ => PduKind::Other,
    };
    let pdu = explain_pdu(device, kind, pdu_bytes, context);
    let mut fields = vec![
        Field::new(&[t0, t1], format!("transaction {transaction}")),
        Field::new(&[p0, p1], "protocol id 0 (Modbus)"),
        Field::new(
            &[l0, l1],
            format!("length {length} (unit id and {} PDU bytes)", length - 1),
        ),
        Field::new(&[unit], format!("unit {unit}")),
    ];
    fields.extend(pdu.fields);
    let mut notes = pdu.notes;
    if let (Some(previous), None) = (context.previous, pdu.request) {
        if previous.transaction.is_some_and(|t| t != transaction) {
            notes.push(format!(
                "the request above has transaction {}, this reply {transaction}",
                previous.transaction.unwrap_or(0)
            ));
        }
    }
    let sent = pdu.request.map(|request| Sent {
        slave: unit,
        transaction: Some(transaction),
        request,
    });
    Ok((
        Explained {
            bytes: frame.to_vec(),
            kind: pdu.kind,
            summary: format!("{}; transaction {transaction}, unit {unit}", pdu.summary),
            fields,
            crc: None,
            registers: pdu.registers,
            notes,
        },
        sent,
    ))
}

/// `slave 1`, `slave 0 (broadcast)`.
fn slave_text(slave: u8) -> String {
    if slave == 0 {
        "slave 0 (broadcast)".to_owned()
    } else {
        format!("slave {slave}")
    }
}

/// The standard name of a Modbus function code.
fn function_name(code: u8) -> &'static str {
    match code {
        0x01 => "read coils",
        0x02 => "read discrete inputs",
        0x03 => "read holding registers",
        0x04 => "read input registers",
        0x05 => "write single coil",
        0x06 => "write single register",
        0x07 => "read exception status",
        0x08 => "diagnostics",
        0x0F => "write multiple coils",
        0x10 => "write multiple registers",
        0x11 => "report server id",
        0x16 => "mask write register",
        0x17 => "read/write multiple registers",
        0x2B => "encapsulated interface transport",
        _ => "no standard function",
    }
}

/// `03, 04, 06`: the function codes `device` answers.
fn function_list(device: &DeviceInfo) -> String {
    let codes: Vec<String> = device
        .functions
        .iter()
        .map(|f| format!("{f:02X}"))
        .collect();
    codes.join(", ")
}

/// The table a read function code reads.
fn table_of(function: u8) -> Option<Table> {
    match function {
        0x03 => Some(Table::Holding),
        0x04 => Some(Table::Input),
        _ => None,
    }
}

/// The codes a family's manual gives for its exception replies, where the spec lists them.
/// What exception code `code` means on `device`.
fn exception_meaning(device: &DeviceInfo, code: u16) -> String {
    if let Some(info) = device
        .exception_codes
        .iter()
        .find(|c| c.code == u32::from(code))
    {
        return format!("{} ({})", info.name, info.doc.trim_end_matches('.'));
    }
    match optobus_codec::ExceptionCode(code).standard_name() {
        Some(name) => name.to_owned(),
        None => "a code the manual does not define".to_owned(),
    }
}

/// A PDU (function code and data) explained.
fn explain_pdu(device: &'static DeviceInfo, kind: PduKind, pdu: &[u8], context: &Context) -> Pdu {
    match kind {
        PduKind::ReadRequest => read_request(device, pdu),
        PduKind::ReadReply => read_reply(device, pdu, context),
        PduKind::Write => write(device, pdu, context),
        PduKind::Exception(shape) => exception(device, pdu, shape, context),
        PduKind::Other => other(device, pdu, None),
    }
}

/// A PDU shown as function code and data, with `why` it is not decoded further.
fn other(device: &DeviceInfo, pdu: &[u8], why: Option<String>) -> Pdu {
    let Some((&function, data)) = pdu.split_first() else {
        return Pdu {
            kind: "other",
            summary: "empty PDU".to_owned(),
            fields: Vec::new(),
            registers: Vec::new(),
            notes: why.into_iter().collect(),
            request: None,
        };
    };
    let name = if function & 0x80 != 0 {
        format!(
            "exception reply to function {:02X} ({})",
            function & 0x7F,
            function_name(function & 0x7F)
        )
    } else {
        function_name(function).to_owned()
    };
    let mut fields = vec![Field::new(
        &[function],
        format!("function {function:02X}: {name}"),
    )];
    if !data.is_empty() {
        fields.push(Field::new(data, format!("data, {} bytes", data.len())));
    }
    let mut notes: Vec<String> = why.into_iter().collect();
    if !device.functions.contains(&(function & 0x7F)) {
        notes.push(format!(
            "{} answers functions {} only",
            device.family,
            function_list(device)
        ));
    }
    Pdu {
        kind: "other",
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
        format!("function {function:02X}: {}", function_name(function)),
    )
}

/// An FC03/FC04 request: address and count.
fn read_request(device: &'static DeviceInfo, pdu: &[u8]) -> Pdu {
    let (&[function, a0, a1, c0, c1], Some(table)) = (pdu, pdu.first().copied().and_then(table_of))
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
    if count == 0 || count > optobus_codec::MAX_READ_WORDS {
        notes.push(format!(
            "a read asks for 1 to {} words: a device answers this with an exception",
            optobus_codec::MAX_READ_WORDS
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
    let registers = layout(device, table, address, usize::from(count))
        .iter()
        .filter_map(|slot| match slot.held {
            Held::Whole(r) | Held::Part(r, _) => Some(register_json(r, &[], None)),
            Held::Nothing => None,
        })
        .collect();
    Pdu {
        kind: "read_request",
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
            function: read_function(table),
            address,
            count,
        }),
    }
}

/// An FC03/FC04 reply: byte count and data, named and decoded when its start is known (from
/// the request before it, or `--address`).
fn read_reply(device: &'static DeviceInfo, pdu: &[u8], context: &Context) -> Pdu {
    let (Some((&function, rest)), Some(table)) =
        (pdu.split_first(), pdu.first().copied().and_then(table_of))
    else {
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
    let start = match context.previous {
        Some(Sent {
            request:
                Request::Read {
                    function: asked,
                    address,
                    count,
                },
            ..
        }) if asked.code() == function => {
            if usize::from(count) * 2 == data.len() {
                Some(address)
            } else {
                notes.push(format!(
                    "the request above asked for {count} words, this reply carries {} bytes",
                    data.len()
                ));
                context.address
            }
        }
        _ => context.address,
    };
    let start = start.or_else(|| {
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
                        let value = values::decode(r, slot_words);
                        registers.push(register_json(r, slot_words, Some(&value)));
                        format!("{at}: {} = {value}", r.name)
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
    Pdu {
        kind: "read_reply",
        summary,
        fields,
        registers,
        notes,
        request: None,
    }
}

/// The lowest start address from which `count` words of `table` are whole, readable
/// registers: where a lone reply most likely starts. With one address per field (the
/// rangefinder), where every read asks for one field, a field of that width comes first.
fn guess_start(device: &DeviceInfo, table: Table, count: usize) -> Option<u16> {
    if device.addressing == Addressing::Field {
        let field = device
            .registers
            .iter()
            .filter(|r| r.table == table && r.access.readable())
            .filter(|r| usize::from(r.words) == count)
            .map(|r| r.address)
            .min();
        if field.is_some() {
            return field;
        }
    }
    let mut starts: Vec<u16> = device
        .registers
        .iter()
        .filter(|r| r.table == table && r.access.readable())
        .map(|r| r.address)
        .collect();
    starts.sort_unstable();
    starts.dedup();
    let whole = |slot: &Slot| matches!(slot.held, Held::Whole(r) if r.access.readable());
    starts
        .into_iter()
        .find(|&start| count > 0 && layout(device, table, start, count).iter().all(whole))
}

/// `0x0036 0xB0BE`.
fn raw_words(words: &[u16]) -> String {
    let shown: Vec<String> = words.iter().map(|w| format!("0x{w:04X}")).collect();
    shown.join(" ")
}

/// An FC06 request or its echo: the register written and the value, decoded.
fn write(device: &'static DeviceInfo, pdu: &[u8], context: &Context) -> Pdu {
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
        Some(previous) if previous.request == request => ("write_echo", "write reply (echo)", None),
        Some(Sent {
            request: Request::Write { .. },
            ..
        }) => {
            notes.push(
                "not the echo of the write above: an FC06 reply repeats the request byte for \
                 byte"
                    .to_owned(),
            );
            ("write", "write request, or its echo", Some(request))
        }
        _ => ("write", "write request, or its echo", Some(request)),
    };
    if kind == "write_echo" {
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
    Pdu {
        kind,
        summary: format!("{role}: holding {address}: {}", meaning.text),
        fields: vec![
            function_field(0x06),
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

/// What an FC06 of `value` to holding `address` does.
struct WriteMeaning {
    /// The register (or half of it) written.
    target: String,
    /// `sampling_interval = us_100 (20)`.
    text: String,
    registers: Vec<Json>,
    notes: Vec<String>,
}

/// What writing `value` to holding `address` of `device` means.
fn write_meaning(device: &'static DeviceInfo, address: u16, value: WriteValue) -> WriteMeaning {
    let table = Table::Holding;
    let whole = |register: &'static RegisterInfo, words: &[u16]| {
        let decoded = values::decode(register, words);
        let mut text = format!("{} = {decoded}", register.name);
        if let Some(command) =
            command_for(device, register, optobus_driver::raw_bits(register, words))
        {
            text.push_str(&format!(" (command `{}`)", command.name));
        }
        WriteMeaning {
            target: register.name.to_owned(),
            text,
            registers: vec![register_json(register, words, Some(&decoded))],
            notes: write_problem(register, words, &decoded)
                .into_iter()
                .collect(),
        }
    };
    let exact = register_at(device, table, u32::from(address));
    match (exact, value) {
        (Some(register), WriteValue::Word(word)) if register.words <= 1 => whole(register, &[word]),
        (Some(register), WriteValue::DoubleWord(wide)) => {
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
        (Some(register), WriteValue::Word(word)) => half_write(device, register, 0, word),
        (None, WriteValue::Word(word)) => {
            match register_around(device, table, u32::from(address)) {
                Some((register, inner)) if device.addressing == Addressing::Word => {
                    half_write(device, register, inner, word)
                }
                _ => nothing_at(address),
            }
        }
        (None, WriteValue::DoubleWord(_)) => nothing_at(address),
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
        let high = u16::try_from(inner).ok() == Some(high_word_offset(register.word_order));
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
            optobus_codec::value::WriteOrder::HighWordFirst => "high",
            optobus_codec::value::WriteOrder::LowWordFirst => "low",
        };
        notes.push(format!(
            "`{}` is written as two FC06, the {first} word first (address {}..{})",
            register.name,
            register.address,
            u32::from(register.address) + 1
        ));
    }
    WriteMeaning {
        target: format!("{part} of {}", register.name),
        text: format!("{part} of {} = 0x{word:04X}", register.name),
        registers: vec![json!({
            "name": register.name,
            "table": register.table.as_str(),
            "address": register.address,
            "part": part,
            "words": [format!("0x{word:04X}")],
        })],
        notes,
    }
}

/// An exception reply: the function that failed and why.
fn exception(
    device: &'static DeviceInfo,
    pdu: &[u8],
    shape: ExceptionShape,
    context: &Context,
) -> Pdu {
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
    let failed = function & 0x7F;
    let meaning = exception_meaning(device, code);
    if let Some(first) = fields.first_mut() {
        first.meaning = format!(
            "function {function:02X}: exception reply to function {failed:02X} ({})",
            function_name(failed)
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
    Pdu {
        kind: "exception",
        summary: format!(
            "exception reply: function {failed:02X} ({}) failed: {meaning}",
            function_name(failed)
        ),
        fields,
        registers: Vec::new(),
        notes,
        request: None,
    }
}

/// Frames explained, field by field; or JSON.
fn render_decoded(frames: &[Explained], json: bool) -> String {
    if json {
        let frames: Vec<Json> = frames
            .iter()
            .map(|frame| {
                json!({
                    "hex": hex(&frame.bytes),
                    "kind": frame.kind,
                    "description": frame.summary,
                    "fields": frame.fields.iter().map(|f| json!({"hex": hex(&f.bytes), "meaning": f.meaning})).collect::<Vec<_>>(),
                    "crc": frame.crc.map(|c| json!({
                        "ok": c.received == c.computed,
                        "received": hex(&c.received.to_le_bytes()),
                        "expected": hex(&c.computed.to_le_bytes()),
                    })),
                    "registers": frame.registers,
                    "notes": frame.notes,
                })
            })
            .collect();
        return pretty(&json!({ "frames": frames }));
    }
    // Wider fields (long data) go on their own line rather than pushing every meaning right.
    const MAX_COLUMN: usize = 23;
    let mut out = Vec::new();
    for (i, frame) in frames.iter().enumerate() {
        let mut lines = Vec::new();
        if frames.len() > 1 {
            lines.push(format!("frame {}: {}", i + 1, frame.summary));
        } else {
            lines.push(frame.summary.clone());
        }
        if frame.fields.is_empty() {
            lines.push(format!("  {}", hex(&frame.bytes)));
        }
        let column = frame
            .fields
            .iter()
            .map(|f| hex(&f.bytes).len())
            .filter(|&len| len <= MAX_COLUMN)
            .max()
            .unwrap_or(2);
        for field in &frame.fields {
            let bytes = hex(&field.bytes);
            if bytes.len() > column {
                lines.push(format!("  {bytes}"));
                lines.push(format!("  {:column$}  {}", "", field.meaning));
            } else {
                lines.push(format!("  {bytes:column$}  {}", field.meaning));
            }
        }
        for note in &frame.notes {
            lines.push(format!("  note: {note}"));
        }
        out.push(lines.join("\n"));
    }
    out.join("\n\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: &DeviceInfo = &optobus_p_series::DEVICE;
    const RANGEFINDER: &DeviceInfo = &optobus_rangefinder::DEVICE;
    const LC_RS: &DeviceInfo = &optobus_lc_rs::DEVICE;
    const CCF: &DeviceInfo = &optobus_ccf::DEVICE;

    fn bytes(text: &str) -> Vec<u8> {
        parse_hex(&[text.to_owned()]).unwrap_or_default()
    }

    fn rtu_hex(planned: &[Planned], slave: u8) -> Vec<String> {
        encode(planned, slave, Framing::Rtu)
            .map(|frames| frames.iter().map(|(b, _)| hex(b)).collect())
            .unwrap_or_default()
    }

    fn decoded(device: &'static DeviceInfo, text: &str) -> Vec<Explained> {
        decode(device, &bytes(text), Framing::Rtu, None).unwrap_or_default()
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
        ] {
            assert_eq!(bytes(text), expected, "{text}");
        }
        let split = parse_hex(&[
            "01 04".to_owned(),
            "0000".to_owned(),
            "0x0002 71CB".to_owned(),
        ]);
        assert_eq!(split.ok(), Some(expected));
    }

    #[test]
    fn bad_hex_is_refused_with_a_reason() {
        let message = |text: &str| {
            parse_hex(&[text.to_owned()])
                .err()
                .map(|e| e.message)
                .unwrap_or_default()
        };
        assert!(message("01 0G").contains("not hex"));
        assert!(message("0x").contains("not hex"));
        assert!(message("héllo").contains("not hex"));
        assert!(message("010").contains("odd number"));
        assert!(message("   ").contains("no bytes"));
    }

    #[test]
    fn addresses_parse_in_decimal_or_hex() {
        assert_eq!(parse_address("16"), Ok(16));
        assert_eq!(parse_address("0x10"), Ok(16));
        assert!(parse_address("70000").is_err());
    }

    #[test]
    fn read_of_a_register_is_one_request() {
        let planned = plan_read(P, "distance_1", None).unwrap_or_default();
        assert_eq!(rtu_hex(&planned, 1), ["01 04 00 00 00 02 71 CB"]);
        assert_eq!(
            planned.first().map(|p| p.description.as_str()),
            Some("read input 0-1 (distance_1)")
        );
    }

    #[test]
    fn read_of_a_group_is_the_manuals_request() {
        // 5.4: the buffer page, 122 registers from input 16.
        let planned = plan_read(P, "buffer_page", None).unwrap_or_default();
        assert_eq!(rtu_hex(&planned, 1), ["01 04 00 10 00 7A 70 2C"]);
        let planned = plan_read(P, "measurements", None).unwrap_or_default();
        assert_eq!(
            planned.first().map(|p| p.description.as_str()),
            Some("read input 0-9 (distance_1 .. statistic_2, 5 registers)")
        );
    }

    #[test]
    fn tcp_frames_count_transactions_from_one() {
        let planned = plan_read(P, "laser", None).unwrap_or_default();
        let frames = encode(&planned, 1, Framing::Tcp).unwrap_or_default();
        let shown: Vec<String> = frames.iter().map(|(b, _)| hex(b)).collect();
        assert_eq!(shown, ["00 01 00 00 00 06 01 03 00 00 00 03"]);
    }

    #[test]
    fn writes_follow_the_manuals_order() {
        // 5.2.1: sampling interval 100 us.
        let planned = plan_write(P, "sampling_interval", "100us", None).unwrap_or_default();
        assert_eq!(rtu_hex(&planned, 1), ["01 06 00 06 00 14 69 C4"]);
        // 4.1.2 note 4: slope 2.0 goes to register 28 (low word) first, then 27.
        let planned = plan_write(P, "position_1_slope", "2", None).unwrap_or_default();
        let addresses: Vec<u16> = planned
            .iter()
            .filter_map(|p| match p.request {
                Request::Write { address, .. } => Some(address),
                Request::Read { .. } => None,
            })
            .collect();
        assert_eq!(addresses, [28, 27]);
        assert!(planned
            .first()
            .is_some_and(|p| p.description.contains("low word")));
    }

    #[test]
    fn rangefinder_writes_32_bits_in_one_frame() {
        // 3.7: odd parity, 57600 baud.
        let planned = plan_write(
            RANGEFINDER,
            "serial_parameters",
            "parity=odd,baud_rate=57600",
            None,
        )
        .unwrap_or_default();
        assert_eq!(rtu_hex(&planned, 25), ["19 06 00 04 01 00 E1 00 5F 01"]);
    }

    #[test]
    fn invalid_writes_are_refused_before_encoding() {
        let error = plan_write(P, "light_power", "250", None).err();
        assert!(error.is_some_and(|e| e.message.contains("0.5")));
        assert!(plan_write(P, "distance_1", "1", None).is_err());
        assert!(plan_write(P, "laser", "1", None).is_err());
        assert!(plan_write(CCF, "exposure_time", "100us", None).is_err());
        assert!(plan_write(CCF, "exposure_time", "100us", Some(2)).is_ok());
    }

    #[test]
    fn a_request_and_its_reply_are_paired() {
        let frames = decoded(
            P,
            "01 04 00 00 00 06 70 08 01 04 0C 00 36 B0 BE 00 20 24 5C 00 56 D3 04 41 47",
        );
        assert_eq!(frames.len(), 2);
        let kinds: Vec<&str> = frames.iter().map(|f| f.kind).collect();
        assert_eq!(kinds, ["read_request", "read_reply"]);
        let reply = frames.get(1).map(|f| f.fields.clone()).unwrap_or_default();
        assert!(reply
            .iter()
            .any(|f| f.meaning == "input 0-1: distance_1 = 3.584190 mm"));
        assert!(reply
            .iter()
            .any(|f| f.meaning == "input 4-5: thickness = 5.690116 mm"));
    }

    #[test]
    fn a_lone_reply_is_placed_at_the_first_fitting_address() {
        // 5.3.1's reply alone: 6 input words, whole registers from input 0 on.
        let reply = bytes("01 04 0C 00 36 B0 BE 00 20 24 5C 00 56 D3 04 41 47");
        let lone = decode(P, &reply, Framing::Rtu, None).unwrap_or_default();
        let frame = lone.first();
        assert!(frame.is_some_and(|f| f.notes.iter().any(|n| n.contains("assumed"))));
        assert!(frame.is_some_and(|f| f.registers.len() == 3));
        // --address says where it starts: input 2 holds distance_2, thickness, statistic_1.
        let placed = decode(P, &reply, Framing::Rtu, Some(2)).unwrap_or_default();
        let frame = placed.first();
        assert!(frame.is_some_and(|f| !f.notes.iter().any(|n| n.contains("assumed"))));
        assert!(frame.is_some_and(|f| f
            .fields
            .iter()
            .any(|field| field.meaning == "input 2-3: distance_2 = 3.584190 mm")));
        // Words no run of whole registers holds stay raw.
        assert_eq!(guess_start(P, Table::Input, 200), None);
        assert_eq!(guess_start(RANGEFINDER, Table::Holding, 2), Some(2));
    }

    #[test]
    fn a_wrong_crc_is_flagged_with_the_right_one() {
        let frames = decoded(P, "01 04 00 00 00 02 71 CC");
        let frame = frames.first();
        assert!(frame.is_some_and(|f| f.crc
            == Some(CrcCheck {
                received: 0xCC71,
                computed: 0xCB71
            })));
        assert!(frame.is_some_and(|f| f.notes.iter().any(|n| n.contains("71 CB"))));
        assert!(frame.is_some_and(|f| f.kind == "read_request"));
    }

    #[test]
    fn a_write_and_its_echo() {
        let frames = decoded(P, "01 06 00 06 00 14 69 C4 01 06 00 06 00 14 69 C4");
        let kinds: Vec<&str> = frames.iter().map(|f| f.kind).collect();
        assert_eq!(kinds, ["write", "write_echo"]);
        assert!(frames
            .first()
            .is_some_and(|f| f.summary.contains("sampling_interval") && f.summary.contains("20")));
    }

    #[test]
    fn split_write_halves_are_named() {
        let frames = decoded(P, "01 06 00 1C 00 00 48 0C");
        assert!(frames
            .first()
            .is_some_and(|f| f.summary.contains("low word of position_1_slope")));
    }

    #[test]
    fn rangefinder_four_byte_write_decodes() {
        let frames = decoded(RANGEFINDER, "19 06 00 04 01 00 E1 00 5F 01");
        let frame = frames.first();
        assert!(frame.is_some_and(
            |f| f.bytes.len() == 10 && f.crc.is_some_and(|c| c.received == c.computed)
        ));
        assert!(
            frame.is_some_and(|f| f.summary.contains("serial_parameters")
                && f.summary.contains("odd")
                && f.summary.contains("57600"))
        );
    }

    #[test]
    fn lc_rs_exceptions_have_seven_bytes() {
        let frames = decoded(LC_RS, "01 83 02 00 01 50 44");
        let frame = frames.first();
        assert!(frame.is_some_and(|f| f.kind == "exception" && f.bytes.len() == 7));
        assert!(frame.is_some_and(|f| f.summary.contains("register_address_error")));
        // The same device's standard-shaped exception is still recognised, with a note.
        let standard = decoded(P, "01 83 02 C0 F1");
        assert!(standard
            .first()
            .is_some_and(|f| f.summary.contains("illegal_data_address")));
    }

    #[test]
    fn tcp_frames_are_paired_by_the_header() {
        let input = bytes(
            "00 00 00 00 00 06 01 04 00 00 00 06 \
             00 00 00 00 00 0F 01 04 0C 00 35 CB 69 00 1F 3A 6C 00 2A 05 D5",
        );
        let frames = decode(P, &input, Framing::Tcp, None).unwrap_or_default();
        assert_eq!(frames.len(), 2);
        assert!(frames.get(1).is_some_and(|f| f
            .fields
            .iter()
            .any(|field| field.meaning == "input 0-1: distance_1 = 3.525481 mm")));
    }

    #[test]
    fn short_and_foreign_input_gives_errors() {
        let message = |device: &'static DeviceInfo, text: &str, framing| {
            decode(device, &bytes(text), framing, None)
                .err()
                .map(|e| e.to_string())
                .unwrap_or_default()
        };
        assert!(message(P, "01 04", Framing::Rtu).contains("too short"));
        assert!(
            message(P, "01 04 00 00 00 02", Framing::Rtu).contains("too short for a read request")
        );
        assert!(message(P, "00 00 00 00 00 06 01 03 00 00 00 03", Framing::Rtu).contains("--mbap"));
        assert!(message(P, "01 03 00 00 00 03 05 CB", Framing::Tcp).contains("leave out --mbap"));
        assert!(message(P, "00 01 00 00 00 06 01", Framing::Tcp).contains("too short"));
    }

    #[test]
    fn no_input_panics() {
        // Every prefix and every one-byte corruption of real frames, and noise.
        let frames = [
            "01 04 00 00 00 06 70 08 01 04 0C 00 36 B0 BE 00 20 24 5C 00 56 D3 04 41 47",
            "19 06 00 04 01 00 E1 00 5F 01",
            "01 83 02 00 01 50 44",
            "00 00 00 00 00 0F 01 04 0C 00 35 CB 69 00 1F 3A 6C 00 2A 05 D5",
            "19 03 04 00 00 3D 9B 33 09",
        ];
        let devices: [&'static DeviceInfo; 3] = [P, RANGEFINDER, LC_RS];
        let mut state = 0x2545_F491_u32;
        let mut inputs: Vec<Vec<u8>> = Vec::new();
        for text in frames {
            let original = bytes(text);
            for end in 0..original.len() {
                inputs.push(original.get(..end).unwrap_or_default().to_vec());
                let mut corrupt = original.clone();
                state = state.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                if let Some(byte) = corrupt.get_mut(end) {
                    *byte = (state >> 16) as u8;
                }
                inputs.push(corrupt);
            }
        }
        for _ in 0..200 {
            state = state.wrapping_mul(1_103_515_245).wrapping_add(12_345);
            let len = (state >> 24) as usize % 24;
            inputs.push(
                (0..len)
                    .map(|i| (state >> (i % 24)) as u8 ^ i as u8)
                    .collect(),
            );
        }
        for input in &inputs {
            for device in devices {
                for framing in [Framing::Rtu, Framing::Tcp] {
                    for address in [None, Some(u16::MAX)] {
                        if let Ok(frames) = decode(device, input, framing, address) {
                            let _ = render_decoded(&frames, false);
                            let _ = render_decoded(&frames, true);
                        }
                    }
                }
            }
        }
    }
}
