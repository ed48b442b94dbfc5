//! Seeded fault injection on replies, for testing how clients cope with a bad line.
//!
//! [`Faults`] gives each [`FaultKind`] a probability; every reply the device produces gets at
//! most one fault, drawn from a PRNG seeded by the seed and the reply's number, so the same
//! seed gives the same faults for the same sequence of replies. [`FaultStats`] counts what
//! was injected and logs which reply got which fault.
//!
//! What each kind does to a reply:
//!
//! | kind | RTU | Modbus TCP |
//! |---|---|---|
//! | `corrupt` | one bit of one byte flipped: the CRC no longer matches | one bit flipped in the MBAP header or function code (transaction id, protocol id, length, unit id, function; never the exception bit), since TCP has no CRC: a client that checks the header sees it |
//! | `truncate` | only the first 1 to n-1 bytes | the same; the stream is then out of step |
//! | `garbage` | 1 to 8 random bytes before the frame, the first never the frame's slave address | 4 to 8 bytes before the frame whose protocol id is not 0 |
//! | `wrong_slave` | the frame from another slave address (1 to 247) with a valid CRC | another unit id |
//! | `split` | the correct frame in 2 or 3 pieces, [`Faults::pause`] apart | the same |
//! | `drop` | no reply | no reply |
//! | `delay` | the correct frame after [`Faults::late`]; the device reads no request meanwhile | the same |
//! | `disconnect` | no reply (a serial line cannot hang up) | the connection is closed instead |
//!
//! ```
//! use optobus_simulator::{FaultKind, Faults};
//! let faults: Faults = "delay=0.1,corrupt=0.05,seed=7".parse().unwrap();
//! assert_eq!(faults.probability(FaultKind::Delay), 0.1);
//! assert_eq!(faults.to_string(), "corrupt=0.05,delay=0.1,seed=7");
//! assert!("lightning=0.5".parse::<Faults>().is_err());
//! ```

use std::fmt;
use std::str::FromStr;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;

use optobus_codec::crc::crc16;
use tokio::io::{AsyncWrite, AsyncWriteExt};

use crate::signal::mix;

/// What can go wrong with a reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum FaultKind {
    /// One bit flipped (RTU: anywhere, breaking the CRC; TCP: in the header).
    Corrupt,
    /// Only the start of the frame is sent.
    Truncate,
    /// Random bytes before the frame.
    Garbage,
    /// The reply comes from another slave address or unit id.
    WrongSlave,
    /// The correct frame in 2 or 3 pieces with pauses between them.
    Split,
    /// No reply.
    Drop,
    /// The correct reply, late.
    Delay,
    /// TCP: the connection is closed instead of replying (RTU: no reply).
    Disconnect,
}

const KINDS: usize = 8;

impl FaultKind {
    /// Every kind, in the order probabilities are drawn and printed.
    pub const ALL: [FaultKind; KINDS] = [
        Self::Corrupt,
        Self::Truncate,
        Self::Garbage,
        Self::WrongSlave,
        Self::Split,
        Self::Drop,
        Self::Delay,
        Self::Disconnect,
    ];

    /// The name used in text: `corrupt`, `truncate`, `garbage`, `wrong_slave`, `split`,
    /// `drop`, `delay`, `disconnect`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Corrupt => "corrupt",
            Self::Truncate => "truncate",
            Self::Garbage => "garbage",
            Self::WrongSlave => "wrong_slave",
            Self::Split => "split",
            Self::Drop => "drop",
            Self::Delay => "delay",
            Self::Disconnect => "disconnect",
        }
    }

    /// The kind called `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|kind| kind.name() == name)
    }

    const fn index(self) -> usize {
        self as usize
    }
}

