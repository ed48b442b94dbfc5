//! The phase plan: where each periodic poll of a line starts its ticks, so that colliding
//! deadlines (and so period jitter) stay rare and short.

use std::time::Duration;

use tokio::time::Instant;

use super::{Next, Outcome, Schedule};

/// A periodic poll as the phase plan sees it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PlannedPoll {
    pub(crate) every: Duration,
    pub(crate) took: Duration,
    pub(crate) priority: u8,
    /// A phase the plan must keep (a measurement's group, on the bus's common ticks).
    pub(crate) fixed: Option<Duration>,
}

/// Phases tried per poll at most.
const PHASE_CANDIDATES: u32 = 64;
/// Poll runs simulated per candidate phase at most.
const PLANNED_RUNS: f64 = 2000.0;
/// About how many poll choices a whole plan may simulate (each looks at every poll).
const PLAN_BUDGET: f64 = 2e7;
/// The longest stretch a plan simulates.
const MAX_HORIZON: Duration = Duration::from_secs(24 * 60 * 60);

/// The phase of each poll (its first deadline after the plan starts) that keeps colliding
/// deadlines, and so period jitter, low: polls are placed one at a time, shortest period
/// first, each at the phase (of up to [`PHASE_CANDIDATES`] spread over its period) with the
/// least worst-case, then total, jitter of the polls placed so far, found by running this
/// very schedule on a simulated line where each poll takes its measured time.
///
/// Periods that share no common step make collisions unavoidable (38 ms and 45 ms meet every
/// 1.71 s at every offset); the plan makes them rare and short, where spreading the phases
/// evenly leaves chains of several polls waiting behind each other.
pub(crate) fn plan_phases(polls: &[PlannedPoll]) -> Vec<Duration> {
    if polls.len() < 2 {
        return polls.iter().map(|p| p.fixed.unwrap_or_default()).collect();
    }
    // Fixed phases are placed first: the others find their phases around them.
    let mut order: Vec<usize> = (0..polls.len()).collect();
    order.sort_by_key(|&i| (polls[i].fixed.is_none(), polls[i].every, i));
    let horizon = plan_horizon(polls);
    let mut phases = vec![Duration::ZERO; polls.len()];
    for placed in 0..order.len() {
        let index = order[placed];
        if let Some(fixed) = polls[index].fixed {
            phases[index] = fixed;
            continue;
        }
        let every = polls[index].every;
        let step = (every / PHASE_CANDIDATES).max(Duration::from_millis(1));
        let mut best: Option<((Duration, Duration), Duration)> = None;
        let mut phase = Duration::ZERO;
        while phase < every {
            phases[index] = phase;
            let score = simulated_jitter(polls, &order[..=placed], &phases, horizon);
            if best.is_none_or(|(least, _)| score < least) {
                best = Some((score, phase));
            }
            if score.0.is_zero() {
                break;
            }
            phase += step;
        }
        phases[index] = best.map_or(Duration::ZERO, |(_, phase)| phase);
    }
    phases
}

/// How long a plan simulates: [`PLANNED_RUNS`] runs of the polls, so that periods which meet
/// rarely are seen meeting, fewer when there are so many polls that the plan would take more
/// than some [`PLAN_BUDGET`] steps (a line's task plans between two polls), and at most a day.
fn plan_horizon(polls: &[PlannedPoll]) -> Duration {
    let n = polls.len() as f64;
    let runs = PLANNED_RUNS.min(PLAN_BUDGET / (n * n * f64::from(PHASE_CANDIDATES)));
    let runs_per_second: f64 = polls.iter().map(|p| 1.0 / p.every.as_secs_f64()).sum();
    Duration::try_from_secs_f64(runs / runs_per_second)
        .map_or(MAX_HORIZON, |horizon| horizon.min(MAX_HORIZON))
}

/// The worst and the total of the largest period jitter of polls `placed` at `phases`, run
/// by this schedule for `horizon` with each poll taking its time.
fn simulated_jitter(
    polls: &[PlannedPoll],
    placed: &[usize],
    phases: &[Duration],
    horizon: Duration,
) -> (Duration, Duration) {
    let start = Instant::now();
    let mut schedule = Schedule {
        phased: true,
        ..Schedule::default()
    };
    for &index in placed {
        let device = schedule.add_device(start);
        let poll = &polls[index];
        let added = schedule.add_poll(device, Some(poll.every), poll.priority);
        schedule.polls[added].due = start + phases[index];
    }
    let mut last: Vec<Option<Instant>> = vec![None; placed.len()];
    let mut jitter = vec![Duration::ZERO; placed.len()];
    let mut now = start;
    while now < start + horizon {
        match schedule.next(now) {
            Next::Run(k) => {
                let poll = &polls[placed[k]];
                if let Some(previous) = last[k] {
                    let interval = now.duration_since(previous);
                    jitter[k] = jitter[k].max(interval.abs_diff(poll.every));
                }
                last[k] = Some(now);
                now += poll.took;
                schedule.done(k, now, Outcome::Answered);
            }
            Next::Wait(at) => now = at,
            Next::Idle => break,
        }
    }
    let worst = jitter.iter().copied().max().unwrap_or_default();
    (worst, jitter.iter().sum())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    #[test]
    fn planned_phases_keep_colliding_periods_within_one_transaction_of_jitter() {
        // The jitter bench's polls: periods with no common step, each taking 2 to 7 ms.
        let polls: Vec<PlannedPoll> = [(38, 4), (45, 4), (60, 6), (75, 2), (90, 7), (120, 5)]
            .into_iter()
            .chain([(150, 4), (190, 7)])
            .map(|(every, took)| PlannedPoll {
                every: ms(every),
                took: ms(took),
                priority: 0,
                fixed: None,
            })
            .collect();
        let phases = plan_phases(&polls);
        let all: Vec<usize> = (0..polls.len()).collect();
        let (worst, _) = simulated_jitter(&polls, &all, &phases, Duration::from_secs(60));
        assert!(
            worst <= ms(7),
            "worst jitter {worst:?} at phases {phases:?}"
        );
        // Spread evenly over their periods instead, they wait behind each other in chains.
        let even: Vec<Duration> = polls
            .iter()
            .zip(0u32..)
            .map(|(poll, k)| poll.every / 8 * k)
            .collect();
        let (spread, _) = simulated_jitter(&polls, &all, &even, Duration::from_secs(60));
        assert!(spread > ms(10), "{spread:?}");
    }

    #[test]
    fn a_plan_of_many_polls_is_bounded_and_keeps_each_phase_within_its_period() {
        let polls: Vec<PlannedPoll> = (0..120u64)
            .map(|k| PlannedPoll {
                every: ms(50 + 7 * k),
                took: ms(1 + k % 5),
                priority: 0,
                fixed: None,
            })
            .collect();
        assert!(plan_horizon(&polls) < plan_horizon(&polls[..8]));
        let phases = plan_phases(&polls);
        for (poll, phase) in polls.iter().zip(&phases) {
            assert!(*phase < poll.every, "{phase:?} of {:?}", poll.every);
        }
        assert!(phases.iter().any(|phase| !phase.is_zero()));
    }
}
