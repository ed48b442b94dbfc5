//! The kernel's timers for the fine part of a precise wait: one thread per process that sleeps
//! until the earliest deadline asked for and wakes its task (on a timerfd on Linux, on a
//! condition variable elsewhere), or (Linux, benches only) a timerfd per wait in tokio's
//! reactor.

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::sync::{Condvar, Mutex, MutexGuard, OnceLock, PoisonError};
use std::time::{Duration, Instant};

use tokio::sync::oneshot;

/// The kernel timer a precise wait sleeps on.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Kernel {
    /// The timer thread; on Linux it sleeps on a timerfd that waiting tasks arm directly.
    Thread,
    /// The timer thread sleeping on a condition variable's timed wait (elsewhere than Linux
    /// the only one; on Linux only for the benches).
    CondvarThread,
    /// A timerfd per wait in tokio's reactor (Linux, benches only).
    ReactorFd,
}

/// Sleeps `rest` of real time or a little longer, never less, on `kernel`'s timer (the timer
/// thread when a timerfd cannot be had). When no timer thread can be started either, the
/// wait spins.
pub(super) async fn sleep(rest: Duration, kernel: Kernel) {
    let until = Instant::now() + rest;
    #[cfg(target_os = "linux")]
    let timed = (kernel == Kernel::ReactorFd && timer_fd::sleep(rest).await.is_ok())
        || thread_sleep(until, kernel == Kernel::CondvarThread).await;
    #[cfg(not(target_os = "linux"))]
    let timed = {
        let _ = kernel;
        thread_sleep(until, true).await
    };
    if !timed {
        tracing::debug!(target: "optobus_transport", "no timer thread: spinning");
    }
    // Never early, even when no timer could be had.
    while Instant::now() < until {
        tokio::task::yield_now().await;
    }
}

/// Waits on a timer thread until `until`; `false` if there is none.
async fn thread_sleep(until: Instant, condvar: bool) -> bool {
    let Some(timers) = timers(condvar) else {
        return false;
    };
    timers.insert(until).await.is_ok()
}

/// The process's timer thread, started on first use (on a timerfd where there is one, unless
/// `condvar`); `None` if no thread can be started.
fn timers(condvar: bool) -> Option<&'static Timers> {
    static ON_FD: OnceLock<Option<&'static Timers>> = OnceLock::new();
    static ON_CONDVAR: OnceLock<Option<&'static Timers>> = OnceLock::new();
    if !condvar {
        if let Some(timers) = *ON_FD.get_or_init(|| Timers::start(Alarm::fd()?)) {
            return Some(timers);
        }
    }
    *ON_CONDVAR.get_or_init(|| Timers::start(Alarm::Condvar(Condvar::new())))
}

/// Deadlines waited for, earliest first, and the timer their thread sleeps on.
struct Timers {
    queue: Mutex<BinaryHeap<Entry>>,
    alarm: Alarm,
}

/// What the timer thread sleeps on.
enum Alarm {
    /// A condition variable, notified when an earlier deadline comes.
    Condvar(Condvar),
    /// A timerfd, armed for the earliest deadline (by the task that brings an earlier one,
    /// without waking the thread).
    #[cfg(target_os = "linux")]
    Fd(nix::sys::timerfd::TimerFd),
}

impl Alarm {
    #[cfg(target_os = "linux")]
    fn fd() -> Option<Self> {
        use nix::sys::timerfd::{ClockId, TimerFd, TimerFlags};
        match TimerFd::new(ClockId::CLOCK_MONOTONIC, TimerFlags::TFD_CLOEXEC) {
            Ok(timer) => Some(Self::Fd(timer)),
            Err(error) => {
                tracing::debug!(target: "optobus_transport", "no timerfd for the timer thread: {error}");
                None
            }
        }
    }

    #[cfg(not(target_os = "linux"))]
    fn fd() -> Option<Self> {
        None
    }

    /// Makes the thread wake within `rest` (called with the queue locked).
    fn arm(&self, rest: Duration) {
        match self {
            Self::Condvar(changed) => {
                // The thread computes its own timeout.
                let _ = rest;
                changed.notify_one();
            }
            #[cfg(target_os = "linux")]
            Self::Fd(timer) => {
                use nix::sys::time::TimeSpec;
                use nix::sys::timerfd::{Expiration, TimerSetTimeFlags};
                // A zero expiration would disarm the timer.
                let rest = TimeSpec::from_duration(rest.max(Duration::from_nanos(1)));
                if let Err(error) = timer.set(Expiration::OneShot(rest), TimerSetTimeFlags::empty())
                {
                    tracing::debug!(target: "optobus_transport", "timerfd not armed: {error}");
                }
            }
        }
    }
}

/// One wait: its deadline and the task to tell (a dropped receiver: a cancelled wait, which
/// stays until its deadline, at most `KERNEL_SPAN`).
struct Entry {
    at: Instant,
    done: oneshot::Sender<()>,
}

impl PartialEq for Entry {
    fn eq(&self, other: &Self) -> bool {
        self.at == other.at
    }
}

impl Eq for Entry {}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Entry {
    /// Reversed: the heap's greatest is the earliest deadline.
    fn cmp(&self, other: &Self) -> Ordering {
        other.at.cmp(&self.at)
    }
}

