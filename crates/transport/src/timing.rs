//! Deadlines that never overflow, and waits finer than tokio's 1 ms timer.

use std::future::{poll_fn, Future};
use std::pin::{pin, Pin};
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::task::Poll;
use std::time::Duration;

use tokio::time::{sleep_until, Instant};

mod kernel;
#[cfg(target_os = "linux")]
mod own;

#[cfg(target_os = "linux")]
pub use own::runtime_has_io;

/// Waits up to this long are left to a kernel timer whole; longer ones sleep on tokio's timer
/// until this long before the deadline (tokio wakes on whole milliseconds, late by up to one
/// tick plus scheduling), so a kernel timer never holds a far deadline.
const KERNEL_SPAN: Duration = Duration::from_millis(20);

/// The spinning wait's stretch: tokio's timer sleeps until this long before the deadline and
/// the rest is spent yielding while watching the clock.
const SPIN_SPAN: Duration = Duration::from_micros(2_000);

/// Waiting that long or longer is waiting forever (about 30 years, as tokio's own far future).
const FOREVER: Duration = Duration::from_secs(86_400 * 365 * 30);

/// `now + wait`, saturating: a huge wait (even `Duration::MAX`) means "wait forever" rather
/// than an overflow.
pub fn deadline_after(wait: Duration) -> Instant {
    let now = Instant::now();
    now.checked_add(wait.min(FOREVER))
        .unwrap_or_else(|| now + Duration::from_secs(86_400))
}

/// `from + wait`, saturating like [`deadline_after`].
pub fn deadline_from(from: Instant, wait: Duration) -> Instant {
    from.checked_add(wait.min(FOREVER))
        .unwrap_or_else(|| from + Duration::from_secs(86_400))
}

/// How [`sleep_until_precise`] waits out the fine part of a wait. Only the benches choose:
/// they compare the ways in one run.
#[doc(hidden)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PreciseWait {
    /// The default: a [`PreciseTimer`]'s own timerfd in tokio's reactor where the runtime is
    /// known to have its IO driver (Linux), else the timer thread.
    OwnTimer,
    /// The process's timer thread, which wakes the waiting task: on Linux it sleeps on a
    /// timerfd that the waiting task arms, elsewhere on a condition variable.
    TimerThread,
    /// The timer thread on a condition variable's timed wait (a futex with a timer slack of
    /// 1 ns on Linux): as `clock_nanosleep`, with a notification for an earlier deadline.
    CondvarThread,
    /// A timerfd per wait, registered with tokio's reactor (Linux; panics in a runtime
    /// without IO enabled; elsewhere the timer thread).
    TimerFd,
    /// Yielding to other tasks while watching the clock for the last 2 ms (the wait before
    /// the timer thread; a core busy the whole time).
    Spin,
}

static PRECISE_WAIT: AtomicU8 = AtomicU8::new(0);

/// Chooses how every [`sleep_until_precise`] of the process waits from now on (benches only).
#[doc(hidden)]
pub fn set_precise_wait(wait: PreciseWait) {
    PRECISE_WAIT.store(wait as u8, Ordering::Relaxed);
}

/// Whether RTU clients sleep through a reply by its device's learned turnaround or await its
/// first byte as it comes (the default).
static SLEEP_THROUGH_REPLIES: AtomicBool = AtomicBool::new(false);

/// Whether RTU clients watch the last stretch of t3.5 on the clock (the default) or leave all
/// of it to the kernel's timer (benches only compare).
static GAP_SPIN: AtomicBool = AtomicBool::new(true);

/// Makes every RTU client of the process (on a timed line) sleep through each reply until it
/// can be whole by its device's turnaround as learned from its last replies, and read it in
/// one go, or (`false`, the default) await its first byte as it comes. Experimental: on a
/// line that hands a reply over a character at a time it takes some 35 % less CPU a
/// transaction (2.3 sleeps of the thread instead of 5.5), but on a loaded machine a timer's
/// late wake-up then costs line time, and the line's share fell (see the bus README, "CPU per
/// transaction"); the benches compare both.
pub fn set_sleep_through_replies(on: bool) {
    SLEEP_THROUGH_REPLIES.store(on, Ordering::Relaxed);
}

pub(crate) fn sleeps_through_replies() -> bool {
    SLEEP_THROUGH_REPLIES.load(Ordering::Relaxed)
}

/// Chooses whether RTU clients watch the end of t3.5 on the clock (benches only).
#[doc(hidden)]
pub fn set_gap_spin(on: bool) {
    GAP_SPIN.store(on, Ordering::Relaxed);
}

pub(crate) fn gap_spins() -> bool {
    GAP_SPIN.load(Ordering::Relaxed)
}

fn precise_wait() -> PreciseWait {
    match PRECISE_WAIT.load(Ordering::Relaxed) {
        1 => PreciseWait::TimerThread,
        2 => PreciseWait::CondvarThread,
        3 => PreciseWait::TimerFd,
        4 => PreciseWait::Spin,
        _ => PreciseWait::OwnTimer,
    }
}

