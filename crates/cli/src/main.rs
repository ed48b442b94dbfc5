//! `optobus`: read, watch, set and simulate optical distance sensors over Modbus.
//!
//! Without `--serial` or `--tcp` every device command runs against the built-in simulator
//! of the chosen model, so the tool works on a laptop with nothing attached.
#![forbid(unsafe_code)]

mod commands;
mod connect;
mod error;
mod frame;
mod inputs;
mod link;
mod log;
mod models;
mod render;
mod values;

use std::process::ExitCode;

use clap::Parser;

use crate::commands::Command;
use crate::connect::Global;

/// Read, watch and set industrial optical distance sensors over Modbus RTU or TCP.
///
/// Without --serial or --tcp, device commands talk to the built-in simulator of --model.
#[derive(Debug, Parser)]
#[command(name = "optobus", version, propagate_version = true)]
struct Cli {
    #[command(flatten)]
    global: Global,
    #[command(subcommand)]
    command: Command,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let runtime = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(runtime) => runtime,
        Err(error) => {
            log::note!("optobus: cannot start: {error}");
            return ExitCode::FAILURE;
        }
    };
    match runtime.block_on(commands::run(cli.global, cli.command)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            log::note!("optobus: {error}");
            ExitCode::FAILURE
        }
    }
}
