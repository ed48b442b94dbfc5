//! Measurements as values come: each input's latest reading kept, and a measurement evaluated
//! once every one of its inputs has been read again since its last value, then judged and
//! added to its statistics. Inputs read too far apart, or without a valid value, make the
//! value invalid with the reason: never a stale or mixed value.

use std::time::{Duration, Instant, SystemTime};

use optobus_codec::value::Fixed;

use crate::formula::{Invalid, Plan};
use crate::judge::{Comparator, Judgement, Limits};
use crate::number::Decimal;
use crate::stats::{Rolling, Summary, Window};

/// How one measurement is judged and summed up, beside its formula.
#[derive(Clone, Debug)]
pub struct Settings {
    /// Its limits, if it has any.
    pub limits: Option<Limits>,
    /// Its statistics' window, if it keeps statistics.
    pub stats: Option<Window>,
    /// The furthest apart its inputs' requests may be.
    pub max_skew: Duration,
}

/// One input as it was read.
#[derive(Clone, Debug, PartialEq)]
pub struct Reading {
    /// Its value; `None` when it has none (the reason says why).
    pub value: Option<Fixed>,
    /// When its request left.
    pub requested: SystemTime,
    /// Why it has no value (the device's sentinel, the device offline, no reply).
    pub reason: Option<String>,
}

/// A measurement's value, or why it has none, with what it was computed from.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// Which measurement (its index in the plan's formulas).
    pub formula: usize,
    /// Its value in its unit, or why it has none.
    pub value: Result<Fixed, String>,
    /// Its inputs as they were read (indices into the plan's inputs).
    pub inputs: Vec<(usize, Reading)>,
    /// Between the first and the last input's request.
    pub skew: Duration,
    /// Against its limits, if it has any and a value.
    pub judgement: Option<Judgement>,
    /// Its statistics after this value, if it keeps them.
    pub stats: Option<Summary>,
}

/// The live state of a file's measurements.
#[derive(Debug)]
pub struct Live {
    plan: Plan,
    settings: Vec<Settings>,
    /// The latest reading of each input, and a count of readings taken, which tells a fresh
    /// one from one a measurement has used already.
    latest: Vec<Option<(u64, Reading)>>,
    /// For each formula, the reading count of each of its inputs at its last value.
    used: Vec<Vec<u64>>,
    comparators: Vec<Option<Comparator>>,
    rolling: Vec<Option<Rolling>>,
    taken: u64,
}

impl Live {
    /// The measurements of `plan`, with `settings` in the order of its formulas.
    pub fn new(plan: Plan, settings: Vec<Settings>) -> Self {
        let comparators = settings
            .iter()
            .map(|s| s.limits.map(Comparator::new))
            .collect();
        let rolling = settings.iter().map(|s| s.stats.map(Rolling::new)).collect();
        let used = plan
            .formulas
            .iter()
            .map(|f| vec![0; f.inputs.len()])
            .collect();
        Self {
            latest: vec![None; plan.inputs.len()],
            plan,
            settings,
            used,
            comparators,
            rolling,
            taken: 0,
        }
    }

    /// The plan.
    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// Takes in a reading of input `input`; gives the measurements it completes: those whose
    /// inputs have all been read again since their last value, in the plan's order (a
    /// measurement after those it uses).
    pub fn take(&mut self, input: usize, reading: Reading) -> Vec<Outcome> {
        let Some(slot) = self.latest.get_mut(input) else {
            return Vec::new();
        };
        self.taken += 1;
        *slot = Some((self.taken, reading));
        let due: Vec<usize> = (0..self.plan.formulas.len())
            .filter(|&f| self.is_due(f) && self.plan.formulas[f].inputs.contains(&input))
            .collect();
        if due.is_empty() {
            return Vec::new();
        }
        let values: Vec<Option<Fixed>> = self
            .latest
            .iter()
            .map(|l| l.as_ref().and_then(|(_, r)| r.value))
            .collect();
        let results = self.plan.evaluate(&values);
        due.into_iter()
            .map(|formula| self.outcome(formula, results[formula].clone()))
            .collect()
    }

