//! Deterministic, plausible readings for measurement registers.
//!
//! A measurement is a readable, non-writable integer or record register that has a unit, a
//! scale or a sentinel, sits in the input table, or belongs to the `measurements` group. Its
//! value is a function of the time since the simulator was created (tokio's clock, so paused
//! test time works) and of the seed:
//!
//! - a *level*: a slow sine (period 20 to 40 s) around a plausible value with a little
//!   per-sample noise; inside `range` when the register has one, else chosen by unit (a
//!   distance of 5 mm, or 1500 mm for coarse 0.1 mm long-range steps; 35 ℃; 40000 uV);
//! - a *counter* for unit-less `*_count` readings (encoder pulses), 1000 per second;
//! - a *mirror* of another reading whose name it ends with (`sampled_distance_1` follows
//!   `distance_1`; the rangefinder's result record follows `distance` and `temperature`);
//! - a *statistic* (maximum, minimum or peak-to-peak, as its `<name>_config` packed register
//!   selects) of another reading since the statistic was last reset.
//!
//! Readings with a sentinel read as the sentinel in one sample of `sentinel_every` (10 ms
//! samples, chosen by a hash of the seed, the register and the sample number); statistics and
//! counters never do. A valid reading that would equal the sentinel is moved by one step.

use std::f64::consts::TAU;

use optobus_codec::value::Fixed;
use optobus_device::{
    Access, DeviceInfo, FieldInfo, GroupInfo, RegisterInfo, Scalar, Scale, ValueKind,
};

use crate::names;

/// Index into [`Signals`].
pub(crate) type SignalId = usize;

/// Seconds per sample: sentinels and noise change once per sample.
const SAMPLE: f64 = 0.01;

/// A slow sine.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Level {
    center: f64,
    amplitude: f64,
    period: f64,
    phase: f64,
}

impl Level {
    fn at(&self, t: f64) -> f64 {
        self.center + self.amplitude * (TAU * t / self.period + self.phase).sin()
    }

    /// The lowest and highest value over `[from, to]` (noise aside).
    fn extremes(&self, from: f64, to: f64) -> (f64, f64) {
        let (a, b) = (self.at(from), self.at(to));
        let (mut low, mut high) = (a.min(b), a.max(b));
        let omega = TAU / self.period;
        // The sine peaks where its angle is π/2 + 2πk and bottoms out at 3π/2 + 2πk.
        let reaches = |angle: f64| {
            let k = ((omega * from + self.phase - angle) / TAU).ceil();
            let t = (angle + TAU * k - self.phase) / omega;
            t <= to
        };
        if reaches(TAU / 4.0) {
            high = self.center + self.amplitude;
        }
        if reaches(3.0 * TAU / 4.0) {
            low = self.center - self.amplitude;
        }
        (low, high)
    }
}

/// A statistic's kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum StatisticKind {
    Maximum,
    Minimum,
    PeakToPeak,
}

impl StatisticKind {
    pub(crate) fn from_code_name(name: &str) -> Option<Self> {
        match name {
            names::MAXIMUM => Some(Self::Maximum),
            names::MINIMUM => Some(Self::Minimum),
            names::PEAK_TO_PEAK => Some(Self::PeakToPeak),
            _ => None,
        }
    }
}

/// A statistic: which register configures it and which of its fields say what.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Statistic {
    /// The packed configuration register.
    pub(crate) config: usize,
    /// Its field whose code names are the source registers.
    pub(crate) source_field: &'static FieldInfo,
    /// Its field whose codes are maximum / minimum / peak-to-peak.
    pub(crate) kind_field: &'static FieldInfo,
}

/// Where a signal's value comes from.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Source {
    Level(Level),
    Counter { per_second: f64 },
    Mirror(SignalId),
    Statistic(Statistic),
}

/// One signal: a measurement register or one member of a measurement record.
#[derive(Clone, Debug)]
pub(crate) struct Signal {
    pub(crate) source: Source,
    pub(crate) scalar: Scalar,
    pub(crate) sentinel: Option<u32>,
    /// Hash of the name: sentinel samples and noise differ between signals.
    key: u64,
}

/// Every signal of a device, with the zero offsets and reset times commands set.
#[derive(Clone, Debug)]
pub(crate) struct Signals {
    signals: Vec<Signal>,
    /// The signals of each register (one per record member), `None` for non-measurements.
    by_register: Vec<Option<Vec<SignalId>>>,
    offsets: Vec<i64>,
    resets: Vec<Option<f64>>,
    /// Varies phases, noise and sentinel samples.
    pub(crate) seed: u64,
    /// One sample in this many of a reading with a sentinel is invalid (0: never).
    pub(crate) sentinel_every: u32,
}

