//! Which poll of a line goes next: pure bookkeeping, no I/O, so every rule is tested on its own.
//!
//! - Periodic polls that are due go first, highest priority first, then earliest deadline.
//!   After a poll its next deadline is one period later; ticks missed while the line was busy
//!   are skipped, never made up in a burst.
//! - Polls "as fast as the line allows" share what is left, least recently served first, so
//!   each gets an equal share of turns.
//! - A device that fails [`OFFLINE_AFTER`] times in a row goes offline: its polls stop, and one
//!   of them probes it after a backoff that starts at [`FIRST_BACKOFF`] and doubles to
//!   [`MAX_BACKOFF`], so a dead device costs at most one attempt per backoff period. A
//!   successful probe brings it back online, its periodic polls resuming at their phases.
//! - A device is first asked once its power-up wait has passed.
//! - The polls that feed one measurement run as a group (`schedule/group.rs`): back to back
//!   when due, on ticks counted from the bus's start, so that its inputs are read together.

mod group;
mod plan;

use std::time::Duration;

use tokio::time::Instant;

pub(crate) use group::measurement_groups;
use group::Group;
use plan::{plan_phases, PlannedPoll};

/// Failures in a row that take a device offline.
pub const OFFLINE_AFTER: u32 = 3;
/// The first wait before probing an offline device.
pub const FIRST_BACKOFF: Duration = Duration::from_secs(1);
/// The longest wait between probes of an offline device.
pub const MAX_BACKOFF: Duration = Duration::from_secs(60);

/// Whether a device is being polled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Health {
    /// Answering (or not yet failed often enough to be given up).
    Online,
    /// Failed [`OFFLINE_AFTER`] times in a row; probed with backoff.
    Offline,
}

/// How a poll ended, as far as the schedule cares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Outcome {
    /// The device answered (values, or an exception: it is alive).
    Answered,
    /// No usable answer (timeout, garbled reply, closed line).
    Failed,
}

#[derive(Debug)]
struct Poll {
    device: usize,
    every: Option<Duration>,
    priority: u8,
    /// Periodic polls: the next deadline.
    due: Instant,
    /// Fast polls: the turn it was last served in.
    served: u64,
    /// How long its last run took.
    took: Option<Duration>,
    /// When its last run started.
    started: Option<Instant>,
    /// The measurement group it runs in, if any (its ticks are the group's then).
    group: Option<usize>,
}

#[derive(Debug)]
struct Device {
    health: Health,
    /// Not asked before this (power-up wait, or the next probe while offline).
    not_before: Instant,
    failures: u32,
    backoff: Duration,
}

impl Poll {
    /// A periodic poll whose last run started late (its next tick at hand) waits for the tick
    /// after: two runs less than half a period apart would be a burst.
    fn keep_apart(&mut self) {
        if let (Some(every), Some(started)) = (self.every, self.started) {
            if self.due < started + every / 2 {
                self.due += every;
            }
        }
    }
}

/// What the line should do next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Next {
    /// Run poll `index` now.
    Run(usize),
    /// Nothing is due before this instant.
    Wait(Instant),
    /// There is nothing to poll.
    Idle,
}

/// The polls of one line and the health of its devices.
#[derive(Debug, Default)]
pub(crate) struct Schedule {
    polls: Vec<Poll>,
    devices: Vec<Device>,
    turns: u64,
    /// Whether the periodic polls run at their planned phases yet.
    phased: bool,
    /// The measurement groups of the line.
    groups: Vec<Group>,
    /// The polls of the group being run that are still to go, in order: nothing else takes
    /// the line before them.
    cycle: Vec<usize>,
}

impl Schedule {
    /// Adds a device, first asked at `start`; gives its index.
    pub(crate) fn add_device(&mut self, start: Instant) -> usize {
        self.devices.push(Device {
            health: Health::Online,
            not_before: start,
            failures: 0,
            backoff: FIRST_BACKOFF,
        });
        self.devices.len() - 1
    }

    /// Adds a poll of `device`, periodic with `every` (first due at the device's start) or as
    /// fast as the line allows; gives its index.
    pub(crate) fn add_poll(
        &mut self,
        device: usize,
        every: Option<Duration>,
        priority: u8,
    ) -> usize {
        let due = self.devices[device].not_before;
        self.polls.push(Poll {
            device,
            every,
            priority,
            due,
            served: 0,
            took: None,
            started: None,
            group: None,
        });
        self.polls.len() - 1
    }

