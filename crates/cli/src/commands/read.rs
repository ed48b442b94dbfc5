//! `optobus read` (registers and groups by name) and `optobus dump` (every readable
//! register whose read changes nothing), both in the fewest requests.

use clap::Args;
use optobus_device::RegisterInfo;
use optobus_inspect::decode_values;
use serde_json::json;

use crate::connect::{failed_read, read_values, DeviceArgs, Global, Names};
use crate::error::CliError;
use crate::log::note;
use crate::render::{counted, pretty, print, values_json, values_text};

#[derive(Debug, Args)]
pub(crate) struct ReadArgs {
    #[command(flatten)]
    names: Names,
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
}

pub(crate) async fn read(global: &Global, args: &ReadArgs) -> Result<(), CliError> {
    let (registers, mut core) = global.connect_to_read(&args.names, "read").await?;
    let values = read_values(&mut core, &registers).await?;
    if global.json {
        print(&pretty(&values_json(&values)));
    } else {
        print(&values_text(&values));
    }
    Ok(())
}

pub(crate) async fn dump(global: &Global) -> Result<(), CliError> {
    let device = global.device()?;
    global.check_line(device)?;
    let registers: Vec<&'static RegisterInfo> = device.dump_registers().collect();
    let slave = global.answering_slave(device, "dump")?;
    let mut core = global.connect(device, slave).await?;
    let readings = core
        .read_group_partly(&registers)
        .await
        .map_err(|partial| failed_read(*partial, &registers))?;
    // The requests answered: a device refusing a read over reserved rows is read around them.
    let requests = readings.requests().count();
    let values = decode_values(&registers, &readings);
    let skipped = device.readable_registers().count() - registers.len();
    if skipped > 0 {
        note!(
            "optobus: {} left out: reading them changes the device (see `optobus registers`); \
             read them by name",
            counted(skipped, "register")
        );
    }
    if global.json {
        print(&pretty(&json!({
            "model": device.family,
            "slave": core.slave(),
            "requests": requests,
            "values": values_json(&values),
        })));
    } else {
        print(&values_text(&values));
        note!(
            "optobus: {} in {}",
            counted(registers.len(), "register"),
            counted(requests, "request")
        );
    }
    Ok(())
}