/// SplitMix64: a cheap, good 64-bit mix for deterministic pseudo-randomness.
pub(crate) fn mix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

fn hash_name(name: &str) -> u64 {
    name.bytes()
        .fold(0xCBF2_9CE4_8422_2325, |h, b| mix(h ^ u64::from(b)))
}

fn step(scale: Option<Scale>) -> f64 {
    let step = scale.map_or(1.0, |scale| Fixed::new(1, scale).to_f64());
    if step > 0.0 {
        step
    } else {
        1.0
    }
}

fn is_temperature(unit: &str) -> bool {
    matches!(unit, "℃" | "°C" | "degC" | "C")
}

/// A level for a reading with this unit, scale, range and type; `key` varies its phase.
fn level(
    unit: Option<&str>,
    scale: Option<Scale>,
    range: Option<(i64, i64)>,
    scalar: Scalar,
    key: u64,
) -> Level {
    let step = step(scale);
    let (center, amplitude) = if let Some((min, max)) = range {
        let (min, max) = (min as f64, max as f64);
        ((min + max) / 2.0, (max - min) / 20.0)
    } else {
        let (center, amplitude) = match unit {
            Some("mm") if step >= 0.01 => (1500.0, 30.0),
            Some("mm") => (5.0, 0.1),
            Some(unit) if is_temperature(unit) => (35.0, 1.5),
            Some("uV") => (40_000.0, 4_000.0),
            Some("%") => (50.0, 5.0),
            _ => (2_000.0 * step, 300.0 * step),
        };
        (center / step, amplitude / step)
    };
    let (min, max) = scalar.bounds();
    let (min, max) = (min as f64, max as f64);
    let amplitude = amplitude.min((max - min) / 4.0).max(0.0);
    let center = center.clamp(min + amplitude, max - amplitude);
    Level {
        center,
        amplitude,
        period: 20.0 + (key % 2_000) as f64 / 100.0,
        phase: ((key >> 20) % 6_283) as f64 / 1_000.0,
    }
}

fn in_group(group: &GroupInfo, register: &RegisterInfo) -> bool {
    let base = register.member_name().unwrap_or(register.name);
    group
        .registers
        .iter()
        .any(|name| *name == register.name || *name == base)
}

/// Whether `register` is a measurement (see the module docs).
fn is_measurement(device: &DeviceInfo, register: &RegisterInfo) -> bool {
    if register.access != Access::Read || register.name == names::HOST_PORT {
        return false;
    }
    if !matches!(register.kind, ValueKind::Scalar(_) | ValueKind::Record(_)) {
        return false;
    }
    register.unit.is_some()
        || register.scale.is_some()
        || register.sentinel.is_some()
        || register.table == optobus_device::Table::Input
        || device
            .group(names::MEASUREMENTS_GROUP)
            .is_some_and(|group| in_group(group, register))
}

/// The packed `<name>_config` register of a statistic, with its source and kind fields.
fn statistic(device: &DeviceInfo, register: &RegisterInfo) -> Option<Statistic> {
    let config_name = format!("{}{}", register.name, names::CONFIG_SUFFIX);
    let config = device
        .registers
        .iter()
        .position(|r| r.name == config_name)?;
    let ValueKind::Packed(fields) = device.registers.get(config)?.kind else {
        return None;
    };
    let source_field = fields.iter().find(|field| {
        !field.codes.is_empty()
            && field
                .codes
                .iter()
                .all(|code| device.register(code.name).is_some())
    })?;
    let kind_field = fields.iter().find(|field| {
        !field.codes.is_empty()
            && field
                .codes
                .iter()
                .all(|code| StatisticKind::from_code_name(code.name).is_some())
    })?;
    Some(Statistic {
        config,
        source_field,
        kind_field,
    })
}

