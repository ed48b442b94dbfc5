//! `optobus frame`: request bytes for a PLC programmer, and captured frames explained.

use crate::error::CliError;

/// Encode or decode frames.
#[derive(Debug, clap::Subcommand)]
pub(crate) enum FrameCommand {
    /// Print request bytes.
    Encode,
    /// Explain bytes.
    Decode,
}

/// Runs a frame command.
pub(crate) fn run(
    _command: &FrameCommand,
    _json: bool,
    _slave: Option<u8>,
) -> Result<String, CliError> {
    Err(CliError::new("not yet"))
}
