//! `optobus set`: one register written from engineering units or code names, and read back.

use clap::Args;
use optobus_device::RegisterInfo;
use optobus_driver::{address_change, raw_bits, AddressChange, Encode};
use optobus_inspect::{decode_value, parse_value};
use serde_json::json;

use crate::connect::{Global, WriteArgs};
use crate::error::{driver_error, CliError};
use crate::inputs;
use crate::log::note;
use crate::render::{pretty, print, value_json};

#[derive(Debug, Args)]
pub(crate) struct SetArgs {
    /// Register name.
    name: String,
    /// The value; negative ones need no `--` (`-1.5`).
    #[arg(allow_hyphen_values = true)]
    value: String,
    #[command(flatten)]
    pub(crate) write: WriteArgs,
}

/// Names and values are checked first, so bad input is refused before any connection.
pub(crate) async fn run(global: &Global, args: &SetArgs) -> Result<(), CliError> {
    let device = global.device()?;
    global.check_line(device)?;
    let register = optobus_inspect::resolve_one(device, &args.name, args.write.channel)?;
    let words = parse_value(register, &args.value)?;
    let new_address = address_change(device, register, &words);
    inputs::confirm(
        device,
        register,
        Some(raw_bits(register, &words)),
        args.write.yes,
    )?;
    let slave = global.writing_slave(device)?;
    let mut core = global.connect(device, slave).await?;
    global.note_if_simulated("set");
    core.write(register, &Validated(words.clone()))
        .await
        .map_err(|e| driver_error(e, Some(register.name)))?;
    if slave == 0 {
        let value = decode_value(register, &words);
        if global.json {
            print(&json!({ register.name: value_json(&value), "broadcast": true }).to_string());
        } else {
            print(&format!(
                "{}  {value}: broadcast sent, no reply expected",
                register.name
            ));
        }
        return Ok(());
    }
    let afterwards = match new_address {
        Some(AddressChange::AfterSaveAndPowerCycle { address, save }) => {
            let save = save
                .map(|c| format!(" (`optobus do {} --yes`)", c.name))
                .unwrap_or_default();
            Some(format!(
                "optobus: the new address {address} applies after save{save} and a power \
                 cycle; until then the device answers at slave {slave}"
            ))
        }
        Some(AddressChange::Now(address)) => {
            core.set_slave(address)?;
            Some(format!(
                "optobus: the device now answers at slave {address}"
            ))
        }
        None => None,
    };
    if register.readable() {
        let back = core
            .read_words(register)
            .await
            .map_err(|e| driver_error(e, Some(register.name)))?;
        let value = decode_value(register, &back);
        if global.json {
            print(&pretty(&json!({ register.name: value_json(&value) })));
        } else {
            print(&format!("{}  {value}", register.name));
        }
    } else if !global.json {
        print(&format!("{} written", register.name));
    }
    if let Some(afterwards) = afterwards {
        note!("{afterwards}");
    }
    Ok(())
}

/// Words [`parse_value`] already validated, written as they are.
struct Validated(Vec<u16>);

impl Encode for Validated {
    fn encode(&self, _: &'static RegisterInfo) -> Result<Vec<u16>, optobus_driver::Error> {
        Ok(self.0.clone())
    }
}
