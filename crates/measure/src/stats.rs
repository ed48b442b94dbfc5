//! Rolling statistics over a window of the latest values (a count of them, or a duration):
//! count, mean, standard deviation, min, max, range, and Cp/Cpk against a tolerance, each in
//! constant time per value (amortised).

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// The most values a window holds, whatever it says: a duration window of a fast measurement
/// stays bounded in memory.
pub const MAX_WINDOW: usize = 1_000_000;

/// Which values the statistics are over.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Window {
    /// The latest `n` values.
    Count(usize),
    /// The values of the latest span of time.
    Duration(Duration),
}

/// The statistics of the values in the window.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Summary {
    /// How many values.
    pub count: usize,
    /// Their mean.
    pub mean: f64,
    /// Their sample standard deviation (`None` below two values).
    pub sd: Option<f64>,
    /// The least.
    pub min: f64,
    /// The greatest.
    pub max: f64,
    /// `max − min`.
    pub range: f64,
    /// `(hi − lo) / 6σ`, where the tolerance is given and σ > 0.
    pub cp: Option<f64>,
    /// `min(hi − μ, μ − lo) / 3σ`, likewise.
    pub cpk: Option<f64>,
}

/// A rolling window of values with their running sums and the queues that keep its min and
/// max.
#[derive(Clone, Debug)]
pub struct Rolling {
    window: Window,
    values: VecDeque<(u64, Instant, f64)>,
    /// Sequence number of the next value.
    next: u64,
    /// Values are summed less this (the first value), which keeps the sum of squares from
    /// cancelling away the digits of values far from zero.
    shift: Option<f64>,
    sum: f64,
    squares: f64,
    /// Candidates for the min (increasing) and the max (decreasing), by sequence number.
    minima: VecDeque<(u64, f64)>,
    maxima: VecDeque<(u64, f64)>,
    /// Values taken out since the sums were last recomputed: floating-point sums drift as
    /// values come and go, so they are recomputed once per window's worth.
    removed: usize,
}

impl Rolling {
    /// An empty window.
    pub fn new(window: Window) -> Self {
        Self {
            window,
            values: VecDeque::new(),
            next: 0,
            shift: None,
            sum: 0.0,
            squares: 0.0,
            minima: VecDeque::new(),
            maxima: VecDeque::new(),
            removed: 0,
        }
    }

    /// Takes in `value`, read at `at`, dropping what leaves the window. Values that are not
    /// finite are not taken.
    pub fn push(&mut self, at: Instant, value: f64) {
        if !value.is_finite() {
            return;
        }
        let shift = *self.shift.get_or_insert(value);
        let sequence = self.next;
        self.next += 1;
        self.values.push_back((sequence, at, value));
        let shifted = value - shift;
        self.sum += shifted;
        self.squares += shifted * shifted;
        while self.minima.back().is_some_and(|(_, v)| *v >= value) {
            self.minima.pop_back();
        }
        self.minima.push_back((sequence, value));
        while self.maxima.back().is_some_and(|(_, v)| *v <= value) {
            self.maxima.pop_back();
        }
        self.maxima.push_back((sequence, value));
        self.expire(at);
    }

    /// Drops the values that left the window by `now` (a duration window ages without new
    /// values).
    pub fn expire(&mut self, now: Instant) {
        let limit = match self.window {
            Window::Count(count) => count.clamp(1, MAX_WINDOW),
            Window::Duration(_) => MAX_WINDOW,
        };
        while let Some(&(sequence, at, value)) = self.values.front() {
            let too_old = match self.window {
                Window::Duration(span) => now.saturating_duration_since(at) > span,
                Window::Count(_) => false,
            };
            if self.values.len() <= limit && !too_old {
                break;
            }
            self.values.pop_front();
            let shifted = value - self.shift.unwrap_or(0.0);
            self.sum -= shifted;
            self.squares -= shifted * shifted;
            if self.minima.front().is_some_and(|(s, _)| *s == sequence) {
                self.minima.pop_front();
            }
            if self.maxima.front().is_some_and(|(s, _)| *s == sequence) {
                self.maxima.pop_front();
            }
            self.removed += 1;
        }
        if self.removed > self.values.len().max(64) {
            self.recompute();
        }
    }

