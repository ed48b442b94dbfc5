//! The subcommands, one file each, and the dispatch of a command line to them. A command
//! uses the shared modules below it (options and connection, values, inputs, output), never
//! another command.

mod buffer;
mod bus;
mod do_command;
mod frame;
mod identify;
mod models;
mod plot;
mod raw;
mod read;
mod record;
mod registers;
mod run;
mod scan;
mod set;
mod simulate;
mod ui;
mod watch;

use clap::Subcommand;

use crate::connect::{DeviceArgs, Options};
use crate::error::CliError;

#[derive(Debug, Subcommand)]
pub(crate) enum Command {
    /// The sensor families, their transports and defaults.
    Models,
    /// The register map of a model: name, table, address, access, type, unit, range or codes.
    Registers(registers::RegistersArgs),
    /// Read registers or groups and print typed values with units.
    Read(read::ReadArgs),
    /// Show registers or groups live, refreshed in place; Ctrl-C ends.
    Watch(watch::WatchArgs),
    /// Sample registers or groups into a CSV file (time, elapsed seconds, values in units).
    Record(record::RecordArgs),
    /// Draw a recording as SVG or PNG: each column over the elapsed time, with its unit.
    Plot(plot::PlotArgs),
    /// Every readable register, decoded, read in the fewest transactions.
    Dump(DeviceArgs),
    /// Write a register: engineering units (`100us`, `42.5`) or code names.
    Set(set::SetArgs),
    /// Run a command of the device (zero, reset, save, reboot…).
    Do(do_command::DoArgs),
    /// Buffer measurements in the device and download them, with a progress bar (models whose
    /// spec describes a data buffer).
    Buffer(buffer::BufferArgs),
    /// Which model the device at --tcp or --serial is: each model's registers, table bounds
    /// and settings read (never written) as that model would be read.
    Identify(DeviceArgs),
    /// Find the slave address and baud rate a device answers on.
    Scan(scan::ScanArgs),
    /// Serve a virtual device for other Modbus tools: Modbus TCP on --tcp (default
    /// 127.0.0.1:5020), RTU on a new pty (--pty) or on an existing port (--serial).
    Simulate(simulate::SimulateArgs),
    /// Poll a bus of sensors (several devices on shared lines) from a bus file and show them
    /// live; --json prints a line per sample, --record writes a CSV per device.
    Run(run::RunArgs),
    /// The console in the browser: the demo bus, or one device (--model, --spec, --serial,
    /// --tcp); prints the page's address.
    Ui(ui::UiArgs),
    /// Bus files: `optobus bus check FILE` checks one, `optobus bus schema` prints every key.
    #[command(subcommand)]
    Bus(bus::BusCommand),
    /// Read or write registers by address, for those a spec lacks (addresses 0-based).
    #[command(subcommand)]
    Raw(raw::RawCommand),
    /// Encode request bytes, or explain captured frames.
    #[command(subcommand)]
    Frame(frame::FrameCommand),
}

/// Runs one command line: the commands that talk to a device get the common options together
/// with their device options.
pub(crate) async fn run(options: Options, command: Command) -> Result<(), CliError> {
    match command {
        Command::Models => models::run(&options),
        Command::Registers(args) => registers::run(&options, &args),
        Command::Read(args) => read::read(&options.with(&args.device), &args).await,
        Command::Watch(args) => watch::run(&options.with(&args.device), &args).await,
        Command::Record(args) => record::run(&options.with(&args.device), &args).await,
        Command::Plot(args) => plot::run(&args),
        Command::Dump(device) => read::dump(&options.with(&device)).await,
        Command::Set(args) => set::run(&options.with(&args.write.device), &args).await,
        Command::Do(args) => do_command::run(&options.with(&args.write.device), &args).await,
        Command::Buffer(args) => buffer::run(&options.with(&args.device), &args).await,
        Command::Identify(device) => identify::run(&options.with(&device)).await,
        Command::Scan(args) => scan::run(&options.with(&args.device), &args).await,
        Command::Simulate(args) => simulate::run(&options.with(&args.device), &args).await,
        Command::Run(args) => {
            bus::no_spec(&options)?;
            run::run(options.json, &args).await
        }
        Command::Ui(args) => ui::run(&options.with(&args.device), &args).await,
        Command::Bus(command) => {
            bus::no_spec(&options)?;
            bus::run(options.json, &command)
        }
        Command::Raw(command) => raw::run(&options, &command).await,
        Command::Frame(command) => frame::run(&options, &command),
    }
}
