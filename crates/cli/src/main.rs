//! `optobus`: read, watch, set and simulate optical distance sensors over Modbus.
//!
//! Without `--serial` or `--tcp` every device command runs against the built-in simulator
//! of the chosen model, so the tool works on a laptop with nothing attached.
#![forbid(unsafe_code)]

mod bus_file;
mod commands;
mod connect;
mod error;
mod inputs;
mod log;
mod models;
mod render;
mod target;

use std::process::ExitCode;

use clap::{Arg, Args, CommandFactory, FromArgMatches, Parser};

use crate::commands::Command;
use crate::connect::Options;
use crate::error::{Exit, EXIT_CODES};

/// Read, watch and set industrial optical distance sensors over Modbus RTU or TCP.
///
/// Without --serial or --tcp, device commands talk to the built-in simulator of --model.
#[derive(Debug, Parser)]
#[command(name = "optobus", version, propagate_version = true, after_help = EXIT_CODES)]
struct Cli {
    #[command(flatten)]
    options: Options,
    #[command(subcommand)]
    command: Command,
}

/// How long the process waits at its end for stderr to take its last notes.
const STDERR_AT_EXIT: std::time::Duration = std::time::Duration::from_secs(1);

/// Commands that take no model (`frame` names its model with each subcommand): their help does
/// not show `--model`.
const WITHOUT_MODEL: [&str; 5] = ["models", "plot", "frame", "run", "bus"];

/// Every argument that takes a model lists the models the tool has in its help; `--model`
/// says its default: `OPTOBUS_MODEL`, else the first model for the built-in simulator only.
fn with_models(command: clap::Command) -> clap::Command {
    let names = models::names();
    let list = names.join(", ");
    let takes_model = |arg: &Arg| {
        arg.get_id() == "model" || arg.get_value_names().is_some_and(|v| v == ["MODEL"])
    };
    command
        .mut_args(|arg| match arg {
            arg if !takes_model(&arg) => arg,
            arg if arg.is_global_set() => arg.help(format!(
                "Sensor family: {list} (see `optobus models`). Default: ${}, else {} for the \
                 built-in simulator; a device reached with --tcp or --serial needs it",
                connect::MODEL_VARIABLE,
                names.first().map_or("", String::as_str)
            )),
            arg if arg.is_required_set() => arg.help(format!("Sensor family: {list}")),
            arg => arg.help(format!("Sensor family: {list} (default: --model)")),
        })
        .mut_subcommands(|sub| {
            if !WITHOUT_MODEL.contains(&sub.get_name()) {
                return with_models(sub);
            }
            // An argument of the same id keeps the global one from being propagated here.
            let hidden = Arg::new("model").long("model").short('m').hide(true);
            with_models(sub.arg(hidden))
        })
}

/// An option given to a command that does not take it: clap's tip (a similar argument, or `--
/// --tcp` as if it were a value) would mislead, so the error says what the option is for
/// instead: a device option says that this command reaches no device, and an option of other
/// commands names them (`--interval` belongs to `watch` and `record`).
fn explain_misplaced_option(error: clap::Error, command: &clap::Command) -> clap::Error {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    if error.kind() != ErrorKind::UnknownArgument {
        return error;
    }
    let Some(ContextValue::String(given)) = error.get(ContextKind::InvalidArg) else {
        return error;
    };
    let option = given.split('=').next().unwrap_or(given);
    let Some(long) = option.strip_prefix("--") else {
        return error;
    };
    let takes =
        |command: &clap::Command| command.get_arguments().any(|a| a.get_long() == Some(long));
    let device_options = connect::DeviceArgs::augment_args(clap::Command::new("device"));
    let why = if takes(&device_options) {
        "it says how to reach a device, and this command reaches none (`frame` writes Modbus \
         TCP frames with --mbap)"
            .to_owned()
    } else {
        let owners = commands_taking(command, "", &takes);
        if owners.is_empty() {
            return error;
        }
        format!("it belongs to {}", listed(&owners))
    };
    clap::Error::raw(
        ErrorKind::UnknownArgument,
        format!("unexpected argument '{option}': {why}"),
    )
}

/// The subcommands of `command` (named from `prefix`, `raw read`) that `takes` holds for.
fn commands_taking(
    command: &clap::Command,
    prefix: &str,
    takes: &dyn Fn(&clap::Command) -> bool,
) -> Vec<String> {
    let mut owners = Vec::new();
    for sub in command.get_subcommands() {
        let name = format!("{prefix}{}", sub.get_name());
        if takes(sub) {
            owners.push(name.clone());
        }
        owners.extend(commands_taking(sub, &format!("{name} "), takes));
    }
    owners
}

/// `` `a` ``, `` `a` and `b` ``, `` `a`, `b` and `c` ``.
fn listed(names: &[String]) -> String {
    let quoted: Vec<String> = names.iter().map(|n| format!("`{n}`")).collect();
    match quoted.split_last() {
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} and {last}", rest.join(", ")),
        None => String::new(),
    }
}

/// The names of the subcommands `args` runs, outermost first, for the usage line of an error.
fn subcommand_path(command: &clap::Command, args: &[String]) -> Vec<String> {
    let mut path = Vec::new();
    let mut current = command;
    for arg in args {
        if let Some(sub) = current.find_subcommand(arg) {
            path.push(sub.get_name().to_owned());
            current = sub;
        }
    }
    path
}

fn main() -> ExitCode {
    let mut command = with_models(Cli::command());
    let parsed = command
        .try_get_matches_from_mut(std::env::args_os())
        .and_then(|matches| Cli::from_arg_matches(&matches));
    let cli = match parsed {
        Ok(cli) => cli,
        // --help and --version come this way too, on stdout.
        Err(error) => {
            let args: Vec<String> = std::env::args().skip(1).collect();
            let path = subcommand_path(&command, &args);
            let error = explain_misplaced_option(error, &command);
            let error = match path
                .iter()
                .try_fold(&mut command, |c, name| c.find_subcommand_mut(name))
            {
                Some(sub) => error.format(sub),
                None => error.format(&mut command),
            };
            let _ = error.print();
            return if error.use_stderr() {
                Exit::Usage.code()
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    let code = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(runtime) => match runtime.block_on(commands::run(cli.options, cli.command)) {
            Ok(()) => ExitCode::SUCCESS,
            Err(error) => {
                log::note!("optobus: {error}");
                error.exit().code()
            }
        },
        Err(error) => {
            log::note!("optobus: cannot start: {error}");
            Exit::Failed.code()
        }
    };
    // The last notes, if stderr takes them soon (nobody may be reading it).
    log::flush(STDERR_AT_EXIT);
    code
}