    fn recompute(&mut self) {
        self.shift = self.values.front().map(|(_, _, v)| *v);
        let shift = self.shift.unwrap_or(0.0);
        self.sum = self.values.iter().map(|(_, _, v)| v - shift).sum();
        self.squares = self
            .values
            .iter()
            .map(|(_, _, v)| (v - shift).powi(2))
            .sum();
        self.removed = 0;
    }

    /// Empties the window.
    pub fn reset(&mut self) {
        *self = Self::new(self.window);
    }

    /// The statistics now, against the tolerance `(lo, hi)` if given; `None` while empty.
    pub fn summary(&self, tolerance: Option<(f64, f64)>) -> Option<Summary> {
        let count = self.values.len();
        let (min, max) = (self.minima.front()?.1, self.maxima.front()?.1);
        let n = count as f64;
        let shift = self.shift.unwrap_or(0.0);
        let mean = shift + self.sum / n;
        let sd = (count >= 2).then(|| {
            let variance = (self.squares - self.sum * self.sum / n) / (n - 1.0);
            variance.max(0.0).sqrt()
        });
        let capability = |sd: Option<f64>| {
            let (lo, hi) = tolerance?;
            let sd = sd.filter(|sd| *sd > 0.0)?;
            Some((
                (hi - lo) / (6.0 * sd),
                (hi - mean).min(mean - lo) / (3.0 * sd),
            ))
        };
        let (cp, cpk) = capability(sd).unzip();
        Some(Summary {
            count,
            mean,
            sd,
            min,
            max,
            range: max - min,
            cp,
            cpk,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The statistics written out the long way, for the values in the window.
    fn by_hand(values: &[f64]) -> (f64, f64, f64, f64) {
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let sd = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let min = values.iter().copied().fold(f64::INFINITY, f64::min);
        let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (mean, sd, min, max)
    }

    #[test]
    fn a_count_window_keeps_the_latest_values() {
        let mut rolling = Rolling::new(Window::Count(5));
        let start = Instant::now();
        let values: Vec<f64> = (0..1_000)
            .map(|i| 10.0 + ((i * 37) % 17) as f64 * 0.001)
            .collect();
        for (i, v) in values.iter().enumerate() {
            rolling.push(start, *v);
            let window = &values[i.saturating_sub(4)..=i];
            let summary = rolling.summary(Some((9.99, 10.02))).unwrap();
            assert_eq!(summary.count, window.len());
            let (mean, sd, min, max) = by_hand(window);
            assert!(
                (summary.mean - mean).abs() < 1e-9,
                "{i}: {} {mean}",
                summary.mean
            );
            assert_eq!((summary.min, summary.max), (min, max));
            if window.len() >= 2 {
                assert!((summary.sd.unwrap() - sd).abs() < 1e-9);
                if sd > 0.0 {
                    let cp = 0.03 / (6.0 * sd);
                    assert!((summary.cp.unwrap() - cp).abs() < 1e-6 * cp);
                }
            }
        }
    }

    #[test]
    fn a_duration_window_ages() {
        let mut rolling = Rolling::new(Window::Duration(Duration::from_secs(10)));
        let start = Instant::now();
        for second in 0..20u64 {
            rolling.push(start + Duration::from_secs(second), second as f64);
        }
        let summary = rolling.summary(None).unwrap();
        // 9 to 19: ten seconds back from 19, inclusive.
        assert_eq!((summary.count, summary.min, summary.max), (11, 9.0, 19.0));
        rolling.expire(start + Duration::from_secs(100));
        assert!(rolling.summary(None).is_none());
    }

    #[test]
    fn without_both_limits_there_is_no_capability() {
        let mut rolling = Rolling::new(Window::Count(10));
        let now = Instant::now();
        rolling.push(now, 1.0);
        rolling.push(now, 2.0);
        let summary = rolling.summary(None).unwrap();
        assert_eq!((summary.cp, summary.cpk), (None, None));
        assert!(rolling.summary(Some((0.0, 3.0))).unwrap().cpk.is_some());
    }
}
