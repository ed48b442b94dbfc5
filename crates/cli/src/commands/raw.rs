//! `optobus raw`: words read or written by address, for registers a spec lacks, through the
//! same link as every other command. Addresses are 0-based, as on the wire.

use clap::{Subcommand, ValueEnum};
use optobus_device::Table;
use optobus_driver::transport::{ReadRequest, WriteValue};
use optobus_driver::Transport;
use optobus_inspect::{hex_and_decimal, parse_number};
use serde_json::json;

use crate::connect::{DeviceArgs, Global, Options};
use crate::error::{transport_error, CliError};
use crate::inputs;
use crate::render::{pretty, print};

/// `optobus raw …`.
#[derive(Debug, Subcommand)]
pub(crate) enum RawCommand {
    /// Read words with FC03 (holding) or FC04 (input), printed in hex and decimal.
    Read {
        /// The register table.
        table: RawTable,
        /// The first address, 0-based as on the wire (mbpoll counts from 1): decimal or 0x hex.
        address: String,
        /// How many words, 1 to the model's most per read.
        #[arg(long, default_value = "1")]
        count: String,
        #[command(flatten)]
        device: DeviceArgs,
    },
    /// Write one holding register with FC06.
    Write {
        /// The address, 0-based as on the wire (mbpoll counts from 1): decimal or 0x hex.
        address: String,
        /// The word to write, 0 to 65535: decimal or 0x hex.
        #[arg(allow_hyphen_values = true)]
        value: String,
        /// Confirm a write to a register that the spec's save, restart or reset commands write.
        #[arg(long)]
        yes: bool,
        #[command(flatten)]
        device: DeviceArgs,
    },
}

/// The tables `raw read` reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub(crate) enum RawTable {
    /// Holding registers (FC03).
    Holding,
    /// Input registers (FC04).
    Input,
}

impl RawTable {
    /// The device table it names (its read function and name are the device crate's facts).
    const fn table(self) -> Table {
        match self {
            Self::Holding => Table::Holding,
            Self::Input => Table::Input,
        }
    }
}

pub(crate) async fn run(options: &Options, command: &RawCommand) -> Result<(), CliError> {
    match command {
        RawCommand::Read {
            table,
            address,
            count,
            device,
        } => read(&options.with(device), *table, address, count).await,
        RawCommand::Write {
            address,
            value,
            yes,
            device,
        } => write(&options.with(device), address, value, *yes).await,
    }
}

/// Reads `count` words from `address` of `table`; everything checked before the link opens.
async fn read(
    global: &Global,
    table: RawTable,
    address: &str,
    count: &str,
) -> Result<(), CliError> {
    let device = global.device()?;
    global.check_line(device)?;
    let address = parse_number(address, "a register address")?;
    let count = parse_number(count, "a word count")?;
    let most = device.max_read_words;
    if !(1..=most).contains(&count) {
        return Err(CliError::new(format!(
            "--count {count}: {} reads 1 to {most} words at a time",
            crate::models::name(device)
        )));
    }
    let last = address.checked_add(count - 1).ok_or_else(|| {
        CliError::new(format!(
            "{count} words from {} run past the last address, 0xFFFF (65535)",
            hex_and_decimal(address)
        ))
    })?;
    let slave = global.answering_slave(device, "raw read")?;
    let mut core = global.connect(device, slave).await?;
    let subject = format!(
        "{} {}..={}",
        table.table().as_str(),
        hex_and_decimal(address),
        hex_and_decimal(last)
    );
    let words = core
        .transport_mut()
        .read_words(
            slave,
            ReadRequest::new(table.table().read_function(), address, count),
        )
        .await
        .map_err(|e| transport_error(e, &subject))?;
    let at = (address..=last).zip(&words);
    if global.json {
        let list: Vec<_> = at
            .map(|(address, word)| json!({"address": address, "value": word}))
            .collect();
        print(&pretty(
            &json!({"table": table.table().as_str(), "words": list}),
        ));
    } else {
        let lines: Vec<String> = at
            .map(|(address, word)| {
                format!(
                    "{} {}  {}",
                    table.table().as_str(),
                    hex_and_decimal(address),
                    hex_and_decimal(*word)
                )
            })
            .collect();
        print(&lines.join("\n"));
    }
    Ok(())
}

/// Writes `value` to the holding register at `address` (FC06); broadcast with `--slave 0`.
/// An address the spec knows as a drastic command's register needs `yes`, as `set` does.
async fn write(global: &Global, address: &str, value: &str, yes: bool) -> Result<(), CliError> {
    let device = global.device()?;
    global.check_line(device)?;
    let address = parse_number(address, "a register address")?;
    let value = parse_number(value, "a register value")?;
    if let Some((register, offset)) = device.register_at(Table::Holding, address) {
        let whole = offset == 0 && register.span(device.addressing) == 1;
        inputs::confirm(device, register, whole.then_some(u32::from(value)), yes)?;
    }
    let slave = global.writing_slave(device)?;
    let mut core = global.connect(device, slave).await?;
    global.note_if_simulated("raw write");
    let subject = format!("holding {}", hex_and_decimal(address));
    core.transport_mut()
        .write(slave, address, WriteValue::Word(value))
        .await
        .map_err(|e| transport_error(e, &subject))?;
    if global.json {
        print(&pretty(&json!({
            "table": "holding",
            "address": address,
            "value": value,
            "broadcast": slave == 0,
        })));
    } else {
        let done = if slave == 0 {
            "broadcast sent, no reply expected"
        } else {
            "written"
        };
        print(&format!("{subject}  {}: {done}", hex_and_decimal(value)));
    }
    Ok(())
}