/// Waits until `deadline` and returns at it or a little later, never earlier: a kernel timer
/// of microsecond precision wakes the task, so the thread sleeps meanwhile instead of
/// spinning; the runtime keeps running other tasks. Waits longer than a few milliseconds
/// sleep on tokio's timer first. Cancel-safe: dropping the future drops its timer.
///
/// Under tokio's paused test clock the wait ends when the clock reaches the deadline (which
/// auto-advance does at once when nothing else is running), as `tokio::time::sleep_until`.
pub async fn sleep_until_precise(deadline: Instant) {
    let kernel = match precise_wait() {
        PreciseWait::Spin => return spin_until(deadline).await,
        PreciseWait::OwnTimer | PreciseWait::TimerThread => kernel::Kernel::Thread,
        PreciseWait::CondvarThread => kernel::Kernel::CondvarThread,
        PreciseWait::TimerFd => kernel::Kernel::ReactorFd,
    };
    if deadline.saturating_duration_since(Instant::now()) > KERNEL_SPAN {
        sleep_until(deadline - KERNEL_SPAN).await;
    }
    // tokio's timer beside the kernel's: under a paused clock it is the one that ends the
    // wait; on the real clock it wakes later than the kernel's, if ever.
    loop {
        let rest = deadline.saturating_duration_since(Instant::now());
        if rest.is_zero() {
            return;
        }
        let kernel = pin!(kernel::sleep(rest, kernel));
        let tokio = pin!(sleep_until(deadline));
        if first_of(kernel, tokio).await == Finished::Second {
            return;
        }
    }
}

/// As [`sleep_until_precise`], but the kernel's timer wakes the task `spin` before the
/// deadline and the rest is spent yielding while watching the clock: on time within a few
/// microseconds even where a woken thread waits tens of microseconds for a core, for the price
/// of a core busy for `spin`. For instruments that must keep time more than they must save
/// CPU (the simulator's line emulation, with 50 µs), and for the last 40 µs of the t3.5 an RTU
/// client keeps before each request, where lateness is line time lost.
pub async fn sleep_until_precise_spinning(deadline: Instant, spin: Duration) {
    if let Some(early) = deadline.checked_sub(spin) {
        sleep_until_precise(early).await;
    }
    spin_until(deadline).await;
}

/// A precise wait for one waiter at a time (an RTU client keeps one): on Linux, in a runtime
/// known to have its IO driver (one where a serial port of this crate was registered), a
/// timerfd of its own in tokio's reactor, armed for each wait, so the runtime's thread is
/// woken straight from epoll: one thread wake per wait, against two through the timer thread
/// (its own, then the runtime's). Elsewhere, or if the timerfd fails, the timer thread of
/// [`sleep_until_precise`]. Waits end at their deadline or a little later, never earlier;
/// cancel-safe (a wait dropped before its timer fires leaves a stale expiry that the next
/// wait does not take for its own).
#[derive(Debug, Default)]
pub struct PreciseTimer {
    #[cfg(target_os = "linux")]
    own: own::OwnTimer,
}

impl PreciseTimer {
    /// A timer; its timerfd is made at the first wait that can use it.
    pub fn new() -> Self {
        Self::default()
    }

    /// As [`sleep_until_precise`].
    pub async fn sleep_until(&mut self, deadline: Instant) {
        #[cfg(target_os = "linux")]
        if precise_wait() == PreciseWait::OwnTimer && self.own.sleep_until(deadline).await {
            return;
        }
        sleep_until_precise(deadline).await;
    }

    /// As [`sleep_until_precise_spinning`].
    pub async fn sleep_until_spinning(&mut self, deadline: Instant, spin: Duration) {
        if let Some(early) = deadline.checked_sub(spin) {
            self.sleep_until(early).await;
        }
        spin_until(deadline).await;
    }
}

/// Which of two futures finished first.
#[derive(PartialEq, Eq)]
enum Finished {
    First,
    Second,
}

/// Polls `first`, then `second`, until one finishes.
async fn first_of(
    mut first: Pin<&mut impl Future<Output = ()>>,
    mut second: Pin<&mut impl Future<Output = ()>>,
) -> Finished {
    poll_fn(|cx| {
        if first.as_mut().poll(cx).is_ready() {
            Poll::Ready(Finished::First)
        } else if second.as_mut().poll(cx).is_ready() {
            Poll::Ready(Finished::Second)
        } else {
            Poll::Pending
        }
    })
    .await
}

