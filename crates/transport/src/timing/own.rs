//! A waiter's own timerfd in tokio's reactor, in runtimes known to have their IO driver.

use std::collections::VecDeque;
use std::future::{poll_fn, Future};
use std::io;
use std::os::fd::{AsFd, AsRawFd, RawFd};
use std::pin::pin;
use std::sync::{Mutex, PoisonError};
use std::task::Poll;
use std::time::Duration;

use nix::sys::time::TimeSpec;
use nix::sys::timerfd::{ClockId, Expiration, TimerFd, TimerFlags, TimerSetTimeFlags};
use tokio::io::unix::AsyncFd;
use tokio::io::Interest;
use tokio::runtime::{Handle, Id};
use tokio::time::{sleep_until, Instant};

use super::KERNEL_SPAN;

/// Runtimes where a descriptor of this crate was registered with the reactor, most recent
/// first: they have their IO driver, so a timerfd can be registered there without the panic
/// tokio gives in a runtime without one (which it offers no way to ask about beforehand).
static IO_RUNTIMES: Mutex<VecDeque<Id>> = Mutex::new(VecDeque::new());

/// How many such runtimes are remembered (a process has one or two).
const RUNTIMES_KEPT: usize = 8;

/// Tells the precise waits that the current runtime has its IO driver, so that a
/// [`PreciseTimer`](super::PreciseTimer) may use a timerfd in its reactor (a serial port of
/// this crate tells it when it registers; tokio offers no way to ask, and panics when a
/// descriptor is registered in a runtime without IO). Outside a runtime it does nothing.
pub fn runtime_has_io() {
    let Ok(handle) = Handle::try_current() else {
        return;
    };
    let id = handle.id();
    let mut runtimes = IO_RUNTIMES.lock().unwrap_or_else(PoisonError::into_inner);
    if runtimes.front() != Some(&id) {
        runtimes.retain(|known| *known != id);
        runtimes.push_front(id);
        runtimes.truncate(RUNTIMES_KEPT);
    }
}

/// The current runtime, if it is known to have its IO driver.
fn io_runtime() -> Option<Id> {
    let id = Handle::try_current().ok()?.id();
    let runtimes = IO_RUNTIMES.lock().unwrap_or_else(PoisonError::into_inner);
    runtimes.contains(&id).then_some(id)
}

/// A timerfd as tokio's reactor takes it.
#[derive(Debug)]
struct Timer(TimerFd);

impl AsRawFd for Timer {
    fn as_raw_fd(&self) -> RawFd {
        self.0.as_fd().as_raw_fd()
    }
}

/// The timerfd of one waiter, made at its first wait in a runtime known to have IO.
#[derive(Debug, Default)]
pub(super) struct OwnTimer {
    /// The timerfd and the runtime whose reactor it is registered with.
    timer: Option<(AsyncFd<Timer>, Id)>,
    /// A timerfd failed: the timer thread from now on.
    failed: bool,
}

impl OwnTimer {
    /// Waits until `deadline` (or a little later) on its own timerfd; `false`, without
    /// waiting, where it has none. Under tokio's paused clock the wait ends when the clock
    /// reaches the deadline, as tokio's timer runs beside the timerfd.
    pub(super) async fn sleep_until(&mut self, deadline: Instant) -> bool {
        if self.failed {
            return false;
        }
        let Some(runtime) = io_runtime() else {
            return false;
        };
        if self
            .timer
            .as_ref()
            .is_none_or(|(_, made_in)| *made_in != runtime)
        {
            match register() {
                Ok(timer) => self.timer = Some((timer, runtime)),
                Err(error) => {
                    tracing::debug!(target: "optobus_transport", "no timerfd of its own: {error}");
                    self.failed = true;
                    return false;
                }
            }
        }
        let Some((timer, _)) = &self.timer else {
            return false;
        };
        if deadline.saturating_duration_since(Instant::now()) > KERNEL_SPAN {
            sleep_until(deadline - KERNEL_SPAN).await;
        }
        loop {
            let rest = deadline.saturating_duration_since(Instant::now());
            if rest.is_zero() {
                return true;
            }
            if !clock_paused() {
                // tokio's timer beside it would cost a wake of the driver (an eventfd write
                // and an `epoll_wait`) each time it is set earlier than the driver's next.
                match expire(timer, rest).await {
                    Ok(()) => continue,
                    Err(error) => {
                        tracing::debug!(target: "optobus_transport", "timerfd failed: {error}");
                        self.failed = true;
                        return false;
                    }
                }
            }
            let mut expired = pin!(expire(timer, rest));
            let mut tokio = pin!(sleep_until(deadline));
            let first = poll_fn(|cx| match expired.as_mut().poll(cx) {
                Poll::Ready(result) => Poll::Ready(Some(result)),
                Poll::Pending => tokio.as_mut().poll(cx).map(|()| None),
            })
            .await;
            match first {
                // tokio's timer: the paused clock reached the deadline.
                None => return true,
                // Early wake-ups (a stale expiry) go round again.
                Some(Ok(())) => {}
                Some(Err(error)) => {
                    tracing::debug!(target: "optobus_transport", "timerfd failed: {error}");
                    self.failed = true;
                    return false;
                }
            }
        }
    }
}

/// tokio's test clock is paused: its time is not the system's (ahead of it once advanced,
/// behind it once real time passed). The system clock is read second, so a running clock
/// reads a little ahead of tokio's, never behind.
fn clock_paused() -> bool {
    let tokio = Instant::now().into_std();
    let system = std::time::Instant::now();
    tokio > system || system - tokio > PAUSE_SEEN_AFTER
}

/// How far tokio's clock may fall behind the system's between two reads before it counts as
/// paused (a preempted thread can take that long between them; a paused clock falls behind
/// by real time passing, and a wait under it misses tokio's timer only before that).
const PAUSE_SEEN_AFTER: Duration = Duration::from_millis(50);

/// A new non-blocking timerfd in the current runtime's reactor (which has IO).
fn register() -> io::Result<AsyncFd<Timer>> {
    let timer = TimerFd::new(
        ClockId::CLOCK_MONOTONIC,
        TimerFlags::TFD_NONBLOCK | TimerFlags::TFD_CLOEXEC,
    )?;
    // tokio 1.54 deprecates this constructor for the `unsafe` `register_with_interest` (a
    // type whose `as_raw_fd` could change); ours owns its descriptor for its whole life.
    #[allow(deprecated)]
    AsyncFd::with_interest(Timer(timer), Interest::READABLE)
}

/// Arms `timer` to expire after `rest` and waits until it does (or until a stale expiry of
/// an earlier, dropped wait is seen: the caller checks the clock).
///
/// The expiry is not read: arming the timer again resets its count, and each expiry is a new
/// edge for the reactor's edge-triggered epoll, so clearing tokio's readiness is enough (one
/// system call a wait saved).
async fn expire(timer: &AsyncFd<Timer>, rest: Duration) -> io::Result<()> {
    // A zero expiration would disarm the timer.
    let rest = TimeSpec::from_duration(rest.max(Duration::from_nanos(1)));
    timer
        .get_ref()
        .0
        .set(Expiration::OneShot(rest), TimerSetTimeFlags::empty())?;
    let mut ready = timer.readable().await?;
    ready.clear_ready();
    Ok(())
}