impl Signals {
    /// The signals of `device`; registers for which `skip` is true (the data buffer's) are
    /// left to their own model.
    pub(crate) fn new(device: &'static DeviceInfo, skip: impl Fn(usize) -> bool) -> Self {
        let mut signals: Vec<Signal> = Vec::new();
        let mut by_register: Vec<Option<Vec<SignalId>>> = vec![None; device.registers.len()];
        // Names of plain measurements, to let others mirror them.
        let mut named: Vec<(&'static str, SignalId)> = Vec::new();
        let mut mirrors: Vec<(SignalId, &'static str)> = Vec::new();
        for (index, register) in device.registers.iter().enumerate() {
            if skip(index) || !is_measurement(device, register) {
                continue;
            }
            let key = hash_name(register.name);
            match register.kind {
                ValueKind::Record(fields) => {
                    let mut ids = Vec::new();
                    for field in fields {
                        let id = signals.len();
                        let key = mix(key ^ hash_name(field.name));
                        signals.push(Signal {
                            source: Source::Level(level(
                                field.unit,
                                field.scale,
                                field.range,
                                field.scalar,
                                key,
                            )),
                            scalar: field.scalar,
                            sentinel: field.sentinel,
                            key,
                        });
                        mirrors.push((id, field.name));
                        ids.push(id);
                    }
                    by_register[index] = Some(ids);
                }
                _ => {
                    let scalar = register.scalar();
                    let source = if let Some(statistic) = statistic(device, register) {
                        Source::Statistic(statistic)
                    } else if register.name.ends_with(names::COUNT_SUFFIX)
                        && register.unit.is_none()
                        && register.scale.is_none()
                    {
                        Source::Counter { per_second: 1000.0 }
                    } else {
                        Source::Level(level(
                            register.unit,
                            register.scale,
                            register.range,
                            scalar,
                            key,
                        ))
                    };
                    let id = signals.len();
                    signals.push(Signal {
                        source,
                        scalar,
                        sentinel: register.sentinel,
                        key,
                    });
                    if matches!(source, Source::Level(_)) {
                        mirrors.push((id, register.name));
                    }
                    named.push((register.name, id));
                    by_register[index] = Some(vec![id]);
                }
            }
        }
        // `sampled_distance_1` follows `distance_1`; a record's `distance` follows `distance`.
        for (id, name) in mirrors {
            let target = named.iter().find(|(other, other_id)| {
                *other_id != id
                    && (name == *other || name.ends_with(&format!("_{other}")))
                    && matches!(signals[*other_id].source, Source::Level(_))
            });
            if let Some((_, target)) = target {
                signals[id].source = Source::Mirror(*target);
            }
        }
        let count = signals.len();
        Self {
            signals,
            by_register,
            offsets: vec![0; count],
            resets: vec![None; count],
            seed: 0,
            sentinel_every: 50,
        }
    }

    /// The signals of register `index`, if it is a measurement.
    pub(crate) fn of_register(&self, index: usize) -> Option<&[SignalId]> {
        self.by_register.get(index)?.as_deref()
    }

    pub(crate) fn get(&self, id: SignalId) -> Option<&Signal> {
        self.signals.get(id)
    }

    /// The level behind `id`, following mirrors (at most a few hops).
    fn root(&self, mut id: SignalId) -> Option<(SignalId, &Signal)> {
        for _ in 0..4 {
            let signal = self.signals.get(id)?;
            match signal.source {
                Source::Mirror(target) => id = target,
                _ => return Some((id, signal)),
            }
        }
        None
    }

    /// The value of `id` at `t` before zero offsets and sentinels.
    fn underlying(&self, id: SignalId, t: f64) -> f64 {
        let Some((root, signal)) = self.root(id) else {
            return 0.0;
        };
        match signal.source {
            Source::Level(level) => {
                let sample = (t / SAMPLE).floor() as u64;
                let noise = (mix(self.seed ^ signal.key ^ mix(sample)) % 2_001) as f64 / 1_000.0;
                // The seed shifts the sine by up to a whole period.
                let shift = (mix(self.seed) % 10_000) as f64 / 10_000.0 * level.period;
                level.at(t + shift) + (noise - 1.0) * level.amplitude / 100.0
            }
            Source::Counter { per_second } => {
                let since = self.resets.get(root).copied().flatten().unwrap_or(0.0);
                (per_second * (t - since).max(0.0)).floor()
            }
            Source::Mirror(_) | Source::Statistic(_) => 0.0,
        }
    }

    fn offset(&self, id: SignalId) -> i64 {
        self.offsets.get(id).copied().unwrap_or(0)
    }

    /// Whether `id` reads as its sentinel at `t`.
    fn is_sentinel_sample(&self, id: SignalId, t: f64) -> bool {
        let (seed, every) = (self.seed, self.sentinel_every);
        let Some(signal) = self.signals.get(id) else {
            return false;
        };
        if every == 0 || signal.sentinel.is_none() {
            return false;
        }
        if matches!(signal.source, Source::Statistic(_) | Source::Counter { .. }) {
            return false;
        }
        let sample = (t / SAMPLE).floor() as u64;
        mix(seed ^ signal.key ^ mix(sample)).is_multiple_of(u64::from(every))
    }

    /// The reading of `id` at `t`, `None` for an invalid (sentinel) sample. `statistic` tells
    /// what a statistic is currently computed over and how.
    pub(crate) fn reading(
        &self,
        id: SignalId,
        t: f64,
        statistic: impl Fn(&Statistic) -> Option<(SignalId, StatisticKind)>,
    ) -> Option<i64> {
        let signal = self.signals.get(id)?;
        if self.is_sentinel_sample(id, t) {
            return None;
        }
        let reset = self.resets.get(id).copied().flatten();
        let value = match signal.source {
            Source::Statistic(config) => {
                let (source, kind) = statistic(&config)?;
                self.statistic(source, kind, reset.unwrap_or(0.0), t)
            }
            Source::Counter { .. } => self.underlying(id, t),
            Source::Level(_) | Source::Mirror(_) => {
                // A reset reading (the P series' sampled data) shows 0 until the next sample.
                if reset.is_some_and(|at| t - at < SAMPLE) {
                    0.0
                } else {
                    self.underlying(id, t) - self.offset(id) as f64
                }
            }
        };
        Some(value.round() as i64)
    }

    /// A statistic of `source`'s reading over `[from, to]`.
    fn statistic(&self, source: SignalId, kind: StatisticKind, from: f64, to: f64) -> f64 {
        let (low, high) = match self.root(source).map(|(_, signal)| signal.source) {
            Some(Source::Level(level)) => {
                let shift = (mix(self.seed) % 10_000) as f64 / 10_000.0 * level.period;
                level.extremes(from.min(to) + shift, to + shift)
            }
            _ => {
                let (a, b) = (self.underlying(source, from), self.underlying(source, to));
                (a.min(b), a.max(b))
            }
        };
        let offset = self.offset(source) as f64;
        match kind {
            StatisticKind::Maximum => high - offset,
            StatisticKind::Minimum => low - offset,
            StatisticKind::PeakToPeak => high - low,
        }
    }

    /// Makes the current reading of `id` its zero.
    pub(crate) fn zero(&mut self, id: SignalId, t: f64) {
        let value = self.underlying(id, t).round() as i64;
        if let Some(offset) = self.offsets.get_mut(id) {
            *offset = value;
        }
    }

    /// Removes the zero offset of `id`.
    pub(crate) fn clear_zero(&mut self, id: SignalId) {
        if let Some(offset) = self.offsets.get_mut(id) {
            *offset = 0;
        }
    }

    /// Restarts `id` (statistic window, counter, sampled value).
    pub(crate) fn reset(&mut self, id: SignalId, t: f64) {
        if let Some(reset) = self.resets.get_mut(id) {
            *reset = Some(t);
        }
    }

    /// Forgets every zero offset and reset (power cycle).
    pub(crate) fn clear_all(&mut self) {
        self.offsets.iter_mut().for_each(|offset| *offset = 0);
        self.resets.iter_mut().for_each(|reset| *reset = None);
    }
}

/// The raw bits a reading is sent as: the sentinel for `None`, else the value clamped to the
/// type and nudged off the sentinel so that a valid reading never looks invalid.
pub(crate) fn raw_reading(signal: &Signal, value: Option<i64>) -> u32 {
    let counter = matches!(signal.source, Source::Counter { .. });
    match value {
        // Counters wrap like the hardware's.
        Some(value) if counter => signal.scalar.to_raw(value),
        _ => raw_value(signal.scalar, signal.sentinel, value),
    }
}

/// `value` as raw bits of `scalar`: clamped, never equal to `sentinel` unless `None`.
pub(crate) fn raw_value(scalar: Scalar, sentinel: Option<u32>, value: Option<i64>) -> u32 {
    let Some(value) = value else {
        return sentinel.unwrap_or(0);
    };
    let (min, max) = scalar.bounds();
    let value = value.clamp(min, max);
    let raw = scalar.to_raw(value);
    if Some(raw) == sentinel {
        let nudged = if value >= max { value - 1 } else { value + 1 };
        return scalar.to_raw(nudged);
    }
    raw
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extremes_find_the_peak_inside_the_window() {
        let level = Level {
            center: 100.0,
            amplitude: 10.0,
            period: 20.0,
            phase: 0.0,
        };
        // sin peaks at t = 5 s and bottoms out at t = 15 s.
        assert_eq!(level.extremes(0.0, 6.0).1, 110.0);
        assert!(level.extremes(0.0, 4.0).1 < 110.0);
        assert_eq!(level.extremes(0.0, 16.0).0, 90.0);
    }

    #[test]
    fn levels_stay_inside_their_type() {
        let level = level(None, None, Some((0, 10)), Scalar::U16, 7);
        assert!(level.center - level.amplitude >= 0.0);
        let distance = super::level(Some("mm"), Scale::ratio(1, 10), None, Scalar::U32, 3);
        assert_eq!(distance.center, 15_000.0);
    }
}