impl fmt::Display for FaultKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The client timeout [`Faults::late`] assumes by default (the transports' default).
pub const DEFAULT_CLIENT_TIMEOUT: Duration = Duration::from_secs(1);

const DEFAULT_LATE: Duration = Duration::from_millis(1500);
const DEFAULT_PAUSE: Duration = Duration::from_millis(2);

/// Which faults to inject into replies, how often, and the seed.
///
/// Text form (parse with [`str::parse`], print with `Display`): comma-separated `kind=p` with
/// `p` in `0..=1` and the sum at most 1, plus optional `seed=N`, `late=DURATION`,
/// `pause=DURATION` and `timeout=DURATION` (sets `late` to 1.5 × the client timeout);
/// durations take `s`, `ms`, `us` or `ns` (`1.5s`, `250ms`). `none` or an empty text means no
/// faults.
#[derive(Clone, Debug, PartialEq)]
pub struct Faults {
    probabilities: [f64; KINDS],
    seed: u64,
    late: Duration,
    pause: Duration,
}

impl Default for Faults {
    fn default() -> Self {
        Self {
            probabilities: [0.0; KINDS],
            seed: 0,
            late: DEFAULT_LATE,
            pause: DEFAULT_PAUSE,
        }
    }
}

impl Faults {
    /// No faults, seed 0, `late` 1.5 s (1.5 × [`DEFAULT_CLIENT_TIMEOUT`]), `pause` 2 ms.
    pub fn new() -> Self {
        Self::default()
    }

    /// Gives `kind` probability `p` per reply (clamped to `0..=1`; NaN counts as 0). When
    /// the sum exceeds 1, kinds later in [`FaultKind::ALL`] get what is left
    /// ([`Faults::check`] reports it; parsing refuses it).
    pub fn with(mut self, kind: FaultKind, p: f64) -> Self {
        let p = if p.is_nan() { 0.0 } else { p.clamp(0.0, 1.0) };
        if let Some(slot) = self.probabilities.get_mut(kind.index()) {
            *slot = p;
        }
        self
    }

    /// Probability of [`FaultKind::Corrupt`].
    pub fn corrupt(self, p: f64) -> Self {
        self.with(FaultKind::Corrupt, p)
    }

    /// Probability of [`FaultKind::Truncate`].
    pub fn truncate(self, p: f64) -> Self {
        self.with(FaultKind::Truncate, p)
    }

    /// Probability of [`FaultKind::Garbage`].
    pub fn garbage(self, p: f64) -> Self {
        self.with(FaultKind::Garbage, p)
    }

    /// Probability of [`FaultKind::WrongSlave`].
    pub fn wrong_slave(self, p: f64) -> Self {
        self.with(FaultKind::WrongSlave, p)
    }

    /// Probability of [`FaultKind::Split`].
    pub fn split(self, p: f64) -> Self {
        self.with(FaultKind::Split, p)
    }

    /// Probability of [`FaultKind::Drop`].
    pub fn drop(self, p: f64) -> Self {
        self.with(FaultKind::Drop, p)
    }

    /// Probability of [`FaultKind::Delay`].
    pub fn delay(self, p: f64) -> Self {
        self.with(FaultKind::Delay, p)
    }

    /// Probability of [`FaultKind::Disconnect`].
    pub fn disconnect(self, p: f64) -> Self {
        self.with(FaultKind::Disconnect, p)
    }

    /// Seeds the choice of faults and of their bytes (default 0).
    pub fn seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// How late a delayed reply comes (default 1.5 s).
    pub fn late(mut self, late: Duration) -> Self {
        self.late = late;
        self
    }

    /// How late a delayed reply comes.
    pub fn late_by(&self) -> Duration {
        self.late
    }

    /// Sets `late` to 1.5 × `timeout`, so a delayed reply lands after the client gave up.
    pub fn client_timeout(self, timeout: Duration) -> Self {
        self.late(timeout.saturating_add(timeout / 2))
    }

    /// The pause between the pieces of a split reply (default 2 ms; 2 pauses at most).
    pub fn pause(mut self, pause: Duration) -> Self {
        self.pause = pause;
        self
    }

    /// The probability of `kind`.
    pub fn probability(&self, kind: FaultKind) -> f64 {
        self.probabilities.get(kind.index()).copied().unwrap_or(0.0)
    }

    /// Whether no fault can happen.
    pub fn is_none(&self) -> bool {
        self.probabilities.iter().all(|&p| p == 0.0)
    }

    /// Refuses probabilities that add up to more than 1.
    pub fn check(&self) -> Result<(), FaultsError> {
        let sum: f64 = self.probabilities.iter().sum();
        // Decimal text like 0.7+0.2+0.1 may sum to 1 plus rounding.
        if sum > 1.0 + 1e-9 {
            Err(FaultsError::SumAboveOne { sum })
        } else {
            Ok(())
        }
    }

    /// The fault for reply number `reply`, and the generator its bytes are drawn from.
    fn choose(&self, reply: u64) -> (Option<FaultKind>, Rng) {
        let mut rng = Rng(self.seed ^ mix(reply));
        let draw = rng.unit();
        let mut below = 0.0;
        for kind in FaultKind::ALL {
            below += self.probability(kind);
            if draw < below {
                return (Some(kind), rng);
            }
        }
        (None, rng)
    }
}

impl fmt::Display for Faults {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let defaults = Self::default();
        let mut items: Vec<String> = FaultKind::ALL
            .into_iter()
            .filter(|&kind| self.probability(kind) > 0.0)
            .map(|kind| format!("{kind}={}", self.probability(kind)))
            .collect();
        if self.seed != defaults.seed {
            items.push(format!("seed={}", self.seed));
        }
        if self.late != defaults.late {
            items.push(format!("late={}", DurationText(self.late)));
        }
        if self.pause != defaults.pause {
            items.push(format!("pause={}", DurationText(self.pause)));
        }
        if items.is_empty() {
            f.write_str("none")
        } else {
            f.write_str(&items.join(","))
        }
    }
}

