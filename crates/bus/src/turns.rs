//! The network's share of a line: whose turn it is among the queues of work from outside
//! the schedule (the gateway's and one per [`Source`]), and how much of the line's time that
//! work may take.

use std::time::Duration;

use tokio::time::Instant;

use crate::schedule::MAX_BACKOFF;
use crate::source::Source;

/// How many queues of network work a line serves in turns: the gateway's and one per
/// [`Source`].
pub(crate) const QUEUES: usize = 1 + Source::ALL.len();

/// The share of a line's time that work from outside its schedule may take on a line with
/// polls: a request that costs the line long (a slave that does not answer, its timeout and
/// the quiet after it) is paid back to the polls before the next one goes.
pub const NETWORK_SHARE: f64 = 0.5;

/// The most line time such work may save up while nobody asks.
const NETWORK_BURST: Duration = Duration::from_millis(500);

/// Whose turn it is among a line's queues of network work (queue 0 the gateway's, then one per
/// [`Source`] in [`Source::ALL`] order), and how much line time that work may still take.
#[derive(Debug)]
pub(crate) struct Turns {
    /// What each queue may still have served before the next due poll.
    allowance: [usize; QUEUES],
    /// The queue looked at first, so that no queue starves another.
    next: usize,
    /// Line time the work may still take, in seconds (negative: owed to the polls); it grows
    /// by [`NETWORK_SHARE`] of the time that passes, up to [`NETWORK_BURST`].
    credit: f64,
    /// When the credit was last brought up to date.
    at: Instant,
}

impl Default for Turns {
    fn default() -> Self {
        Self {
            allowance: [0; QUEUES],
            next: 0,
            credit: NETWORK_BURST.as_secs_f64(),
            at: Instant::now(),
        }
    }
}

impl Turns {
    /// A poll ran: the gateway's clients that waited through it get a turn each, every source
    /// one.
    pub(crate) fn after_poll(&mut self, gateway_waiting: usize) {
        self.allowance = [1; QUEUES];
        self.allowance[0] = gateway_waiting;
    }

    /// Whether the work has not taken more than its share of the line by `now`.
    pub(crate) fn in_credit(&mut self, now: Instant) -> bool {
        self.credit = (self.credit
            + NETWORK_SHARE * now.saturating_duration_since(self.at).as_secs_f64())
        .min(NETWORK_BURST.as_secs_f64());
        self.at = self.at.max(now);
        self.credit >= 0.0
    }

    /// When the work is back within its share, if it is beyond it now.
    pub(crate) fn back_in_credit(&self) -> Option<Instant> {
        (self.credit < 0.0).then(|| {
            let wait = Duration::try_from_secs_f64(-self.credit / NETWORK_SHARE);
            self.at + wait.map_or(MAX_BACKOFF, |wait| wait.min(MAX_BACKOFF))
        })
    }

    /// Work took `took` of the line.
    pub(crate) fn spent(&mut self, took: Duration) {
        self.credit -= took.as_secs_f64();
    }

    /// The queues to look at for the next work, in turn from the one after the last served:
    /// every queue when no poll is due, else those with a turn left in this round.
    pub(crate) fn queues(&self, poll_due: bool) -> impl Iterator<Item = usize> + '_ {
        (0..QUEUES)
            .map(move |step| (self.next + step) % QUEUES)
            .filter(move |&queue| !poll_due || self.allowance[queue] > 0)
    }

    /// Queue `queue` was served: one turn less, and the next queue is looked at first.
    pub(crate) fn served(&mut self, queue: usize) {
        self.allowance[queue] = self.allowance[queue].saturating_sub(1);
        self.next = (queue + 1) % QUEUES;
    }
}