    /// Makes `members` (periodic polls of this line, in the order they run) the group of a
    /// measurement: due every `every` from `origin` (the bus's start, shared by every line),
    /// and run back to back.
    pub(crate) fn add_group(&mut self, members: Vec<usize>, every: Duration, origin: Instant) {
        let index = self.groups.len();
        let mut priority = 0;
        for &member in &members {
            let poll = &mut self.polls[member];
            poll.every = Some(every);
            poll.group = Some(index);
            priority = priority.max(poll.priority);
        }
        self.groups.push(Group {
            members,
            every,
            priority,
            due: origin,
            started: None,
            failed: false,
        });
    }

    /// Whether a group is being run: its next poll goes before anything else.
    pub(crate) fn mid_group(&self) -> bool {
        !self.cycle.is_empty()
    }

    /// Whether poll `index`'s device may be asked at `now` (online, not held).
    fn runnable(&self, index: usize, now: Instant) -> bool {
        let device = &self.devices[self.polls[index].device];
        device.health == Health::Online && device.not_before <= now
    }

    /// When group `group` may run: its tick, or later while its online devices are held;
    /// `None` while none of its devices is online (their probes stand for it then).
    fn group_ready(&self, group: &Group) -> Option<Instant> {
        let held = group
            .members
            .iter()
            .map(|&m| &self.devices[self.polls[m].device])
            .filter(|d| d.health == Health::Online)
            .map(|d| d.not_before)
            .min()?;
        Some(group.due.max(held))
    }

    /// Asks nothing of `device` before `until` (it is busy after a command).
    pub(crate) fn hold(&mut self, device: usize, until: Instant) {
        let device = &mut self.devices[device];
        device.not_before = device.not_before.max(until);
    }

    /// Records how long a run of poll `index` took, for the phase plan.
    pub(crate) fn measured(&mut self, index: usize, started: Instant, took: Duration) {
        let poll = &mut self.polls[index];
        poll.took = Some(took);
        poll.started = Some(started);
    }

    /// Once every periodic poll of a device online has run (and so been timed), moves their
    /// next deadlines to the phases [`plan_phases`] finds, from `now` on.
    fn plan_once_timed(&mut self, now: Instant) {
        let online = |poll: &Poll| self.devices[poll.device].health == Health::Online;
        let periodic: Vec<usize> = (0..self.polls.len())
            .filter(|&i| {
                let poll = &self.polls[i];
                poll.every.is_some() && poll.group.is_none() && online(poll)
            })
            .collect();
        let mut timed: Vec<PlannedPoll> = periodic
            .iter()
            .filter_map(|&i| {
                let poll = &self.polls[i];
                Some(PlannedPoll {
                    every: poll.every?,
                    took: poll.took?,
                    priority: poll.priority,
                    fixed: None,
                })
            })
            .collect();
        if timed.len() < periodic.len() {
            return;
        }
        // The groups keep their ticks; the other polls are placed around them, each group
        // taking the time of its polls together.
        for group in &self.groups {
            let mut took = Duration::ZERO;
            for &member in &group.members {
                match self.polls[member].took {
                    Some(time) => took += time,
                    None if online(&self.polls[member]) => return,
                    None => {}
                }
            }
            let phase = group.due.saturating_duration_since(now);
            timed.push(PlannedPoll {
                every: group.every,
                took,
                priority: group.priority,
                fixed: Some(Duration::from_nanos(
                    (phase.as_nanos() % group.every.as_nanos().max(1)) as u64,
                )),
            });
        }
        self.phased = true;
        for (&index, phase) in periodic.iter().zip(plan_phases(&timed)) {
            let poll = &mut self.polls[index];
            poll.due = now + phase;
            poll.keep_apart();
        }
    }

    /// The device a poll belongs to.
    pub(crate) fn device_of(&self, poll: usize) -> usize {
        self.polls[poll].device
    }

    /// A device's health.
    #[cfg(test)]
    pub(crate) fn health(&self, device: usize) -> Health {
        self.devices[device].health
    }