/// Why a text does not describe [`Faults`].
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum FaultsError {
    /// A name that is neither a fault kind nor a parameter.
    UnknownKind(String),
    /// `name` without `=value`.
    MissingValue(String),
    /// The same name twice.
    Duplicate(String),
    /// A probability that is not a number in `0..=1`.
    BadProbability {
        /// The kind.
        kind: FaultKind,
        /// The text given.
        value: String,
    },
    /// Probabilities adding up to more than 1.
    SumAboveOne {
        /// Their sum.
        sum: f64,
    },
    /// A duration that is not a number with `s`, `ms`, `us` or `ns`.
    BadDuration {
        /// The parameter.
        name: &'static str,
        /// The text given.
        value: String,
    },
    /// A seed that is not an unsigned 64-bit integer.
    BadSeed(String),
}

impl fmt::Display for FaultsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::UnknownKind(name) => write!(
                f,
                "unknown fault `{name}` (known: corrupt, truncate, garbage, wrong_slave, split, \
                 drop, delay, disconnect, and seed, late, pause, timeout)"
            ),
            Self::MissingValue(name) => write!(f, "`{name}` needs a value: `{name}=…`"),
            Self::Duplicate(name) => write!(f, "`{name}` is given twice"),
            Self::BadProbability { kind, value } => {
                write!(f, "`{kind}={value}`: a probability is a number in 0..=1")
            }
            Self::SumAboveOne { sum } => {
                write!(f, "the probabilities add up to {sum}, more than 1")
            }
            Self::BadDuration { name, value } => {
                write!(
                    f,
                    "`{name}={value}`: a duration is a number with s, ms, us or ns"
                )
            }
            Self::BadSeed(value) => write!(f, "`seed={value}`: a seed is a whole number"),
        }
    }
}

impl std::error::Error for FaultsError {}

