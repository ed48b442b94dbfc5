//! `optobus`: read, watch, set and simulate optical distance sensors over Modbus.
//!
//! Without `--serial` or `--tcp` every device command runs against the built-in simulator
//! of the chosen model, so the tool works on a laptop with nothing attached.
#![forbid(unsafe_code)]

mod commands;
mod connect;
mod error;
mod inputs;
mod link;
mod log;
mod models;
mod render;

use std::process::ExitCode;

use clap::{Arg, CommandFactory, FromArgMatches, Parser};

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

/// Every argument that takes a model lists the models the tool has in its help, and
/// `--model` defaults to the first of them.
fn with_models(command: clap::Command) -> clap::Command {
    let names = models::names();
    let list = names.join(", ");
    let takes_model = |arg: &Arg| {
        arg.get_id() == "model" || arg.get_value_names().is_some_and(|v| v == ["MODEL"])
    };
    command
        .mut_args(|arg| match arg {
            arg if !takes_model(&arg) => arg,
            arg if arg.is_global_set() => arg
                .help(format!("Sensor family: {list} (see `optobus models`)"))
                .default_value(names.first().cloned().unwrap_or_default())
                .required(false),
            arg if arg.is_required_set() => arg.help(format!("Sensor family: {list}")),
            arg => arg.help(format!("Sensor family: {list} (default: --model)")),
        })
        .mut_subcommands(with_models)
}

fn main() -> ExitCode {
    let mut command = with_models(Cli::command());
    let cli = Cli::from_arg_matches(&command.get_matches_mut())
        .unwrap_or_else(|error| error.format(&mut command).exit());
    if cli.global.target.verbose {
        log::show_frames();
    }
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
