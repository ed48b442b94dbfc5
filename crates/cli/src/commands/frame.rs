//! `optobus frame`: request bytes for a PLC programmer, and captured frames explained.
//!
//! `frame encode` prints the exact bytes the drivers send for a read (a register or a group, in
//! the fewest requests) or a validated write (a 32-bit value as two FC06 in the order the
//! device needs, or the rangefinder's single 4-byte FC06). `frame decode` explains bytes
//! captured on the wire field by field: request, reply or exception, CRC checked, registers
//! named and values decoded. Nothing here does I/O, and no input makes it panic.

use clap::{Args, Subcommand};
use optobus_device::{DeviceInfo, RegisterInfo};
use optobus_inspect::{hex, parse_hex, EncodedFrame, ExplainedFrame, Framing, HexError};
use serde::Serialize;
use serde_json::json;

use crate::connect::Global;
use crate::error::CliError;
use crate::models;
use crate::render::{pretty, print};

/// `optobus frame …`.
#[derive(Debug, Subcommand)]
pub(crate) enum FrameCommand {
    /// Print the exact request bytes of a read or a write, one frame per line, in the order
    /// they must be sent.
    Encode {
        /// Sensor family (the list of models is added at startup).
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
        /// Sensor family (the list of models is added at startup).
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

/// Prints the frames (JSON with `--json`). The global `--slave` is the slave (default: the
/// model's factory address); the global `--tcp` implies Modbus TCP framing like `--mbap`.
pub(crate) fn run(global: &Global, command: &FrameCommand) -> Result<(), CliError> {
    let framing = |mbap: bool| {
        if mbap || global.tcp.is_some() {
            Framing::Tcp
        } else {
            Framing::Rtu
        }
    };
    match command {
        FrameCommand::Encode { family, request } => {
            let device = models::find(family)?;
            let slave = global.slave.unwrap_or(device.default_slave);
            let frames = match request {
                EncodeRequest::Read { .. } if slave == 0 => {
                    return Err(CliError::new(
                        "a read sent to slave 0, the broadcast address, gets no reply",
                    )
                    .hint("give the device's address, 1 to 247, with --slave"))
                }
                EncodeRequest::Read { name, options } => {
                    encode_read(device, name, options.channel, slave, framing(options.mbap))?
                }
                EncodeRequest::Set {
                    name,
                    value,
                    options,
                } => {
                    let register = one_register(device, name, options.channel)?;
                    encode_write(device, register, value, slave, framing(options.mbap))?
                }
            };
            print(&render(&frames, global.json, render_encoded));
        }
        FrameCommand::Decode {
            family,
            hex,
            mbap,
            address,
        } => {
            let device = models::find(family)?;
            let bytes = parse_hex(&hex.join(" ")).map_err(hex_refused)?;
            let frames = optobus_inspect::decode(device, &bytes, framing(*mbap), *address)?;
            print(&render(&frames, global.json, render_decoded));
        }
    }
    Ok(())
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

/// A refused hex argument, with an example of what works.
fn hex_refused(error: HexError) -> CliError {
    let hint = match error {
        HexError::NotHex(_) => {
            "give bytes like `01 04 00 00 00 02 71 CB`, `010400000002 71CB` or `0x01 0x04 …`"
        }
        HexError::OddDigits(_) => "write every byte as two digits, e.g. `01 04 00 00`",
        HexError::Empty => "e.g. `optobus frame decode p-series 01 04 00 00 00 02 71 CB`",
    };
    CliError::new(error.to_string()).hint(hint)
}

/// The frames that read `name` (a register, a repeat member or a group).
fn encode_read(
    device: &'static DeviceInfo,
    name: &str,
    channel: Option<u8>,
    slave: u8,
    framing: Framing,
) -> Result<Vec<EncodedFrame>, CliError> {
    let registers = optobus_inspect::resolve(device, name, channel)?;
    if !registers.iter().any(|r| r.access.readable()) {
        return Err(
            CliError::new(format!("`{name}` is write-only: there is nothing to read")).hint(
                format!(
                    "encode a write instead: `optobus frame encode {} set {name} VALUE`",
                    device.family
                ),
            ),
        );
    }
    optobus_inspect::encode_read(device, &registers, slave, framing).map_err(not_encoded)
}

/// The frames that write `text` to `register`, validated as the drivers do.
fn encode_write(
    device: &'static DeviceInfo,
    register: &'static RegisterInfo,
    text: &str,
    slave: u8,
    framing: Framing,
) -> Result<Vec<EncodedFrame>, CliError> {
    let words = optobus_inspect::parse_value(register, text)?;
    let frames = optobus_inspect::encode_write(device, register, &words, slave, framing)
        .map_err(not_encoded)?;
    if frames.is_empty() {
        return Err(CliError::new(format!(
            "`{text}` gives no words to write to `{}`",
            register.name
        )));
    }
    Ok(frames)
}

/// The one register `name` stands for: not a group, one copy.
fn one_register(
    device: &'static DeviceInfo,
    name: &str,
    channel: Option<u8>,
) -> Result<&'static RegisterInfo, CliError> {
    match optobus_inspect::resolve(device, name, channel)?.as_slice() {
        [one] => Ok(*one),
        many if device.group(name).is_some() => {
            let names: Vec<&str> = many.iter().map(|r| r.name).collect();
            Err(CliError::new(format!(
                "`{name}` is a group: set its registers one at a time ({})",
                names.join(", ")
            )))
        }
        many => Err(CliError::new(format!(
            "`{name}` has {} copies: choose one with --channel 1 to {}",
            many.len(),
            many.len()
        ))),
    }
}

fn not_encoded(error: optobus_inspect::EncodeError) -> CliError {
    CliError::new(format!("cannot encode the request: {error}"))
}

/// `{"frames": [...]}` as pretty JSON, or each frame as text.
fn render<F: Serialize>(frames: &[F], json: bool, text: fn(&[F]) -> String) -> String {
    if json {
        let frames = serde_json::to_value(frames).unwrap_or_default();
        return pretty(&json!({ "frames": frames }));
    }
    text(frames)
}

/// One `# description` line above each frame's hex, so a line copies as it is.
fn render_encoded(frames: &[EncodedFrame]) -> String {
    frames
        .iter()
        .map(|frame| format!("# {}\n{}", frame.description, hex(&frame.bytes)))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Frames explained, field by field, numbered when there are several.
fn render_decoded(frames: &[ExplainedFrame]) -> String {
    let shown: Vec<String> = frames
        .iter()
        .enumerate()
        .map(|(i, frame)| match frames.len() {
            1 => frame.to_string(),
            _ => format!("frame {}: {frame}", i + 1),
        })
        .collect();
    shown.join("\n\n")
}
