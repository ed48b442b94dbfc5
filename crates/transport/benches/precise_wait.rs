//! The precise wait alone: back-to-back waits of one t3.5 at 115200 baud (304 µs) and at
//! 9600 baud (4.01 ms) on a current-thread runtime, by each way `sleep_until_precise` can wait
//! (trials interleaved), and on an RTU client's own `PreciseTimer` (a timerfd of its own in
//! the reactor, the default where the runtime has IO), and, the floor of any wait, on a thread of
//! its own blocked in `clock_nanosleep` (no runtime). For each it prints how late the wait ended (p50, p99, max; never
//! early is checked) and the process's CPU time (user + system, the timer thread included)
//! per wait; the anchor is the spinning wait, measured in the same run.
//! Run with `cargo bench -p optobus-transport --bench precise_wait`.

use std::time::Duration;

use optobus_transport::timing::{
    runtime_has_io, set_precise_wait, sleep_until_precise, PreciseTimer, PreciseWait,
};
use tokio::time::Instant;

/// The process's CPU time so far (user + system, every thread).
fn cpu_time() -> Duration {
    let usage = nix::sys::resource::getrusage(nix::sys::resource::UsageWho::RUSAGE_SELF)
        .expect("getrusage");
    let micros = |t: nix::sys::time::TimeVal| {
        Duration::from_secs(t.tv_sec() as u64) + Duration::from_micros(t.tv_usec() as u64)
    };
    micros(usage.user_time()) + micros(usage.system_time())
}

fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(str::to_owned))
        .unwrap_or_else(|| "?".to_owned())
}

fn quantile(sorted: &[f64], q: f64) -> f64 {
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

#[derive(Default)]
struct Totals {
    late_us: Vec<f64>,
    cpu: Duration,
    waits: u64,
}

async fn trial(wait: Duration, count: u32, way: PreciseWait, totals: &mut Totals) {
    // `OwnTimer`: a client's own timer, in a runtime said to have IO (as a serial port does).
    let mut own = (way == PreciseWait::OwnTimer).then(|| {
        runtime_has_io();
        PreciseTimer::new()
    });
    let cpu = cpu_time();
    for _ in 0..count {
        let deadline = Instant::now() + wait;
        match &mut own {
            Some(timer) => timer.sleep_until(deadline).await,
            None => sleep_until_precise(deadline).await,
        }
        let now = Instant::now();
        assert!(now >= deadline, "a precise wait ended early");
        totals.late_us.push((now - deadline).as_secs_f64() * 1e6);
    }
    totals.cpu += cpu_time() - cpu;
    totals.waits += u64::from(count);
}

/// The floor of any wait: a thread of its own blocked in `clock_nanosleep` until the
/// deadline (absolute, `CLOCK_MONOTONIC`, as a blocking serial thread would wait), no runtime.
fn blocking_trial(wait: Duration, count: u32, totals: &mut Totals) {
    use nix::sys::time::TimeSpec;
    use nix::time::{clock_gettime, clock_nanosleep, ClockId, ClockNanosleepFlags};
    // As the timer thread does: no timer slack (50 µs by default).
    nix::sys::prctl::set_timerslack(1).expect("prctl");
    let cpu = cpu_time();
    for _ in 0..count {
        let start = clock_gettime(ClockId::CLOCK_MONOTONIC).expect("clock_gettime");
        let deadline = start + TimeSpec::from_duration(wait);
        // Interrupted by a signal: the rest is slept on the next call.
        while clock_nanosleep(
            ClockId::CLOCK_MONOTONIC,
            ClockNanosleepFlags::TIMER_ABSTIME,
            &deadline,
        )
        .is_err()
        {}
        let late = clock_gettime(ClockId::CLOCK_MONOTONIC).expect("clock_gettime") - deadline;
        assert!(late >= TimeSpec::new(0, 0), "clock_nanosleep ended early");
        totals
            .late_us
            .push(Duration::from(late).as_secs_f64() * 1e6);
    }
    totals.cpu += cpu_time() - cpu;
    totals.waits += u64::from(count);
}

fn main() {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let ways = [
        ("spin", PreciseWait::Spin),
        ("timer thread", PreciseWait::TimerThread),
        ("condvar", PreciseWait::CondvarThread),
        ("timerfd", PreciseWait::TimerFd),
        ("own timerfd", PreciseWait::OwnTimer),
    ];
    // After the ways above, in the same trials: a blocking thread's `clock_nanosleep`.
    let names = ways
        .iter()
        .map(|(name, _)| *name)
        .chain(["clock_nanosleep"]);
    for (name, wait, count) in [
        ("115200 t3.5", Duration::from_nanos(303_820), 300),
        ("9600 t3.5", Duration::from_nanos(4_010_417), 25),
    ] {
        let mut totals: Vec<Totals> = names.clone().map(|_| Totals::default()).collect();
        for _ in 0..10 {
            for ((_, way), totals) in ways.iter().zip(&mut totals) {
                set_precise_wait(*way);
                runtime.block_on(trial(wait, count, *way, totals));
            }
            let blocking = totals.last_mut().expect("a blocking way");
            std::thread::scope(|scope| {
                scope.spawn(|| blocking_trial(wait, count, blocking));
            });
        }
        let spin_cpu = totals[0].cpu.as_secs_f64() / totals[0].waits as f64;
        for (way, totals) in names.clone().zip(&mut totals) {
            totals.late_us.sort_by(f64::total_cmp);
            let cpu = totals.cpu.as_secs_f64() / totals.waits as f64;
            println!(
                "{name:<12} {way:<15} late p50 {:>6.1} µs  p99 {:>7.1} µs  max {:>7.1} µs  CPU {:>6.1} µs a wait ({:.3} of the spin's)  (load {})",
                quantile(&totals.late_us, 0.5),
                quantile(&totals.late_us, 0.99),
                quantile(&totals.late_us, 1.0),
                cpu * 1e6,
                cpu / spin_cpu,
                load()
            );
        }
    }
    set_precise_wait(PreciseWait::OwnTimer);
}