impl FromStr for Faults {
    type Err = FaultsError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let mut faults = Self::default();
        let mut seen: Vec<&str> = Vec::new();
        let text = text.trim();
        if text == "none" {
            return Ok(faults);
        }
        for item in text
            .split(',')
            .map(str::trim)
            .filter(|item| !item.is_empty())
        {
            let (name, value) = item
                .split_once('=')
                .map(|(name, value)| (name.trim(), value.trim()))
                .ok_or_else(|| FaultsError::MissingValue(item.to_owned()))?;
            if seen.contains(&name) {
                return Err(FaultsError::Duplicate(name.to_owned()));
            }
            seen.push(name);
            faults = match name {
                "seed" => {
                    let seed = value
                        .parse()
                        .map_err(|_| FaultsError::BadSeed(value.to_owned()))?;
                    faults.seed(seed)
                }
                "late" => faults.late(parse_duration("late", value)?),
                "pause" => faults.pause(parse_duration("pause", value)?),
                "timeout" => faults.client_timeout(parse_duration("timeout", value)?),
                _ => {
                    let kind = FaultKind::from_name(name)
                        .ok_or_else(|| FaultsError::UnknownKind(name.to_owned()))?;
                    let p = value
                        .parse::<f64>()
                        .ok()
                        .filter(|p| (0.0..=1.0).contains(p))
                        .ok_or_else(|| FaultsError::BadProbability {
                            kind,
                            value: value.to_owned(),
                        })?;
                    faults.with(kind, p)
                }
            };
        }
        faults.check()?;
        Ok(faults)
    }
}

/// `1.5s`, `250ms`, `100us`, `10ns`.
fn parse_duration(name: &'static str, text: &str) -> Result<Duration, FaultsError> {
    let bad = || FaultsError::BadDuration {
        name,
        value: text.to_owned(),
    };
    let digits = text
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .ok_or_else(bad)?;
    let (number, unit) = text.split_at(digits);
    let unit_nanos = match unit.trim() {
        "s" => 1e9,
        "ms" => 1e6,
        "us" | "µs" => 1e3,
        "ns" => 1.0,
        _ => return Err(bad()),
    };
    let nanos = number.parse::<f64>().map_err(|_| bad())? * unit_nanos;
    if !nanos.is_finite() || nanos < 0.0 || nanos >= u64::MAX as f64 {
        return Err(bad());
    }
    Ok(Duration::from_nanos(nanos.round() as u64))
}

/// A duration in the largest unit that shows it exactly, so the text parses back to it.
struct DurationText(Duration);

impl fmt::Display for DurationText {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let nanos = self.0.as_nanos();
        for (unit, size) in [("s", 1_000_000_000), ("ms", 1_000_000), ("us", 1_000)] {
            if nanos.is_multiple_of(size) {
                return write!(f, "{}{unit}", nanos / size);
            }
        }
        write!(f, "{nanos}ns")
    }
}

/// Longest per-reply log [`FaultStats::log`] keeps, so a long run does not grow without end.
const MAX_LOG: usize = 1 << 20;

/// Counts of injected faults and a per-reply log; clones share them, so a test can read them
/// while the device serves.
#[derive(Clone, Debug, Default)]
pub struct FaultStats(Arc<Mutex<Record>>);

#[derive(Debug, Default)]
struct Record {
    replies: u64,
    counts: [u64; KINDS],
    log: Vec<Option<FaultKind>>,
}

impl FaultStats {
    fn lock(&self) -> MutexGuard<'_, Record> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Replies the device produced (faulted or not).
    pub fn replies(&self) -> u64 {
        self.lock().replies
    }

    /// Faults of `kind` injected.
    pub fn count(&self, kind: FaultKind) -> u64 {
        self.lock().counts.get(kind.index()).copied().unwrap_or(0)
    }

    /// Faults injected in all.
    pub fn injected(&self) -> u64 {
        self.lock().counts.iter().sum()
    }

    /// The fault of each reply, in order (`None`: sent as is); the first 2^20 replies.
    pub fn log(&self) -> Vec<Option<FaultKind>> {
        self.lock().log.clone()
    }
}