    /// When the poll may run next: its deadline, or its device's start or next probe.
    fn ready_at(&self, poll: &Poll) -> Instant {
        let device = &self.devices[poll.device];
        match (device.health, poll.every) {
            (Health::Offline, _) => device.not_before,
            (Health::Online, Some(_)) => poll.due.max(device.not_before),
            (Health::Online, None) => device.not_before,
        }
    }

    /// The first poll of each offline device stands for it as its probe; an online device's
    /// polls in a group run with their group.
    fn is_probe_or_online(&self, index: usize) -> bool {
        let poll = &self.polls[index];
        match self.devices[poll.device].health {
            Health::Online => poll.group.is_none(),
            Health::Offline => {
                self.polls.iter().position(|p| p.device == poll.device) == Some(index)
            }
        }
    }

    /// What to do at `now`.
    pub(crate) fn next(&self, now: Instant) -> Next {
        if let Some(&member) = self.cycle.first() {
            return Next::Run(member);
        }
        let candidates = (0..self.polls.len()).filter(|&i| self.is_probe_or_online(i));
        let mut due_periodic: Option<(usize, (u8, Instant))> = None;
        let mut due_fast: Option<(usize, (u8, u64))> = None;
        let mut earliest: Option<Instant> = None;
        for index in candidates {
            let poll = &self.polls[index];
            let ready = self.ready_at(poll);
            if ready > now {
                earliest = Some(earliest.map_or(ready, |e| e.min(ready)));
                continue;
            }
            let probing = self.devices[poll.device].health == Health::Offline;
            if poll.every.is_some() || probing {
                let key = (u8::MAX - poll.priority, ready);
                if due_periodic.is_none_or(|(_, best)| key < best) {
                    due_periodic = Some((index, key));
                }
            } else {
                let key = (u8::MAX - poll.priority, poll.served);
                if due_fast.is_none_or(|(_, best)| key < best) {
                    due_fast = Some((index, key));
                }
            }
        }
        for group in &self.groups {
            let Some(ready) = self.group_ready(group) else {
                continue;
            };
            if ready > now {
                earliest = Some(earliest.map_or(ready, |e| e.min(ready)));
                continue;
            }
            let Some(&first) = group.members.iter().find(|&&m| self.runnable(m, now)) else {
                continue;
            };
            // On a tie the group goes first: it keeps the bus's common ticks, the others
            // have phases to move to.
            let key = (u8::MAX - group.priority, ready);
            if due_periodic.is_none_or(|(_, best)| key <= best) {
                due_periodic = Some((first, key));
            }
        }
        match (due_periodic, due_fast, earliest) {
            (Some((index, _)), _, _) | (None, Some((index, _)), _) => Next::Run(index),
            (None, None, Some(at)) => Next::Wait(at),
            (None, None, None) => Next::Idle,
        }
    }

    /// The line's port closed at `now`: every online device goes offline at once, to be probed
    /// as soon as the line opens again. Gives the devices that went down.
    pub(crate) fn line_down(&mut self, now: Instant) -> Vec<usize> {
        let mut down = Vec::new();
        for (index, device) in self.devices.iter_mut().enumerate() {
            if device.health == Health::Online {
                *device = Device {
                    health: Health::Offline,
                    not_before: device.not_before.max(now),
                    failures: OFFLINE_AFTER,
                    backoff: FIRST_BACKOFF,
                };
                down.push(index);
            }
        }
        // A group cut short: it runs again on its next tick once the line is back.
        self.cycle.clear();
        down
    }

    /// Records that poll `index` ended at `now` with `outcome`; gives the device's new health
    /// when it changed.
    pub(crate) fn done(&mut self, index: usize, now: Instant, outcome: Outcome) -> Option<Health> {
        let device_index = self.polls[index].device;
        let probing = self.devices[device_index].health == Health::Offline;
        let change = self.health_after(index, now, outcome);
        self.turns += 1;
        let poll = &mut self.polls[index];
        poll.served = self.turns;
        match (poll.group, poll.every) {
            // A probe of an offline device is no run of its group.
            (Some(group), _) if !probing => self.member_done(group, index, now, outcome),
            (Some(_), _) => {}
            (None, Some(every)) => {
                poll.due = next_tick(poll.due, every, now);
                poll.keep_apart();
            }
            (None, None) => {}
        }
        if !self.phased {
            self.plan_once_timed(now);
        }
        change
    }

