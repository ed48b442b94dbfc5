//! A client's precise waits on its own timerfd wake the runtime's thread straight from the
//! reactor: the process's timer thread sleeps through them.
#![cfg(target_os = "linux")]

use std::time::Duration;

use optobus_transport::timing::{runtime_has_io, sleep_until_precise, PreciseTimer};
use tokio::time::Instant;

/// The voluntary context switches of the process's timer thread so far (how often it slept);
/// `None` while it has not started.
fn timer_thread_sleeps() -> Option<u64> {
    for task in std::fs::read_dir("/proc/self/task").ok()? {
        let task = task.ok()?.path();
        let name = std::fs::read_to_string(task.join("comm")).unwrap_or_default();
        if name.trim() == "optobus-timer" {
            let status = std::fs::read_to_string(task.join("status")).ok()?;
            return status
                .lines()
                .find_map(|line| line.strip_prefix("voluntary_ctxt_switches:"))
                .and_then(|count| count.trim().parse().ok());
        }
    }
    None
}

/// Issue 28, point 9: in a runtime with IO, 100 waits of 300 µs on a `PreciseTimer` each end
/// at their deadline or later and never wake the timer thread, which 100 waits through it
/// wake about once each (the second thread wake of every wait before).
#[tokio::test]
async fn a_clients_precise_waits_leave_the_timer_thread_asleep() {
    const WAITS: u64 = 100;
    let wait = Duration::from_micros(300);
    // Through the timer thread: it starts, and sleeps once a wait.
    let before = timer_thread_sleeps().unwrap_or(0);
    for _ in 0..WAITS {
        let deadline = Instant::now() + wait;
        sleep_until_precise(deadline).await;
        assert!(Instant::now() >= deadline);
    }
    let through_thread = timer_thread_sleeps().expect("the timer thread started") - before;
    assert!(
        through_thread >= WAITS / 2,
        "the timer thread slept {through_thread} times in {WAITS} waits"
    );

    runtime_has_io();
    let mut timer = PreciseTimer::new();
    let before = timer_thread_sleeps().expect("the timer thread lives");
    for _ in 0..WAITS {
        let deadline = Instant::now() + wait;
        timer.sleep_until(deadline).await;
        assert!(Instant::now() >= deadline);
    }
    let own = timer_thread_sleeps().expect("the timer thread lives") - before;
    // The other tests of this file may use the timer thread a few times meanwhile.
    assert!(
        own <= 5,
        "the timer thread slept {own} times in {WAITS} waits on a client's own timer"
    );
}

/// A wait dropped before its timerfd fires leaves an expiry behind; the next waits are still
/// never early, and a wait far off ends at its deadline.
#[tokio::test]
async fn a_dropped_wait_on_an_own_timer_leaves_the_next_ones_on_time() {
    runtime_has_io();
    let mut timer = PreciseTimer::new();
    let far = Instant::now() + Duration::from_millis(2);
    let cut = tokio::time::timeout(Duration::from_micros(300), timer.sleep_until(far)).await;
    assert!(cut.is_err());
    // The dropped wait's timerfd expires while this one waits.
    tokio::time::sleep(Duration::from_millis(5)).await;
    for micros in [0u64, 150, 304, 1_750, 25_000] {
        let deadline = Instant::now() + Duration::from_micros(micros);
        timer.sleep_until(deadline).await;
        assert!(Instant::now() >= deadline, "{micros} µs: early");
    }
}

/// Without IO the runtime is never taken for one with it: the timer thread serves.
#[test]
fn without_io_a_precise_timer_uses_the_timer_thread() {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()
        .unwrap();
    runtime.block_on(async {
        let mut timer = PreciseTimer::new();
        let deadline = Instant::now() + Duration::from_micros(500);
        timer.sleep_until(deadline).await;
        assert!(Instant::now() >= deadline);
    });
}