/// The wait before the kernel's timers: tokio's timer sleeps the coarse part, and the last
/// `SPIN_SPAN` is spent yielding to other tasks while watching the system clock.
async fn spin_until(deadline: Instant) {
    let now = Instant::now();
    if deadline <= now {
        return;
    }
    if deadline - now > SPIN_SPAN {
        sleep_until(deadline - SPIN_SPAN).await;
    }
    // The rest on the system clock, which moves even when tokio's test clock is paused.
    let rest = deadline.saturating_duration_since(Instant::now());
    let until = std::time::Instant::now() + rest;
    while std::time::Instant::now() < until {
        tokio::task::yield_now().await;
    }
    // A paused clock did not move while we spun: let it advance to the deadline.
    if Instant::now() < deadline {
        sleep_until(deadline).await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn huge_waits_saturate() {
        let far = deadline_after(Duration::MAX);
        assert!(far > Instant::now() + Duration::from_secs(86_400 * 365));
        let _ = deadline_from(far, Duration::MAX);
    }

    /// A future that counts how often it is polled.
    struct Counted<F> {
        inner: Pin<Box<F>>,
        polls: u32,
    }

    impl<F: Future<Output = ()>> Future for Counted<F> {
        type Output = u32;

        fn poll(mut self: Pin<&mut Self>, cx: &mut std::task::Context<'_>) -> Poll<u32> {
            self.polls += 1;
            match self.inner.as_mut().poll(cx) {
                Poll::Ready(()) => Poll::Ready(self.polls),
                Poll::Pending => Poll::Pending,
            }
        }
    }

    /// Issue 28, point 9: the wait sleeps in the kernel and is woken once at its deadline; a
    /// spinning wait is polled again and again (thousands of times in 2 ms).
    #[tokio::test]
    async fn precise_waits_without_spinning() {
        for micros in [304u64, 2_000, 4_010, 25_000] {
            let deadline = Instant::now() + Duration::from_micros(micros);
            let polls = Counted {
                inner: Box::pin(sleep_until_precise(deadline)),
                polls: 0,
            }
            .await;
            assert!(Instant::now() >= deadline);
            // Once to arm the timer, once when it fires; after a long wait also once for
            // tokio's coarse timer.
            assert!(polls <= 4, "a wait of {micros} µs was polled {polls} times");
        }
    }

    #[test]
    fn precise_waits_need_no_io_driver() {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_time()
            .build()
            .unwrap();
        runtime.block_on(async {
            let deadline = Instant::now() + Duration::from_micros(500);
            sleep_until_precise(deadline).await;
            assert!(Instant::now() >= deadline);
        });
    }

    #[tokio::test(start_paused = true)]
    async fn under_a_paused_clock_precise_waits_end_at_the_deadline() {
        for wait in [Duration::from_micros(300), Duration::from_secs(3_600)] {
            let deadline = Instant::now() + wait;
            let real = std::time::Instant::now();
            sleep_until_precise(deadline).await;
            assert!(Instant::now() >= deadline);
            // An hour of the paused clock passes without an hour of real time.
            assert!(real.elapsed() < Duration::from_secs(60));
        }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn many_tasks_wait_at_once_and_each_ends_at_its_deadline() {
        let waits: Vec<_> = (0..64u64)
            .map(|i| {
                tokio::spawn(async move {
                    let deadline = Instant::now() + Duration::from_micros(100 + 37 * i);
                    sleep_until_precise(deadline).await;
                    Instant::now() >= deadline
                })
            })
            .collect();
        for wait in waits {
            assert!(wait.await.unwrap());
        }
    }

    #[tokio::test]
    async fn a_cancelled_wait_leaves_the_next_ones_on_time() {
        let far = Instant::now() + Duration::from_millis(15);
        let near = Instant::now() + Duration::from_micros(200);
        let cancelled = tokio::time::timeout_at(far, async {
            sleep_until_precise(far + Duration::from_millis(5)).await;
        });
        // The near wait ends first; the far one is dropped by its timeout, unfinished.
        let (_, ()) = tokio::join!(cancelled, sleep_until_precise(near));
        assert!(Instant::now() >= near);
        let next = Instant::now() + Duration::from_micros(300);
        sleep_until_precise(next).await;
        assert!(Instant::now() >= next);
    }

    #[tokio::test]
    async fn waits_that_spin_their_last_stretch_never_end_early() {
        for micros in [0u64, 30, 86, 304, 4_010] {
            let deadline = Instant::now() + Duration::from_micros(micros);
            sleep_until_precise_spinning(deadline, Duration::from_micros(50)).await;
            assert!(Instant::now() >= deadline);
        }
    }

    #[tokio::test(start_paused = true)]
    async fn under_a_paused_clock_waits_that_spin_end_at_the_deadline() {
        let deadline = Instant::now() + Duration::from_secs(3_600);
        sleep_until_precise_spinning(deadline, Duration::from_micros(50)).await;
        assert!(Instant::now() >= deadline);
    }

    #[tokio::test]
    async fn precise_waits_never_end_early() {
        for micros in [0u64, 150, 300, 1_750, 4_010, 25_000] {
            let deadline = Instant::now() + Duration::from_micros(micros);
            sleep_until_precise(deadline).await;
            assert!(Instant::now() >= deadline);
        }
    }
}