    /// Poll `index` of group `group` ran: the group's other polls that may be asked go next,
    /// and once none is left the group waits for its next tick.
    fn member_done(&mut self, group: usize, index: usize, now: Instant, outcome: Outcome) {
        if self.cycle.is_empty() {
            let members = self.groups[group].members.clone();
            self.cycle = members.into_iter().filter(|&m| m != index).collect();
            let started = self.polls[index].started.unwrap_or(now);
            self.groups[group].started = Some(started);
        } else {
            self.cycle.retain(|&m| m != index);
        }
        self.groups[group].failed |= outcome == Outcome::Failed;
        // An offline or busy device's poll is left out of this run: it costs the others
        // nothing.
        let cycle = std::mem::take(&mut self.cycle);
        self.cycle = cycle
            .into_iter()
            .filter(|&m| self.runnable(m, now))
            .collect();
        if self.cycle.is_empty() {
            self.groups[group].advance(now);
        }
    }

    /// The device of poll `index` after a run that ended with `outcome`: its new health when
    /// it changed.
    fn health_after(&mut self, index: usize, now: Instant, outcome: Outcome) -> Option<Health> {
        let device_index = self.polls[index].device;
        let device = &mut self.devices[device_index];
        match (outcome, device.health) {
            (Outcome::Answered, Health::Online) => {
                device.failures = 0;
                None
            }
            (Outcome::Answered, Health::Offline) => {
                *device = Device {
                    health: Health::Online,
                    not_before: now,
                    failures: 0,
                    backoff: FIRST_BACKOFF,
                };
                // Its periodic polls resume at their planned phases, clear of the others.
                for poll in self.polls.iter_mut().filter(|p| p.device == device_index) {
                    if let Some(every) = poll.every {
                        poll.due = next_tick(poll.due, every, now);
                    }
                }
                Some(Health::Online)
            }
            (Outcome::Failed, Health::Online) => {
                device.failures += 1;
                if device.failures < OFFLINE_AFTER {
                    return None;
                }
                device.health = Health::Offline;
                device.backoff = FIRST_BACKOFF;
                device.not_before = now + device.backoff;
                Some(Health::Offline)
            }
            (Outcome::Failed, Health::Offline) => {
                device.backoff = (device.backoff * 2).min(MAX_BACKOFF);
                device.not_before = now + device.backoff;
                None
            }
        }
    }
}