    /// Every input of `formula` read, each since its last value; an input without a value
    /// (its device offline) counts as read, so that the measurement goes on giving values,
    /// invalid with the reason, at the pace of its other inputs.
    fn is_due(&self, formula: usize) -> bool {
        self.plan.formulas[formula]
            .inputs
            .iter()
            .zip(&self.used[formula])
            .all(|(&input, &used)| {
                self.latest[input]
                    .as_ref()
                    .is_some_and(|(n, reading)| *n > used || reading.value.is_none())
            })
    }

    fn outcome(&mut self, formula: usize, result: Result<Fixed, Invalid>) -> Outcome {
        let inputs: Vec<(usize, Reading)> = self.plan.formulas[formula]
            .inputs
            .iter()
            .filter_map(|&i| Some((i, self.latest[i].as_ref()?.1.clone())))
            .collect();
        self.used[formula] = self.plan.formulas[formula]
            .inputs
            .iter()
            .map(|&i| self.latest[i].as_ref().map_or(0, |(n, _)| *n))
            .collect();
        let times = inputs.iter().map(|(_, r)| r.requested);
        let (first, last) = (times.clone().min(), times.max());
        let skew = match (first, last) {
            (Some(first), Some(last)) => last.duration_since(first).unwrap_or_default(),
            _ => Duration::ZERO,
        };
        let max_skew = self.settings[formula].max_skew;
        let value = match result {
            Err(invalid) => Err(self.reason(invalid, &inputs)),
            Ok(_) if skew > max_skew => Err(format!(
                "its inputs were read {} ms apart, more than max_skew ({} ms)",
                skew.as_millis(),
                max_skew.as_millis()
            )),
            Ok(value) => Ok(value),
        };
        let (judgement, stats) = match &value {
            Ok(value) => self.judge(formula, *value),
            Err(_) => (None, self.summary(formula)),
        };
        Outcome {
            formula,
            value,
            inputs,
            skew,
            judgement,
            stats,
        }
    }

    /// Why a value is invalid, in words: which input and why, or the arithmetic.
    fn reason(&self, invalid: Invalid, inputs: &[(usize, Reading)]) -> String {
        match invalid {
            Invalid::Input(index) => {
                let name = &self.plan.inputs[index];
                let why = inputs
                    .iter()
                    .find(|(i, _)| *i == index)
                    .and_then(|(_, r)| r.reason.clone())
                    .unwrap_or_else(|| "it has no valid value".to_owned());
                format!("{name}: {why}")
            }
            Invalid::Measurement(index) => {
                format!("{} has no value", self.plan.formulas[index].name)
            }
            Invalid::Arithmetic(error) => error.to_string(),
        }
    }

    fn judge(&mut self, formula: usize, value: Fixed) -> (Option<Judgement>, Option<Summary>) {
        let decimal = Decimal::from_fixed(value, 0);
        let judgement = match (&mut self.comparators[formula], decimal) {
            (Some(comparator), Some(decimal)) => Some(comparator.judge(decimal)),
            _ => None,
        };
        if let Some(rolling) = &mut self.rolling[formula] {
            rolling.push(Instant::now(), value.to_f64());
        }
        (judgement, self.summary(formula))
    }

    fn summary(&self, formula: usize) -> Option<Summary> {
        let tolerance = self.settings[formula]
            .limits
            .and_then(|l| l.tolerance())
            .map(|(lo, hi)| (lo.to_f64(), hi.to_f64()));
        self.rolling[formula].as_ref()?.summary(tolerance)
    }

    /// The judgement counts of `formula` (lowest first), if it has limits.
    pub fn counts(&self, formula: usize) -> Option<[u64; 5]> {
        Some(self.comparators.get(formula)?.as_ref()?.counts())
    }

    /// Judgement counts back to zero, and statistics emptied, for every measurement.
    pub fn reset(&mut self) {
        for comparator in self.comparators.iter_mut().flatten() {
            comparator.reset_counts();
        }
        for rolling in self.rolling.iter_mut().flatten() {
            rolling.reset();
        }
    }
}
