//! One error type for the tool: a line saying what failed and what to try.

/// A failure the user sees as one line on stderr (with a hint in parentheses where one helps)
/// and a non-zero exit code: the inspector's error, which every library error here converts
/// into.
pub(crate) use optobus_inspect::Error as CliError;

/// Explains a driver error; `register` names the register involved, if any.
pub(crate) fn driver_error(error: optobus_driver::Error, register: Option<&str>) -> CliError {
    let subject = register.map(|r| format!(" for `{r}`")).unwrap_or_default();
    let timed_out = matches!(
        error,
        optobus_driver::Error::Transport(optobus_driver::transport::Error::Timeout { .. })
    );
    let error = CliError::new(format!("{error}{subject}"));
    if timed_out {
        error.hint("check wiring, --slave, --baud and --parity, or raise --timeout")
    } else {
        error
    }
}
