//! The polls that feed one measurement, run as a group so that its inputs are read together.
//!
//! - On one line the group's polls run back to back when it is due: no other poll and no
//!   network work takes the line between them, so a measurement's inputs are apart by the
//!   transactions before the last one only.
//! - The group ticks every period of its fastest poll from the bus's start, on every line it
//!   has polls on: its polls on two lines start on the same instants, so the skew between
//!   them is the two lines' transactions, not their phase difference.
//! - A poll of a device offline (probed with backoff) or busy is left out of the group's run:
//!   the other polls go on without it.

use std::collections::BTreeSet;
use std::time::Duration;

use tokio::time::Instant;

use crate::file::BusFile;

/// A measurement group on one line.
#[derive(Debug)]
pub(crate) struct Group {
    /// Its polls (indices of the line's polls), in the order they run.
    pub(crate) members: Vec<usize>,
    pub(crate) every: Duration,
    /// The highest priority of its polls.
    pub(crate) priority: u8,
    /// Its next tick (the bus's start plus a whole number of periods).
    pub(crate) due: Instant,
    /// When its last run started.
    pub(crate) started: Option<Instant>,
    /// Whether a poll of its last run failed.
    pub(crate) failed: bool,
}

impl Group {
    /// Its run ended at `now`: its next tick is the first more than half a period after the
    /// run started (closer would be a burst), decided by the start alone, so that its runs on
    /// other lines, which started at the same instant, decide alike even when the machine
    /// stalled them into their next tick (which then runs late rather than being skipped on
    /// one line only). A run with a failed poll (a timeout) waits for the first tick after it
    /// ended, as a poll does: a dead device is not asked again at once. Ticks stay on the
    /// bus's common grid either way.
    pub(crate) fn advance(&mut self, now: Instant) {
        let after = match (self.started, self.failed) {
            (Some(started), false) => started + self.every / 2,
            _ => now,
        };
        self.due = super::next_tick(self.due, self.every, after);
        self.failed = false;
        if let Some(started) = self.started {
            if self.due < started + self.every / 2 {
                self.due += self.every;
            }
        }
    }
}

/// A measurement group of the bus file: its polls as (device index in the file, poll index in
/// the device), in file order, and its period.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct GroupPlan {
    pub(crate) polls: Vec<(usize, usize)>,
    pub(crate) every: Duration,
}

/// The groups of `file`'s measurements: for each measurement the periodic polls that read its
/// inputs (the fastest such poll of each input); measurements sharing a poll share a group.
/// An input read by no periodic poll (polled `fastest`) is read as fast as the line allows,
/// in no group. A group of fewer than two polls is no group.
pub(crate) fn measurement_groups(file: &BusFile) -> Vec<GroupPlan> {
    let plan = &file.measurements.plan;
    let mut sets: Vec<BTreeSet<(usize, usize)>> = Vec::new();
    for formula in &plan.formulas {
        let mut set = BTreeSet::new();
        for &input in &formula.inputs {
            let input = &plan.inputs[input];
            let Some(device) = file.devices.iter().position(|d| d.name == input.device) else {
                continue;
            };
            let fastest = file.devices[device]
                .polls
                .iter()
                .enumerate()
                .filter(|(_, poll)| poll.registers.iter().any(|r| r.name == input.register))
                .filter_map(|(index, poll)| Some((poll.every?, index)))
                .min();
            if let Some((_, poll)) = fastest {
                set.insert((device, poll));
            }
        }
        // Measurements that share a poll are read together too: their sets merge.
        let mut merged = set;
        loop {
            let before = merged.len();
            sets.retain(|other| {
                if other.is_disjoint(&merged) {
                    return true;
                }
                merged.extend(other.iter().copied());
                false
            });
            if merged.len() == before {
                break;
            }
        }
        sets.push(merged);
    }
    sets.into_iter()
        .filter(|set| set.len() >= 2)
        .filter_map(|set| {
            let polls: Vec<(usize, usize)> = set.into_iter().collect();
            let every = polls
                .iter()
                .filter_map(|&(device, poll)| file.devices[device].polls[poll].every)
                .min()?;
            Some(GroupPlan { polls, every })
        })
        .collect()
}
