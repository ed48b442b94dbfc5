//! Judgement of a value against limits, as the vendors' comparators do it: LL / LO / GO / HI /
//! HH with hysteresis, and a count of each since start or the last reset.

use std::fmt;

use crate::number::Decimal;

/// Where a value lies against the limits, lowest first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Judgement {
    /// Below `ll`.
    LowLow,
    /// Below `lo`.
    Low,
    /// Within the limits (`lo ≤ value ≤ hi`): OK.
    Go,
    /// Above `hi`.
    High,
    /// Above `hh`.
    HighHigh,
}

impl Judgement {
    /// Every judgement, lowest first.
    pub const ALL: [Self; 5] = [
        Self::LowLow,
        Self::Low,
        Self::Go,
        Self::High,
        Self::HighHigh,
    ];

    /// Its name in every output: `ll`, `lo`, `go`, `hi`, `hh`.
    pub fn name(self) -> &'static str {
        match self {
            Self::LowLow => "ll",
            Self::Low => "lo",
            Self::Go => "go",
            Self::High => "hi",
            Self::HighHigh => "hh",
        }
    }

    /// OK (GO) or not good (any other).
    pub fn is_ok(self) -> bool {
        self == Self::Go
    }
}

impl fmt::Display for Judgement {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The limits of a measurement, in its unit; any of them may be absent.
#[derive(Clone, Copy, Debug, Default)]
pub struct Limits {
    /// Below this: LL.
    pub ll: Option<Decimal>,
    /// Below this: LO.
    pub lo: Option<Decimal>,
    /// Above this: HI.
    pub hi: Option<Decimal>,
    /// Above this: HH.
    pub hh: Option<Decimal>,
    /// How far back past a limit a value must come to leave the judgement it crossed into
    /// (zero: none).
    pub hysteresis: Decimal,
}

/// Why limits cannot work.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LimitsError(pub String);

impl fmt::Display for LimitsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for LimitsError {}

impl Limits {
    /// Checks that the limits are in order (`ll ≤ lo ≤ hi ≤ hh`, those given) and the
    /// hysteresis is not negative.
    pub fn check(&self) -> Result<(), LimitsError> {
        if self.hysteresis.mantissa() < 0 {
            return Err(LimitsError("`hysteresis` cannot be negative".into()));
        }
        let given: Vec<(&str, Decimal)> = [
            ("ll", self.ll),
            ("lo", self.lo),
            ("hi", self.hi),
            ("hh", self.hh),
        ]
        .into_iter()
        .filter_map(|(name, limit)| Some((name, limit?)))
        .collect();
        for pair in given.windows(2) {
            let ((low_name, low), (high_name, high)) = (pair[0], pair[1]);
            if low.compare(high).is_gt() {
                return Err(LimitsError(format!(
                    "`{low_name}` must not be above `{high_name}`"
                )));
            }
        }
        Ok(())
    }

    /// Whether both `lo` and `hi` are given (what Cp and Cpk need).
    pub fn tolerance(&self) -> Option<(Decimal, Decimal)> {
        Some((self.lo?, self.hi?))
    }
}

/// A comparator: judges each value against the limits, remembering its last judgement for
/// the hysteresis, and counts each judgement.
#[derive(Clone, Debug)]
pub struct Comparator {
    limits: Limits,
    last: Option<Judgement>,
    counts: [u64; 5],
}

impl Comparator {
    /// A comparator with no judgement yet.
    pub fn new(limits: Limits) -> Self {
        Self {
            limits,
            last: None,
            counts: [0; 5],
        }
    }

    /// The limits.
    pub fn limits(&self) -> &Limits {
        &self.limits
    }

    /// Judges `value` and counts it. A limit crossed outwards is crossed at the limit; back
    /// inwards only once the value is `hysteresis` inside it.
    pub fn judge(&mut self, value: Decimal) -> Judgement {
        let last = self.last.unwrap_or(Judgement::Go);
        let h = self.limits.hysteresis;
        // Above an upper limit: past it, or past it less the hysteresis while already there.
        let above = |limit: Option<Decimal>, level: Judgement| {
            limit.is_some_and(|limit| {
                let threshold = if last >= level {
                    limit.checked_sub(h).unwrap_or(limit)
                } else {
                    limit
                };
                value.compare(threshold).is_gt()
            })
        };
        let below = |limit: Option<Decimal>, level: Judgement| {
            limit.is_some_and(|limit| {
                let threshold = if last <= level {
                    limit.checked_add(h).unwrap_or(limit)
                } else {
                    limit
                };
                value.compare(threshold).is_lt()
            })
        };
        let judgement = if above(self.limits.hh, Judgement::HighHigh) {
            Judgement::HighHigh
        } else if above(self.limits.hi, Judgement::High) {
            Judgement::High
        } else if below(self.limits.ll, Judgement::LowLow) {
            Judgement::LowLow
        } else if below(self.limits.lo, Judgement::Low) {
            Judgement::Low
        } else {
            Judgement::Go
        };
        self.last = Some(judgement);
        self.counts[judgement as usize] += 1;
        judgement
    }

    /// The values judged so far, per judgement (lowest first, as [`Judgement::ALL`]).
    pub fn counts(&self) -> [u64; 5] {
        self.counts
    }

    /// The count of one judgement.
    pub fn count(&self, judgement: Judgement) -> u64 {
        self.counts[judgement as usize]
    }

    /// Counts back to zero (the judgement's memory for the hysteresis stays).
    pub fn reset_counts(&mut self) {
        self.counts = [0; 5];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mm(text: &str) -> Decimal {
        let (whole, fraction) = text.split_once('.').unwrap_or((text, ""));
        Decimal::new(
            format!("{whole}{fraction}").parse().unwrap(),
            -(fraction.len() as i32),
        )
    }

    #[test]
    fn hysteresis_holds_a_crossed_limit_until_the_value_is_back_inside_by_it() {
        let mut comparator = Comparator::new(Limits {
            lo: Some(mm("9.9")),
            hi: Some(mm("10.1")),
            hysteresis: mm("0.01"),
            ..Limits::default()
        });
        let judged: Vec<_> = [
            "10.0", "10.1", "10.11", "10.095", "10.09", "9.89", "9.905", "9.91", "10.0",
        ]
        .iter()
        .map(|v| comparator.judge(mm(v)))
        .collect();
        use Judgement::*;
        assert_eq!(judged, [Go, Go, High, High, Go, Low, Low, Go, Go]);
        assert_eq!(comparator.count(Go), 5);
        assert_eq!(comparator.count(High), 2);
        assert_eq!(comparator.count(Low), 2);
        comparator.reset_counts();
        assert_eq!(comparator.counts(), [0; 5]);
    }

    #[test]
    fn outer_limits_judge_first() {
        let mut comparator = Comparator::new(Limits {
            ll: Some(mm("9")),
            lo: Some(mm("9.9")),
            hi: Some(mm("10.1")),
            hh: Some(mm("11")),
            hysteresis: Decimal::ZERO,
        });
        assert_eq!(comparator.judge(mm("12")), Judgement::HighHigh);
        assert_eq!(comparator.judge(mm("10.5")), Judgement::High);
        assert_eq!(comparator.judge(mm("8")), Judgement::LowLow);
        assert_eq!(comparator.judge(mm("9.5")), Judgement::Low);
    }

    #[test]
    fn limits_out_of_order_are_refused() {
        let limits = Limits {
            lo: Some(mm("10.1")),
            hi: Some(mm("9.9")),
            ..Limits::default()
        };
        assert!(limits
            .check()
            .unwrap_err()
            .0
            .contains("`lo` must not be above `hi`"));
    }
}
