//! Which poll of a line goes next: pure bookkeeping, no I/O, so every rule is tested on its own.
//!
//! - Periodic polls that are due go first, highest priority first, then earliest deadline.
//!   After a poll its next deadline is one period later; ticks missed while the line was busy
//!   are skipped, never made up in a burst.
//! - Polls "as fast as the line allows" share what is left, least recently served first, so
//!   each gets an equal share of turns.
//! - A device that fails [`OFFLINE_AFTER`] times in a row goes offline: its polls stop, and one
//!   of them probes it after a backoff that starts at [`FIRST_BACKOFF`] and doubles to
//!   [`MAX_BACKOFF`], so a dead device costs at most one timeout per backoff period. A
//!   successful probe brings it back online with its periodic polls starting afresh.
//! - A device is first asked once its power-up wait has passed.

use std::time::Duration;

use tokio::time::Instant;

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
}

#[derive(Debug)]
struct Device {
    health: Health,
    /// Not asked before this (power-up wait, or the next probe while offline).
    not_before: Instant,
    failures: u32,
    backoff: Duration,
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
        });
        self.polls.len() - 1
    }

    /// Asks nothing of `device` before `until` (it is busy after a command).
    pub(crate) fn hold(&mut self, device: usize, until: Instant) {
        let device = &mut self.devices[device];
        device.not_before = device.not_before.max(until);
    }

    /// Spreads the first deadlines of the periodic polls over their periods (the k-th of n
    /// polls starts k/n of its period late), so polls of equal or multiple periods do not all
    /// fall due at the same instants and wait behind each other every time.
    pub(crate) fn stagger(&mut self) {
        let periodic: Vec<usize> = (0..self.polls.len())
            .filter(|&i| self.polls[i].every.is_some())
            .collect();
        let n = u32::try_from(periodic.len()).unwrap_or(u32::MAX).max(1);
        for (k, &index) in periodic.iter().enumerate() {
            let poll = &mut self.polls[index];
            let every = poll.every.unwrap_or_default();
            let k = u32::try_from(k).unwrap_or(u32::MAX);
            poll.due += every / n * k;
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

    /// The first poll of each offline device stands for it as its probe.
    fn is_probe_or_online(&self, index: usize) -> bool {
        let poll = &self.polls[index];
        self.devices[poll.device].health == Health::Online
            || self.polls.iter().position(|p| p.device == poll.device) == Some(index)
    }

    /// What to do at `now`.
    pub(crate) fn next(&self, now: Instant) -> Next {
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
        match (due_periodic, due_fast, earliest) {
            (Some((index, _)), _, _) | (None, Some((index, _)), _) => Next::Run(index),
            (None, None, Some(at)) => Next::Wait(at),
            (None, None, None) => Next::Idle,
        }
    }

    /// Records that poll `index` ended at `now` with `outcome`; gives the device's new health
    /// when it changed.
    pub(crate) fn done(&mut self, index: usize, now: Instant, outcome: Outcome) -> Option<Health> {
        self.turns += 1;
        let device_index = self.polls[index].device;
        let poll = &mut self.polls[index];
        poll.served = self.turns;
        if let Some(every) = poll.every {
            poll.due = next_tick(poll.due, every, now);
        }
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
                for poll in self.polls.iter_mut().filter(|p| p.device == device_index) {
                    poll.due = now;
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
        let _second_dead_poll = schedule.add_poll(dead, Some(ms(50)), 0);
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
    fn periodic_polls_start_spread_over_their_period() {
        let start = Instant::now();
        let mut schedule = Schedule::default();
        let device = schedule.add_device(start);
        let polls: Vec<usize> = (0..4)
            .map(|_| schedule.add_poll(device, Some(ms(100)), 0))
            .collect();
        schedule.stagger();
        for (k, at) in [0, 25, 50, 75].into_iter().enumerate() {
            let due = start + ms(at);
            if at > 0 {
                assert_eq!(schedule.next(due - ms(1)), Next::Wait(due));
            }
            assert_eq!(schedule.next(due), Next::Run(polls[k]));
            schedule.done(polls[k], due, Outcome::Answered);
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
}
