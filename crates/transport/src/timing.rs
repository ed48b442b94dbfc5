//! Deadlines that never overflow, and waits finer than tokio's 1 ms timer.

use std::time::Duration;

use tokio::time::{sleep_until, Instant};

/// tokio's timer wakes on whole milliseconds, late by up to one tick plus scheduling: sleeping
/// stops this long before a deadline and the rest is waited out precisely.
const TIMER_SLACK: Duration = Duration::from_micros(2_000);

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

/// Waits until `deadline` and returns within a few microseconds of it: tokio's timer sleeps
/// the coarse part, and the last `TIMER_SLACK` is spent yielding to other tasks while
/// watching the clock, so the runtime keeps running meanwhile.
///
/// Under tokio's paused test clock the coarse part is skipped by auto-advance and the fine
/// part takes real time (at most the slack).
pub async fn sleep_until_precise(deadline: Instant) {
    let now = Instant::now();
    if deadline <= now {
        return;
    }
    if deadline - now > TIMER_SLACK {
        sleep_until(deadline - TIMER_SLACK).await;
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

    #[tokio::test]
    async fn precise_waits_never_end_early() {
        for micros in [0u64, 150, 300, 1_750, 4_010] {
            let deadline = Instant::now() + Duration::from_micros(micros);
            sleep_until_precise(deadline).await;
            assert!(Instant::now() >= deadline);
        }
    }
}
