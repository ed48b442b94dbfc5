//! `optobus frame`: request bytes for a PLC programmer, and captured frames explained.
//!
//! `frame encode` prints the exact bytes the drivers send for a read (a register or a group, in
//! the fewest requests) or a validated write (a 32-bit value as two FC06 in the order the
//! device needs, or the rangefinder's single 4-byte FC06). `frame decode` explains bytes
//! captured on the wire field by field: request, reply or exception, CRC checked, registers
//! named and values decoded. Nothing here does I/O, and no input makes it panic.

use clap::{Args, Subcommand};
use optobus_inspect::{hex, parse_hex, EncodedFrame, ExplainedFrame, Framing, HexError};
use serde::Serialize;
use serde_json::json;

use crate::connect::Options;
use crate::error::CliError;
use crate::inputs;
use crate::render::{pretty, print};

/// `optobus frame …`.
#[derive(Debug, Subcommand)]
pub(crate) enum FrameCommand {
    /// Print the exact request bytes of a read or a write, one frame per line, in the order
    /// they must be sent.
    Encode {
        /// Sensor family (the list of models is added at startup).
        #[arg(id = "model", value_name = "MODEL")]
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
        #[arg(id = "model", value_name = "MODEL")]
        family: String,
        /// The bytes in hex: one string or several, spaces optional, `0x` prefixes allowed.
        #[arg(required = true, value_name = "HEX")]
        hex: Vec<String>,
        /// Modbus TCP framing (MBAP header, no CRC) instead of RTU.
        #[arg(long)]
        mbap: bool,
        /// Start address of the read a lone reply answers (a reply does not carry it): 0-based,
        /// decimal or 0x hex.
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
    /// RTU.
    #[arg(long)]
    mbap: bool,
    /// Slave address (unit id) in the frames, 0 to 247 (default: the model's factory
    /// setting).
    #[arg(long, value_parser = inputs::parse_slave)]
    slave: Option<u8>,
}

/// Prints the frames (JSON with `--json`).
pub(crate) fn run(options: &Options, command: &FrameCommand) -> Result<(), CliError> {
    let framing = |mbap: bool| if mbap { Framing::Tcp } else { Framing::Rtu };
    match command {
        FrameCommand::Encode { family, request } => {
            let device = options.device_or(Some(family))?;
            let slave = |encode: &EncodeOptions| encode.slave.unwrap_or(device.default_slave);
            let frames = match request {
                EncodeRequest::Read { name, options } => optobus_inspect::encode_read_of(
                    device,
                    name,
                    options.channel,
                    slave(options),
                    framing(options.mbap),
                )?,
                EncodeRequest::Set {
                    name,
                    value,
                    options,
                } => optobus_inspect::encode_write_of(
                    device,
                    name,
                    options.channel,
                    value,
                    slave(options),
                    framing(options.mbap),
                )?,
            };
            print(&render(&frames, options.json, render_encoded));
        }
        FrameCommand::Decode {
            family,
            hex,
            mbap,
            address,
        } => {
            let device = options.device_or(Some(family))?;
            let bytes = parse_hex(&hex.join(" ")).map_err(hex_refused)?;
            let frames = optobus_inspect::decode(device, &bytes, framing(*mbap), *address)?;
            print(&render(&frames, options.json, render_decoded));
        }
    }
    Ok(())
}

/// A register address, `16` or `0x10`.
fn parse_address(text: &str) -> Result<u16, optobus_inspect::Error> {
    optobus_inspect::parse_number(text, "a register address")
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