impl Timers {
    /// Starts a timer thread sleeping on `alarm`; `None` if no thread can be started.
    fn start(alarm: Alarm) -> Option<&'static Self> {
        // One per process and kind, for the process's life.
        let timers: &'static Self = Box::leak(Box::new(Self {
            queue: Mutex::new(BinaryHeap::new()),
            alarm,
        }));
        std::thread::Builder::new()
            .name("optobus-timer".into())
            .stack_size(64 * 1024)
            .spawn(move || timers.run())
            .ok()
            .map(|_| timers)
    }

    fn lock(&self) -> MutexGuard<'_, BinaryHeap<Entry>> {
        // Nothing panics while holding the lock; a poisoned queue is still a valid heap.
        self.queue.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// A receiver told at `at` or a little later.
    fn insert(&self, at: Instant) -> oneshot::Receiver<()> {
        let (done, told) = oneshot::channel();
        let mut queue = self.lock();
        if queue.peek().is_none_or(|next| at < next.at) {
            self.alarm.arm(at.saturating_duration_since(Instant::now()));
        }
        queue.push(Entry { at, done });
        told
    }

    /// The thread: tells each entry once its deadline has passed, and sleeps until the next.
    fn run(&self) {
        match &self.alarm {
            Alarm::Condvar(changed) => self.run_on_condvar(changed),
            #[cfg(target_os = "linux")]
            Alarm::Fd(timer) => self.run_on_fd(timer),
        }
    }

    fn run_on_condvar(&self, changed: &Condvar) {
        lower_timer_slack();
        let mut queue = self.lock();
        loop {
            let now = Instant::now();
            let Some(next) = queue.peek() else {
                queue = changed.wait(queue).unwrap_or_else(PoisonError::into_inner);
                continue;
            };
            if next.at > now {
                let wait = next.at - now;
                queue = changed
                    .wait_timeout(queue, wait)
                    .unwrap_or_else(PoisonError::into_inner)
                    .0;
                continue;
            }
            if let Some(due) = queue.pop() {
                // Told without the lock: waking a runtime may take a system call.
                drop(queue);
                let _ = due.done.send(());
                queue = self.lock();
            }
        }
    }

    /// Each pass takes the entries due, arms the timer for the next (a task that brings an
    /// earlier one arms it again) and sleeps until it fires. The timer is not subject to the
    /// thread's timer slack.
    #[cfg(target_os = "linux")]
    fn run_on_fd(&self, timer: &nix::sys::timerfd::TimerFd) {
        let mut due = Vec::new();
        loop {
            {
                let mut queue = self.lock();
                let now = Instant::now();
                while queue.peek().is_some_and(|next| next.at <= now) {
                    due.extend(queue.pop());
                }
                match queue.peek() {
                    Some(next) => self.alarm.arm(next.at - now),
                    None => {
                        if let Err(error) = timer.unset() {
                            tracing::debug!(target: "optobus_transport", "timerfd not disarmed: {error}");
                        }
                    }
                }
            }
            for entry in due.drain(..) {
                let _ = entry.done.send(());
            }
            if let Err(error) = timer.wait() {
                // Waiting tasks still end on tokio's timer; this thread must not spin.
                tracing::debug!(target: "optobus_transport", "timerfd unreadable: {error}");
                std::thread::sleep(Duration::from_millis(1));
            }
        }
    }
}

/// Linux lets a sleeping thread's timer expire up to 50 µs late by default (its timer slack,
/// for grouping wake-ups); the condition variable's thread asks for 1 ns.
fn lower_timer_slack() {
    #[cfg(target_os = "linux")]
    if let Err(error) = nix::sys::prctl::set_timerslack(1) {
        tracing::debug!(target: "optobus_transport", "timer slack kept: {error}");
    }
}

#[cfg(target_os = "linux")]
mod timer_fd {
    use std::os::fd::{AsFd, AsRawFd, RawFd};
    use std::time::Duration;

    use nix::sys::time::TimeSpec;
    use nix::sys::timerfd::{ClockId, Expiration, TimerFd, TimerFlags, TimerSetTimeFlags};
    use tokio::io::unix::AsyncFd;
    use tokio::io::Interest;

    /// A timerfd as tokio's reactor takes it.
    struct Timer(TimerFd);

    impl AsRawFd for Timer {
        fn as_raw_fd(&self) -> RawFd {
            self.0.as_fd().as_raw_fd()
        }
    }

    /// Sleeps `rest` on a new timerfd watched by tokio's reactor (which must have IO enabled).
    pub(super) async fn sleep(rest: Duration) -> std::io::Result<()> {
        let timer = TimerFd::new(
            ClockId::CLOCK_MONOTONIC,
            TimerFlags::TFD_NONBLOCK | TimerFlags::TFD_CLOEXEC,
        )?;
        // A zero expiration would disarm the timer.
        let rest = rest.max(Duration::from_nanos(1));
        timer.set(
            Expiration::OneShot(TimeSpec::from_duration(rest)),
            TimerSetTimeFlags::empty(),
        )?;
        // tokio 1.54 deprecates this constructor for the unsafe `register_with_interest` (a
        // type whose `as_raw_fd` could change); ours owns its descriptor for its whole life.
        #[allow(deprecated)]
        let timer = AsyncFd::with_interest(Timer(timer), Interest::READABLE)?;
        let _expired = timer.readable().await?;
        Ok(())
    }
}
