//! `optobus do`: a command of the device (zero, reset, save, reboot…); drastic ones ask for
//! `--yes`.

use clap::Args;
use serde_json::json;

use crate::connect::{Global, WriteArgs};
use crate::error::{driver_error, CliError};
use crate::inputs;
use crate::log::note;
use crate::render::print;

#[derive(Debug, Args)]
pub(crate) struct DoArgs {
    /// Command name (`optobus models` and `optobus registers` list them).
    command: String,
    #[command(flatten)]
    pub(crate) write: WriteArgs,
}

pub(crate) async fn run(global: &Global, args: &DoArgs) -> Result<(), CliError> {
    let device = global.device()?;
    global.check_line(device)?;
    let command = &args.command;
    let info = device.command(command).ok_or_else(|| {
        let names: Vec<&str> = device.commands.iter().map(|c| c.name).collect();
        CliError::new(format!(
            "`{command}` is no command of {}",
            crate::models::name(device)
        ))
        .hint(format!("commands: {}", names.join(", ")))
    })?;
    if info.effect.is_drastic() && !args.write.yes {
        return Err(CliError::new(format!(
            "`{command}` {}; add --yes to go ahead",
            inputs::effect_text(info)
        )));
    }
    let register = optobus_inspect::resolve_one(device, info.register, args.write.channel)?;
    let slave = global.writing_slave(device)?;
    if info.busy_ms > 0 && !global.json {
        note!(
            "optobus: the device is busy for {} ms afterwards",
            info.busy_ms
        );
    }
    let mut core = global.connect(device, slave).await?;
    global.note_if_simulated("do");
    core.run(info, register)
        .await
        .map_err(|e| driver_error(e, Some(register.name)))?;
    print(&match (slave == 0, global.json) {
        (true, true) => json!({"command": info.name, "broadcast": true}).to_string(),
        (true, false) => format!("{}: broadcast sent, no reply expected", info.name),
        (false, true) => json!({"command": info.name, "done": true}).to_string(),
        (false, false) => format!("{} done", info.name),
    });
    Ok(())
}
