//! `optobus frame`: request bytes for a PLC programmer, and captured frames explained.
//!
//! `frame encode` prints the exact bytes the drivers send for a read (a register or a group, in
//! the fewest requests) or a validated write (a 32-bit value as two FC06 in the order the
//! device needs, or the rangefinder's single 4-byte FC06). `frame decode` explains bytes
//! captured on the wire field by field: request, reply or exception, CRC checked, registers
//! named and values decoded. Nothing here does I/O, and no input makes it panic.

use clap::{Args, Subcommand};
use optobus_device::{DeviceInfo, RegisterInfo};
use optobus_inspect::{hex, EncodedFrame, ExplainedFrame, Framing};
use serde_json::{json, Value as Json};

use crate::error::CliError;
use crate::models;
use crate::values;

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
            let framing = |options: &EncodeOptions| {
                if options.mbap || tcp {
                    Framing::Tcp
                } else {
                    Framing::Rtu
                }
            };
            let frames = match request {
                EncodeRequest::Read { .. } if slave == 0 => {
                    return Err(CliError::new(
                        "a read sent to slave 0, the broadcast address, gets no reply",
                    )
                    .hint("give the device's address, 1 to 247, with --slave"))
                }
                EncodeRequest::Read { name, options } => {
                    encode_read(device, name, options.channel, slave, framing(options))?
                }
                EncodeRequest::Set {
                    name,
                    value,
                    options,
                } => encode_write(
                    device,
                    name,
                    value,
                    options.channel,
                    slave,
                    framing(options),
                )?,
            };
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
            let frames =
                optobus_inspect::decode(device, &bytes, framing, *address).map_err(|error| {
                    let refused = CliError::new(error.message);
                    match error.hint {
                        Some(hint) => refused.hint(hint),
                        None => refused,
                    }
                })?;
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

// ---------------------------------------------------------------------------------- encode

/// The frames that read `name` (a register, a repeat member or a group).
fn encode_read(
    device: &'static DeviceInfo,
    name: &str,
    channel: Option<u8>,
    slave: u8,
    framing: Framing,
) -> Result<Vec<EncodedFrame>, CliError> {
    let registers = values::resolve(device, name, channel)?;
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

/// The frames that write `text` to register `name`, validated as the drivers do.
fn encode_write(
    device: &'static DeviceInfo,
    name: &str,
    text: &str,
    channel: Option<u8>,
    slave: u8,
    framing: Framing,
) -> Result<Vec<EncodedFrame>, CliError> {
    let register = one_register(device, name, channel)?;
    let words = values::parse(register, text)?;
    let frames = optobus_inspect::encode_write(device, register, &words, slave, framing)
        .map_err(not_encoded)?;
    if frames.is_empty() {
        return Err(CliError::new(format!(
            "`{text}` gives no words to write to `{name}`"
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
    match values::resolve(device, name, channel)?.as_slice() {
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

/// One `# description` line above each frame's hex, so a line copies as it is; or JSON.
fn render_encoded(frames: &[EncodedFrame], json: bool) -> String {
    if json {
        return pretty(serde_json::to_value(frames));
    }
    frames
        .iter()
        .map(|frame| format!("# {}\n{}", frame.description, hex(&frame.bytes)))
        .collect::<Vec<_>>()
        .join("\n")
}

/// `{"frames": [...]}` as JSON text for people and scripts alike.
fn pretty(frames: serde_json::Result<Json>) -> String {
    let value = json!({ "frames": frames.unwrap_or_default() });
    serde_json::to_string_pretty(&value).unwrap_or_else(|_| value.to_string())
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

/// Frames explained, field by field; or JSON.
fn render_decoded(frames: &[ExplainedFrame], json: bool) -> String {
    if json {
        return pretty(serde_json::to_value(frames));
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
    const CCF: &DeviceInfo = &optobus_ccf::DEVICE;

    fn bytes(text: &str) -> Vec<u8> {
        parse_hex(&[text.to_owned()]).unwrap_or_default()
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
    fn invalid_writes_are_refused_before_encoding() {
        let write = |device, name, text, channel| {
            encode_write(device, name, text, channel, 1, Framing::Rtu)
        };
        let error = write(P, "light_power", "250", None).err();
        assert!(error.is_some_and(|e| e.message.contains("0.5")));
        assert!(write(P, "distance_1", "1", None).is_err());
        assert!(write(P, "laser", "1", None).is_err());
        assert!(write(CCF, "exposure_time", "100us", None).is_err());
        assert!(write(CCF, "exposure_time", "100us", Some(2)).is_ok());
    }

    #[test]
    fn rendering_never_panics() {
        let input = bytes("01 04 00 00 00 06 70 08 01 04 0C 00 36 B0 BE 00 20 24 5C 00 56 D3 04");
        for end in 0..input.len() {
            let prefix = input.get(..end).unwrap_or_default();
            if let Ok(frames) = optobus_inspect::decode(P, prefix, Framing::Rtu, None) {
                let _ = render_decoded(&frames, false);
                let _ = render_decoded(&frames, true);
            }
        }
    }
}
