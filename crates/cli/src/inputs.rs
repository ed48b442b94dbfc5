//! Command-line values checked before anything is sent: durations with a bound per option,
//! slave addresses, baud rates, parity, scan lists, and which writes are drastic (need --yes).

use std::time::Duration;

use clap::ValueEnum;
use jiff::SignedDuration;
use optobus_device::{CommandInfo, DeviceInfo, RegisterInfo};
use optobus_driver::scan::{self, BaudListError};
use optobus_driver::transport::Parity;

use crate::error::CliError;

/// The bounds of a duration option.
#[derive(Clone, Copy, Debug)]
pub(crate) struct DurationBound {
    /// The option, for messages.
    option: &'static str,
    /// Shortest allowed (zero allowed when zero).
    min: Duration,
    /// Longest allowed.
    max: Duration,
}

const DAY: Duration = Duration::from_secs(24 * 3600);
const MS: Duration = Duration::from_millis(1);

impl DurationBound {
    /// `option` takes at least `min` and at most a day.
    const fn up_to_a_day(option: &'static str, min: Duration) -> Self {
        Self {
            option,
            min,
            max: DAY,
        }
    }

    /// The option's value parser.
    pub(crate) fn parser(
        self,
    ) -> impl Fn(&str) -> Result<Duration, CliError> + Clone + Send + Sync + 'static {
        move |text| parse_duration(text, self)
    }
}

/// `--timeout`: a reply takes at least a millisecond; a day is no timeout any more.
pub(crate) const TIMEOUT: DurationBound = DurationBound::up_to_a_day("--timeout", MS);
/// `watch --interval`.
pub(crate) const INTERVAL: DurationBound = DurationBound::up_to_a_day("--interval", MS);
/// `optobus ui --every`.
pub(crate) const EVERY: DurationBound = DurationBound::up_to_a_day("--every", MS);
/// `buffer --wait`.
pub(crate) const WAIT: DurationBound = DurationBound::up_to_a_day("--wait", Duration::ZERO);
/// `--duration` of `simulate`, `run`, `ui` and `record`.
pub(crate) const RUN_FOR: DurationBound = DurationBound::up_to_a_day("--duration", Duration::ZERO);

/// Waits until `--duration` (`duration`) has passed, or Ctrl-C; without a duration, Ctrl-C.
pub(crate) async fn until_stopped(duration: Option<Duration>) {
    let run_for = async {
        match duration {
            Some(duration) => tokio::time::sleep(duration).await,
            None => std::future::pending().await,
        }
    };
    tokio::select! {
        _ = tokio::signal::ctrl_c() => {}
        () = run_for => {}
    }
}
/// `simulate --turnaround`: the emulated device's reaction time; zero answers at once.
pub(crate) const TURNAROUND: DurationBound =
    DurationBound::up_to_a_day("--turnaround", Duration::ZERO);

/// `24h`, `1s 500ms` for messages.
fn show(duration: Duration) -> String {
    SignedDuration::try_from(duration)
        .map_or_else(|_| format!("{duration:?}"), |d| format!("{d:#}"))
}

/// `200ms`, `1s`, `1.5s`, `2m`, `1h`, `100us`, `1s 500ms` (jiff's friendly format), or a
/// bare number of milliseconds; exact to the nanosecond and within `bound`.
pub(crate) fn parse_duration(text: &str, bound: DurationBound) -> Result<Duration, CliError> {
    let option = bound.option;
    let text = text.trim();
    let example = "e.g. 200ms, 1.5s, 2m";
    let bare_ms = !text.is_empty() && text.bytes().all(|b| b.is_ascii_digit());
    let parsed = if bare_ms {
        format!("{text}ms").parse::<SignedDuration>()
    } else {
        text.parse::<SignedDuration>()
    };
    let too_long = || {
        CliError::new(format!(
            "{option} {text} is too long: at most {}",
            show(bound.max)
        ))
    };
    let signed = parsed.map_err(|error| {
        if error.to_string().contains("too big") {
            too_long()
        } else {
            CliError::new(format!("`{text}` is not a duration")).hint(example)
        }
    })?;
    if signed.is_negative() {
        return Err(CliError::new(format!("{option} cannot be negative")).hint(example));
    }
    let duration = Duration::try_from(signed).map_err(|_| too_long())?;
    if duration > bound.max {
        return Err(too_long());
    }
    if duration < bound.min {
        return Err(CliError::new(format!(
            "{option} {text} is too short: at least {}",
            show(bound.min)
        )));
    }
    Ok(duration)
}