/// The run's summary with the faults that were asked for: `faults injected: 3 of 40 replies
/// (drop 2, delay 1)`, naming every kind asked for or injected.
#[derive(Clone, Copy, Debug)]
pub struct FaultSummary<'a> {
    faults: &'a Faults,
    stats: &'a FaultStats,
}

impl FaultStats {
    /// The one-line summary of these counts for a run with `faults`.
    pub fn summary<'a>(&'a self, faults: &'a Faults) -> FaultSummary<'a> {
        FaultSummary {
            faults,
            stats: self,
        }
    }
}

impl fmt::Display for FaultSummary<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let Self { faults, stats } = self;
        write!(
            f,
            "faults injected: {} of {} replies",
            stats.injected(),
            stats.replies()
        )?;
        let mut kinds = FaultKind::ALL
            .into_iter()
            .filter(|&kind| faults.probability(kind) > 0.0 || stats.count(kind) > 0);
        if let Some(first) = kinds.next() {
            write!(f, " ({first} {}", stats.count(first))?;
            for kind in kinds {
                write!(f, ", {kind} {}", stats.count(kind))?;
            }
            f.write_str(")")?;
        }
        Ok(())
    }
}

/// How a reply goes out: pieces, each after a pause, and whether the connection closes.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Plan {
    pub(crate) pieces: Vec<(Duration, Vec<u8>)>,
    pub(crate) close: bool,
}

impl Plan {
    pub(crate) fn clean(frame: Vec<u8>) -> Self {
        Self {
            pieces: vec![(Duration::ZERO, frame)],
            close: false,
        }
    }
}

/// Writes `plan`'s pieces to `io`, sleeping out each pause (the device reads nothing
/// meanwhile).
pub(crate) async fn send<IO>(io: &mut IO, plan: &Plan) -> std::io::Result<()>
where
    IO: AsyncWrite + Unpin,
{
    for (pause, bytes) in &plan.pieces {
        if !pause.is_zero() {
            tokio::time::sleep(*pause).await;
        }
        io.write_all(bytes).await?;
        io.flush().await?;
    }
    Ok(())
}

/// How a reply is framed: what `corrupt`, `garbage` and `wrong_slave` touch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Framing {
    Rtu,
    Tcp,
}

/// Faults in force on a device or bus, with their stats.
#[derive(Clone, Debug)]
pub(crate) struct Injector {
    faults: Faults,
    stats: FaultStats,
}

impl Injector {
    pub(crate) fn new(faults: Faults) -> Self {
        Self {
            faults,
            stats: FaultStats::default(),
        }
    }

    pub(crate) fn stats(&self) -> FaultStats {
        self.stats.clone()
    }

    /// How `frame`, the device's reply, goes out.
    pub(crate) fn plan(&self, frame: Vec<u8>, framing: Framing) -> Plan {
        let (kind, mut rng) = {
            let mut record = self.stats.lock();
            let reply = record.replies;
            record.replies = reply.saturating_add(1);
            let (kind, rng) = self.faults.choose(reply);
            if let Some(count) = kind.and_then(|kind| record.counts.get_mut(kind.index())) {
                *count = count.saturating_add(1);
            }
            if record.log.len() < MAX_LOG {
                record.log.push(kind);
            }
            (kind, rng)
        };
        match kind {
            None => Plan::clean(frame),
            Some(kind) => apply(kind, frame, framing, &self.faults, &mut rng),
        }
    }
}