/// The first tick of a schedule (`due`, every `every`) after `now`: ticks already missed are
/// skipped.
fn next_tick(due: Instant, every: Duration, now: Instant) -> Instant {
    let next = due + every;
    if next > now {
        return next;
    }
    let behind = now.duration_since(next);
    let every_ns = every.as_nanos().max(1);
    let skipped = behind.as_nanos() / every_ns + 1;
    // Bounded by the 24 h period limit and the time elapsed, so this fits comfortably.
    let skip = u32::try_from(skipped).unwrap_or(u32::MAX);
    next + every.saturating_mul(skip)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    #[test]
    fn a_due_periodic_poll_goes_before_fast_polls() {
        let start = Instant::now();
        let mut schedule = Schedule::default();
        let device = schedule.add_device(start);
        let fast = schedule.add_poll(device, None, 0);
        let periodic = schedule.add_poll(device, Some(ms(100)), 0);
        assert_eq!(schedule.next(start), Next::Run(periodic));
        schedule.done(periodic, start + ms(5), Outcome::Answered);
        assert_eq!(schedule.next(start + ms(5)), Next::Run(fast));
        assert_eq!(schedule.next(start + ms(100)), Next::Run(periodic));
    }

    #[test]
    fn fast_polls_take_turns() {
        let start = Instant::now();
        let mut schedule = Schedule::default();
        let polls: Vec<usize> = (0..3)
            .map(|_| {
                let device = schedule.add_device(start);
                schedule.add_poll(device, None, 0)
            })
            .collect();
        let mut order = Vec::new();
        let mut now = start;
        for _ in 0..6 {
            let Next::Run(poll) = schedule.next(now) else {
                panic!("a fast poll is always due")
            };
            order.push(poll);
            now += ms(1);
            schedule.done(poll, now, Outcome::Answered);
        }
        assert_eq!(order, [polls.clone(), polls].concat());
    }

    #[test]
    fn missed_ticks_are_skipped_not_burst() {
        let start = Instant::now();
        let mut schedule = Schedule::default();
        let device = schedule.add_device(start);
        let poll = schedule.add_poll(device, Some(ms(10)), 0);
        assert_eq!(schedule.next(start), Next::Run(poll));
        // The poll took 35 ms (a stall): ticks at 10, 20 and 30 ms are gone.
        schedule.done(poll, start + ms(35), Outcome::Answered);
        assert_eq!(schedule.next(start + ms(35)), Next::Wait(start + ms(40)));
    }

    #[test]
    fn a_poll_that_started_late_does_not_run_again_at_once() {
        let start = Instant::now();
        let mut schedule = Schedule::default();
        let device = schedule.add_device(start);
        let poll = schedule.add_poll(device, Some(ms(10)), 0);
        // Its first run (at 0, 1 ms) sets its phase: ticks at 11, 21, 31 ms …
        assert_eq!(schedule.next(start), Next::Run(poll));
        schedule.measured(poll, start, ms(1));
        schedule.done(poll, start + ms(1), Outcome::Answered);
        assert_eq!(schedule.next(start + ms(1)), Next::Wait(start + ms(11)));
        // Due at 11 ms, it started at 20.9 ms (the line was busy) and took 50 µs: its tick at
        // 21 ms would follow 0.1 ms after it, so the one at 31 ms is taken.
        let started = start + Duration::from_micros(20_900);
        schedule.measured(poll, started, Duration::from_micros(50));
        schedule.done(poll, started + Duration::from_micros(50), Outcome::Answered);
        assert_eq!(schedule.next(start + ms(21)), Next::Wait(start + ms(31)));
        // Started 3 ms late, its next tick (7 ms later) stays.
        let started = start + ms(34);
        schedule.measured(poll, started, ms(1));
        schedule.done(poll, started + ms(1), Outcome::Answered);
        assert_eq!(schedule.next(start + ms(35)), Next::Wait(start + ms(41)));
    }

    #[test]
    fn higher_priority_goes_first_among_due_polls() {
        let start = Instant::now();
        let mut schedule = Schedule::default();
        let device = schedule.add_device(start);
        let low = schedule.add_poll(device, Some(ms(10)), 0);
        let high = schedule.add_poll(device, Some(ms(10)), 5);
        assert_eq!(schedule.next(start), Next::Run(high));
        schedule.done(high, start, Outcome::Answered);
        assert_eq!(schedule.next(start), Next::Run(low));
    }

    #[test]
    fn a_device_that_keeps_failing_goes_offline_and_is_probed_with_backoff() {
        let start = Instant::now();
        let mut schedule = Schedule::default();
        let dead = schedule.add_device(start);
        let dead_poll = schedule.add_poll(dead, None, 0);
        let periodic_dead_poll = schedule.add_poll(dead, Some(ms(50)), 0);
        let alive = schedule.add_device(start);
        let alive_poll = schedule.add_poll(alive, None, 0);
        let mut now = start;
        for attempt in 1..=OFFLINE_AFTER {
            let change = schedule.done(dead_poll, now, Outcome::Failed);
            assert_eq!(change.is_some(), attempt == OFFLINE_AFTER);
        }
        assert_eq!(schedule.health(dead), Health::Offline);
        // Until the probe is due only the live device is polled.
        now += ms(1);
        assert_eq!(schedule.next(now), Next::Run(alive_poll));
        let mut probes = Vec::new();
        let mut backoff = FIRST_BACKOFF;
        let mut probe_due = start + FIRST_BACKOFF;
        while backoff < MAX_BACKOFF * 2 && probes.len() < 10 {
            assert_eq!(schedule.next(probe_due - ms(1)), Next::Run(alive_poll));
            assert_eq!(
                schedule.next(probe_due),
                Next::Run(dead_poll),
                "probe at {backoff:?}"
            );
            schedule.done(dead_poll, probe_due, Outcome::Failed);
            probes.push(backoff);
            backoff = (backoff * 2).min(MAX_BACKOFF);
            probe_due += backoff;
        }
        assert_eq!(
            probes[..4],
            [
                FIRST_BACKOFF,
                FIRST_BACKOFF * 2,
                FIRST_BACKOFF * 4,
                FIRST_BACKOFF * 8
            ]
        );
        assert_eq!(*probes.last().unwrap(), MAX_BACKOFF);
        // The device answers its next probe: online again, both polls due at once.
        assert_eq!(
            schedule.done(dead_poll, probe_due, Outcome::Answered),
            Some(Health::Online)
        );
        assert_eq!(schedule.health(dead), Health::Online);
        // Its periodic poll resumes on its own ticks (every 50 ms from the start).
        let resumed = probe_due + ms(50);
        assert_ne!(
            schedule.next(resumed - ms(1)),
            Next::Run(periodic_dead_poll)
        );
        assert_eq!(schedule.next(resumed), Next::Run(periodic_dead_poll));
    }

    #[test]
    fn nothing_is_asked_before_the_power_up_wait() {
        let start = Instant::now();
        let mut schedule = Schedule::default();
        let device = schedule.add_device(start + ms(500));
        let poll = schedule.add_poll(device, None, 0);
        assert_eq!(schedule.next(start), Next::Wait(start + ms(500)));
        assert_eq!(schedule.next(start + ms(500)), Next::Run(poll));
    }

    #[test]
    fn periodic_polls_move_to_planned_phases_once_each_has_been_timed() {
        let start = Instant::now();
        let mut schedule = Schedule::default();
        let device = schedule.add_device(start);
        let polls: Vec<usize> = (0..4)
            .map(|_| schedule.add_poll(device, Some(ms(100)), 0))
            .collect();
        // The first round runs at once, back to back, and times each poll (10 ms).
        let mut now = start;
        for &poll in &polls {
            assert_eq!(schedule.next(now), Next::Run(poll));
            schedule.measured(poll, now, ms(10));
            now += ms(10);
            schedule.done(poll, now, Outcome::Answered);
        }
        // Then each runs at its own phase: never two due at once, none waiting for another.
        let mut starts = Vec::new();
        while starts.len() < 12 {
            match schedule.next(now) {
                Next::Run(poll) => {
                    starts.push((poll, now));
                    now += ms(10);
                    schedule.done(poll, now, Outcome::Answered);
                }
                Next::Wait(at) => now = at,
                Next::Idle => unreachable!("periodic polls"),
            }
        }
        for pair in starts.windows(2) {
            assert!(pair[1].1 >= pair[0].1 + ms(10), "{starts:?}");
        }
        for &poll in &polls {
            let mine: Vec<Instant> = starts
                .iter()
                .filter(|(p, _)| *p == poll)
                .map(|&(_, at)| at)
                .collect();
            for pair in mine.windows(2) {
                assert_eq!(pair[1] - pair[0], ms(100), "poll {poll}: {starts:?}");
            }
        }
    }

    #[test]
    fn a_line_without_polls_is_idle() {
        let mut schedule = Schedule::default();
        schedule.add_device(Instant::now());
        assert_eq!(schedule.next(Instant::now()), Next::Idle);
    }

    #[test]
    fn a_tick_far_behind_lands_on_the_next_tick_after_now() {
        let start = Instant::now();
        let next = next_tick(start, ms(7), start + ms(1000));
        assert!(next > start + ms(1000) && next <= start + ms(1007));
        assert_eq!(next.duration_since(start).as_millis() % 7, 0);
    }

    #[test]
    fn a_due_group_runs_back_to_back_before_any_other_due_poll() {
        let start = Instant::now();
        let mut schedule = Schedule::default();
        let devices: Vec<usize> = (0..3).map(|_| schedule.add_device(start)).collect();
        let top = schedule.add_poll(devices[0], Some(ms(20)), 0);
        let other = schedule.add_poll(devices[1], Some(ms(20)), 9);
        let fast = schedule.add_poll(devices[1], None, 0);
        let bottom = schedule.add_poll(devices[2], Some(ms(50)), 0);
        schedule.add_group(vec![top, bottom], ms(20), start);
        let mut now = start + ms(20);
        // `other` has the higher priority: it goes first, then the group whole.
        let mut order = Vec::new();
        for _ in 0..3 {
            let Next::Run(poll) = schedule.next(now) else {
                panic!("polls are due")
            };
            assert_eq!(schedule.mid_group(), poll == bottom, "{order:?}");
            order.push(poll);
            now += ms(1);
            schedule.done(poll, now, Outcome::Answered);
        }
        assert_eq!(order, [other, top, bottom]);
        assert!(!schedule.mid_group());
        assert_eq!(schedule.next(now), Next::Run(fast));
        schedule.done(fast, now, Outcome::Answered);
        // The group's next tick is on the grid from its origin, at the fastest period.
        assert_eq!(schedule.next(start + ms(39)), Next::Run(fast));
        assert_eq!(schedule.next(start + ms(40)), Next::Run(other));
        schedule.done(other, start + ms(41), Outcome::Answered);
        assert_eq!(schedule.next(start + ms(41)), Next::Run(top));
    }

    #[test]
    fn an_offline_member_is_left_out_of_its_groups_run_and_probed_alone() {
        let start = Instant::now();
        let mut schedule = Schedule::default();
        let dead = schedule.add_device(start);
        let alive = schedule.add_device(start);
        let top = schedule.add_poll(dead, Some(ms(20)), 0);
        let bottom = schedule.add_poll(alive, Some(ms(20)), 0);
        schedule.add_group(vec![top, bottom], ms(20), start);
        let mut now = start;
        let mut failed_at = start;
        let mut runs = Vec::new();
        for _ in 0..OFFLINE_AFTER {
            if let Next::Wait(at) = schedule.next(now) {
                now = at;
            }
            runs.push(now);
            assert_eq!(schedule.next(now), Next::Run(top));
            failed_at = now + ms(100);
            schedule.done(top, failed_at, Outcome::Failed);
            assert_eq!(schedule.next(failed_at), Next::Run(bottom));
            now = failed_at + ms(1);
            schedule.done(bottom, now, Outcome::Answered);
        }
        assert_eq!(schedule.health(dead), Health::Offline);
        // Each run took top's timeout: the next started on the first tick after it.
        assert_eq!(runs, [start, start + ms(120), start + ms(240)]);
        // The group's run is bottom alone, on its ticks, until top's probe is due.
        assert_eq!(schedule.next(now), Next::Wait(start + ms(360)));
        let tick = start + ms(360);
        assert_eq!(schedule.next(tick), Next::Run(bottom));
        schedule.done(bottom, tick + ms(1), Outcome::Answered);
        assert!(!schedule.mid_group());
        let probe = failed_at + FIRST_BACKOFF;
        assert_eq!(
            schedule.next(probe),
            Next::Run(bottom),
            "its overdue tick first"
        );
        schedule.done(bottom, probe, Outcome::Answered);
        assert_eq!(schedule.next(probe), Next::Run(top));
        schedule.done(top, probe + ms(100), Outcome::Failed);
        assert!(!schedule.mid_group(), "a probe is no run of the group");
    }

    #[test]
    fn a_group_run_stalled_past_its_next_tick_keeps_that_tick_unless_it_failed() {
        let start = Instant::now();
        let mut schedule = Schedule::default();
        let devices: Vec<usize> = (0..2).map(|_| schedule.add_device(start)).collect();
        let top = schedule.add_poll(devices[0], Some(ms(20)), 0);
        let bottom = schedule.add_poll(devices[1], Some(ms(20)), 0);
        schedule.add_group(vec![top, bottom], ms(20), start);
        // Started on its tick, stalled (the machine) until after the next one: that tick is
        // run late, not skipped, as on the other lines whose runs started at the same instant.
        assert_eq!(schedule.next(start), Next::Run(top));
        schedule.measured(top, start, ms(24));
        schedule.done(top, start + ms(24), Outcome::Answered);
        schedule.measured(bottom, start + ms(24), ms(1));
        schedule.done(bottom, start + ms(25), Outcome::Answered);
        assert_eq!(schedule.next(start + ms(25)), Next::Run(top));
        // A run with a timeout waits for the first tick after it ended.
        schedule.measured(top, start + ms(25), ms(20));
        schedule.done(top, start + ms(45), Outcome::Failed);
        schedule.measured(bottom, start + ms(45), ms(2));
        schedule.done(bottom, start + ms(47), Outcome::Answered);
        assert_eq!(schedule.next(start + ms(47)), Next::Wait(start + ms(60)));
    }
}