/// `--slave`: 0 (broadcast, writes only) to 247; Modbus reserves 248 to 255.
pub(crate) fn parse_slave(text: &str) -> Result<u8, CliError> {
    let text = text.trim();
    let why = match text.parse::<u32>() {
        Ok(number @ 0..=247) => return Ok(u8::try_from(number).unwrap_or(0)),
        Ok(number @ 248..=255) => {
            format!("slave address {number} is reserved: Modbus reserves 248 to 255")
        }
        Ok(number) => format!("slave address {number} does not exist: addresses are 0 to 247"),
        Err(_) => format!("`{text}` is not a slave address"),
    };
    Err(CliError::new(why).hint("use 1 to 247, or 0 to broadcast a write"))
}

/// `--sim-speed`: how fast the built-in simulator answers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub(crate) enum SimSpeed {
    /// At the model's line speed: a character time per byte and t3.5 gaps, as a device on
    /// its serial line.
    Line,
    /// As fast as memory allows (tests, or a quick look at many values).
    Full,
}

/// `--parity`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub(crate) enum ParityArg {
    /// No parity bit.
    #[value(alias = "n")]
    None,
    /// Odd parity.
    #[value(alias = "o")]
    Odd,
    /// Even parity.
    #[value(alias = "e")]
    Even,
}

impl ParityArg {
    pub(crate) const fn parity(self) -> Parity {
        match self {
            Self::None => Parity::None,
            Self::Odd => Parity::Odd,
            Self::Even => Parity::Even,
        }
    }
}

/// `baud` (given as `option`) is one the model's manual lists, or with `any` at least a rate a
/// serial port can run at.
pub(crate) fn check_baud(
    device: &DeviceInfo,
    option: &str,
    baud: u32,
    any: bool,
) -> Result<(), CliError> {
    let (min, max) = scan::BAUD_RATES;
    if !(min..=max).contains(&baud) {
        return Err(CliError::new(format!(
            "{option} {baud} is no baud rate a serial line can use: {min} to {max}"
        )));
    }
    if any {
        return Ok(());
    }
    let listed = device.rtu.map(|r| r.bauds).unwrap_or_default();
    if listed.contains(&baud) {
        return Ok(());
    }
    let names: Vec<String> = listed.iter().map(u32::to_string).collect();
    Err(CliError::new(format!(
        "{option} {baud}: {} does not list {baud} baud",
        crate::models::name(device)
    ))
    .hint(if names.is_empty() {
        "its spec lists no serial line; --any-baud uses the rate anyway".to_owned()
    } else {
        format!(
            "its manual lists {}; --any-baud uses another rate anyway",
            names.join(", ")
        )
    }))
}

/// `scan --bauds 9600,115200`: every rate checked, no empty item, no repeats.
pub(crate) fn parse_bauds(
    device: &DeviceInfo,
    text: &str,
    any: bool,
) -> Result<Vec<u32>, CliError> {
    scan::parse_bauds(text, "--bauds", |baud| {
        check_baud(device, "--bauds", baud, any)
    })
    .map_err(|refused| match refused {
        BaudListError::Refused(error) => error,
        other => CliError::listed(&other, other.hint()),
    })
}

/// What a command does, in words for a sentence (`stores the current parameters…`).
pub(crate) fn effect_text(command: &CommandInfo) -> String {
    command.doc.trim_end_matches('.').to_lowercase()
}

/// A write of `raw` (unknown: part of a wider register) to a register that a drastic command
/// writes (save, reboot, resets) needs `--yes`, as `do` of the command does.
pub(crate) fn confirm(
    device: &DeviceInfo,
    register: &'static RegisterInfo,
    raw: Option<u32>,
    yes: bool,
) -> Result<(), CliError> {
    if yes {
        return Ok(());
    }
    let drastic: Vec<&CommandInfo> = device.drastic_commands_on(register).collect();
    match (
        raw.and_then(|raw| drastic.iter().find(|c| c.value == raw)),
        drastic.as_slice(),
    ) {
        (_, []) => Ok(()),
        (Some(command), _) => Err(CliError::new(format!(
            "writing {} to `{}` runs `{}`: it {}; add --yes to go ahead",
            command.value,
            register.name,
            command.name,
            effect_text(command)
        ))
        .hint(format!("or run it as `optobus do {} --yes`", command.name))),
        (None, commands) => {
            let names: Vec<String> = commands.iter().map(|c| format!("`{}`", c.name)).collect();
            Err(CliError::new(format!(
                "`{}` is the register of {}, which store, restart or reset the device; add --yes \
                 to go ahead",
                register.name,
                names.join(" and ")
            )))
        }
    }
}