fn apply(
    kind: FaultKind,
    mut frame: Vec<u8>,
    framing: Framing,
    faults: &Faults,
    rng: &mut Rng,
) -> Plan {
    match kind {
        FaultKind::Corrupt => {
            // TCP: the header and function code, the only bytes a client can check.
            let span = match framing {
                Framing::Rtu => frame.len(),
                Framing::Tcp => frame.len().min(8),
            };
            let at = rng.below(span);
            // Flipping the exception bit of the function code would change the reply's
            // meaning rather than break it.
            let bits = if framing == Framing::Tcp && at == 7 {
                7
            } else {
                8
            };
            if let Some(byte) = frame.get_mut(at) {
                *byte ^= 1 << rng.below(bits);
            }
            Plan::clean(frame)
        }
        FaultKind::Truncate => {
            let keep = if frame.len() < 2 {
                0
            } else {
                1 + rng.below(frame.len() - 1)
            };
            frame.truncate(keep);
            Plan::clean(frame)
        }
        FaultKind::Garbage => {
            let count = match framing {
                Framing::Rtu => 1 + rng.below(8),
                Framing::Tcp => 4 + rng.below(5),
            };
            let mut bytes: Vec<u8> = (0..count).map(|_| rng.next() as u8).collect();
            match framing {
                // A client looking for its slave address does not find it at once.
                Framing::Rtu => {
                    if let (Some(first), Some(&slave)) = (bytes.first_mut(), frame.first()) {
                        if *first == slave {
                            *first = slave.wrapping_add(1);
                        }
                    }
                }
                // Protocol id (bytes 2 and 3) not 0: not an MBAP header.
                Framing::Tcp => {
                    if let Some(protocol) = bytes.get_mut(2) {
                        if *protocol == 0 {
                            *protocol = 1;
                        }
                    }
                }
            }
            bytes.extend_from_slice(&frame);
            Plan::clean(bytes)
        }
        FaultKind::WrongSlave => {
            match framing {
                Framing::Rtu if frame.len() >= 4 => {
                    if let Some(slave) = frame.first_mut() {
                        *slave = other_slave(*slave, rng);
                    }
                    let body = frame.len() - 2;
                    let crc = crc16(frame.get(..body).unwrap_or_default()).to_le_bytes();
                    frame.truncate(body);
                    frame.extend_from_slice(&crc);
                }
                Framing::Rtu => {}
                Framing::Tcp => {
                    if let Some(unit) = frame.get_mut(6) {
                        let other = rng.below(255) as u8;
                        *unit = if other >= *unit { other + 1 } else { other };
                    }
                }
            }
            Plan::clean(frame)
        }
        FaultKind::Split => {
            let len = frame.len();
            if len < 2 {
                return Plan::clean(frame);
            }
            let mut cuts = vec![1 + rng.below(len - 1)];
            if len >= 3 && rng.below(2) == 1 {
                // A second cut after the first: three pieces.
                let first = 1 + rng.below(len - 2);
                cuts = vec![first, first + 1 + rng.below(len - 1 - first)];
            }
            let mut pieces = Vec::with_capacity(3);
            let mut start = 0;
            for end in cuts.into_iter().chain([len]) {
                let pause = if start == 0 {
                    Duration::ZERO
                } else {
                    faults.pause
                };
                pieces.push((pause, frame.get(start..end).unwrap_or_default().to_vec()));
                start = end;
            }
            Plan {
                pieces,
                close: false,
            }
        }
        FaultKind::Drop => Plan::default(),
        FaultKind::Delay => Plan {
            pieces: vec![(faults.late, frame)],
            close: false,
        },
        FaultKind::Disconnect => Plan {
            pieces: Vec::new(),
            close: framing == Framing::Tcp,
        },
    }
}

/// A slave address in 1..=247 other than `slave`.
fn other_slave(slave: u8, rng: &mut Rng) -> u8 {
    if (1..=247).contains(&slave) {
        let other = 1 + rng.below(246) as u8;
        if other >= slave {
            other + 1
        } else {
            other
        }
    } else {
        1 + rng.below(247) as u8
    }
}

/// SplitMix64 as a stream: small, seedable, good enough for test faults.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        mix(self.0)
    }

    /// A number in `0..n` (0 when `n` is 0).
    fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next() % n as u64) as usize
        }
    }

    /// A number in `0..1`.
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}
