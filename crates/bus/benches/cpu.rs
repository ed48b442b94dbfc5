//! The bus's CPU per transaction on a saturated 115200 baud line: the 8 mixed devices of
//! `line_share` polled as fast as the line allows, served by `optobus simulate --bus FILE
//! --pty --line-timing` in another process (a pty timed as the line), the bus reading them
//! through the pty as through a serial port.
//!
//! Each trial runs the bus for a few seconds with one of the ways `sleep_until_precise` can
//! wait out t3.5 and one serial stream (trials interleaved): the spinning wait on
//! tokio-serial's stream, which the transport had first (the anchor); the timer thread (the
//! default) on tokio-serial's stream, which stays in tokio's reactor and wakes the thread for
//! every byte that arrives; the timer thread, a timerfd per wait and the client's own timerfd
//! on the transport's `SerialStream`, which is in the reactor only while a read waits, each
//! awaiting a reply's first byte as it comes (the own timerfd is the default); then the own
//! timerfd with each reply slept through by its device's learned turnaround and read in one
//! go ("learned turnaround", `timing::set_sleep_through_replies`), and the same with the end of
//! t3.5 left whole to the kernel's timer ("learned, no gap spin"). Last, the floor of any client
//! that waits twice a transaction ("floor: blocking loop"): the bus's own requests, recorded
//! from a bus run, replayed on the same pty by a blocking loop on a thread of its own (no
//! runtime, bus or events; `clock_nanosleep` through each reply by its learned turnaround and
//! through t3.5), its thread's CPU counted. For each it prints the
//! process's CPU time (user + system, every thread, `getrusage`) per transaction, counted
//! between two of the line's statistics events, the transactions per second and their share
//! of the line limit (characters both ways plus 2 t3.5 per transaction, over the time taken),
//! and the simulator's own CPU per transaction (`/proc`, in clock ticks). The simulator's
//! summary (its gap violations) ends the run.
//!
//! Needs the `optobus` binary: `cargo build --release -p optobus-cli` first (or name it in
//! `OPTOBUS_BIN`). Run with `cargo bench -p optobus-bus --bench cpu`.

#[cfg(target_os = "linux")]
mod common;

#[cfg(not(target_os = "linux"))]
fn main() {
    println!("the cpu bench needs Linux (ptys, getrusage)");
}

#[cfg(target_os = "linux")]
fn main() {
    linux::main();
}

#[cfg(target_os = "linux")]
mod linux {
    use std::path::PathBuf;
    use std::process::{Child, Command};
    use std::sync::atomic::{AtomicU64, Ordering};
    use std::sync::Arc;
    use std::time::{Duration, Instant};

    use optobus_bus::Event;
    use optobus_codec::LineFormat;
    use optobus_transport::timing::{
        set_gap_spin, set_precise_wait, set_sleep_through_replies, PreciseWait,
    };
    use optobus_transport::{Flow, SerialSettings, Tap};

    use super::common::{self, load, median, model_name, models};

    const BAUD: u32 = 115_200;
    /// Trials per way; `OPTOBUS_CPU_TRIALS` changes it.
    const TRIALS: usize = 4;
    /// Statistics events (one a second) a trial measures between, after one to warm up.
    const SECONDS: u64 = 3;

    /// Which stream the bus reads the port through.
    #[derive(Clone, Copy, PartialEq)]
    enum Port {
        /// tokio-serial's `SerialStream`, always in tokio's reactor.
        TokioSerial,
        /// The transport's `SerialStream` (what `SerialSettings::open` gives).
        Transport,
        /// No bus: the bus's requests replayed by a blocking loop (`floor`).
        Floor,
    }

    /// How the RTU client waits for a reply and for the end of t3.5.
    #[derive(Clone, Copy, PartialEq)]
    enum Reply {
        /// Its first byte awaited as it comes, the header and the rest slept through (the
        /// default).
        AsItComes,
        /// Slept through by the device's learned turnaround and read in one go.
        SleptThrough,
        /// As `SleptThrough`, and the end of t3.5 left to the kernel's timer whole, not
        /// watched on the clock for its last 40 µs.
        SleptThroughNoGapSpin,
    }

    const WAYS: [(&str, PreciseWait, Port, Reply); 8] = [
        (
            "spin, tokio-serial",
            PreciseWait::Spin,
            Port::TokioSerial,
            Reply::AsItComes,
        ),
        (
            "timer thread, tokio-serial",
            PreciseWait::TimerThread,
            Port::TokioSerial,
            Reply::AsItComes,
        ),
        (
            "timer thread",
            PreciseWait::TimerThread,
            Port::Transport,
            Reply::AsItComes,
        ),
        (
            "timerfd",
            PreciseWait::TimerFd,
            Port::Transport,
            Reply::AsItComes,
        ),
        (
            "own timerfd",
            PreciseWait::OwnTimer,
            Port::Transport,
            Reply::AsItComes,
        ),
        (
            "learned turnaround",
            PreciseWait::OwnTimer,
            Port::Transport,
            Reply::SleptThrough,
        ),
        (
            "learned, no gap spin",
            PreciseWait::OwnTimer,
            Port::Transport,
            Reply::SleptThroughNoGapSpin,
        ),
        (
            "floor: blocking loop",
            PreciseWait::OwnTimer,
            Port::Floor,
            Reply::SleptThrough,
        ),
    ];

    /// The way the others are compared with besides the first chosen: the default.
    const BEFORE: &str = "own timerfd";

    /// Sets how the RTU client awaits replies and t3.5.
    fn set_reply(reply: Reply) {
        set_sleep_through_replies(reply != Reply::AsItComes);
        set_gap_spin(reply != Reply::SleptThroughNoGapSpin);
    }

    /// The devices as a bus file writes them: every group of measurements, as fast as the
    /// line allows.
    fn devices() -> Vec<String> {
        models()
            .iter()
            .enumerate()
            .map(|(i, model)| {
                format!(
                    "{{ name: d{}, model: {}, slave: {}, timeout: 500ms, poll: [{{ read: measurements }}] }}",
                    i + 1,
                    model_name(model),
                    i + 1
                )
            })
            .collect()
    }

    /// The `optobus` binary: `OPTOBUS_BIN`, else the workspace's release or debug build.
    fn optobus() -> Option<PathBuf> {
        if let Some(path) = std::env::var_os("OPTOBUS_BIN") {
            return Some(path.into());
        }
        let target = std::env::var_os("CARGO_TARGET_DIR")
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target"));
        ["release", "debug"]
            .iter()
            .map(|profile| target.join(profile).join("optobus"))
            .find(|path| path.is_file())
    }

    /// `optobus simulate` serving the devices on a line-timed pty; its path, and the
    /// its stdout and stderr go to files (a thread of this process draining a pipe would wake
    /// once a transaction for the simulator's log line, counted as the bus's CPU).
    struct Simulator {
        child: Child,
        path: String,
        _file: PathBuf,
        log: PathBuf,
        output: PathBuf,
    }

    impl Simulator {
        fn start(binary: &PathBuf, timed: bool) -> Self {
            let file = std::env::temp_dir()
                .join(format!("optobus-cpu-{}-{timed}.yaml", std::process::id()));
            let mut text = format!(
                "lines:\n  - {{ name: bench, serial: /dev/null, baud: {BAUD}, any_format: true }}\ndevices:\n"
            );
            for device in devices() {
                text += &format!("  - {device}\n");
            }
            std::fs::write(&file, text).expect("write the bus file");
            let output = file.with_extension("out");
            let log = file.with_extension("log");
            let child = Command::new(binary)
                .arg("simulate")
                .arg("--bus")
                .arg(&file)
                .args(["--pty", "--duration", "10m"])
                .args(timed.then_some("--line-timing"))
                .stdout(std::fs::File::create(&output).expect("create the output file"))
                .stderr(std::fs::File::create(&log).expect("create the log file"))
                .spawn()
                .expect("start optobus simulate");
            let started = Instant::now();
            let path = loop {
                let text = std::fs::read_to_string(&output).unwrap_or_default();
                if let Some((path, _)) = text.split_once('\n') {
                    break path.to_owned();
                }
                assert!(
                    started.elapsed() < Duration::from_secs(20),
                    "no pty path from optobus simulate in 20 s"
                );
                std::thread::sleep(Duration::from_millis(20));
            };
            Self {
                child,
                path,
                _file: file,
                log,
                output,
            }
        }

        /// Its CPU time so far (user + system, in clock ticks of 10 ms).
        fn cpu_time(&self) -> Duration {
            let stat = std::fs::read_to_string(format!("/proc/{}/stat", self.child.id()))
                .unwrap_or_default();
            // Fields after the command's closing parenthesis; utime and stime are 14 and 15.
            let after = stat.rsplit(')').next().unwrap_or("");
            let fields: Vec<&str> = after.split_whitespace().collect();
            let ticks = |i: usize| {
                fields
                    .get(i)
                    .and_then(|f| f.parse::<u64>().ok())
                    .unwrap_or(0)
            };
            Duration::from_millis((ticks(11) + ticks(12)) * 10)
        }

        /// Stops it (as Ctrl-C does) and gives its summary.
        fn stop(mut self) -> Vec<String> {
            let _ = Command::new("kill")
                .args(["-INT", &self.child.id().to_string()])
                .status();
            let _ = self.child.wait();
            std::thread::sleep(Duration::from_millis(200));
            let _ = std::fs::remove_file(&self._file);
            let _ = std::fs::remove_file(&self.output);
            let log = std::fs::read_to_string(&self.log).unwrap_or_default();
            let _ = std::fs::remove_file(&self.log);
            log.lines()
                .filter(|line| line.starts_with("optobus:"))
                .map(str::to_owned)
                .collect()
        }
    }

    /// The process's CPU time so far (user + system, every thread).
    fn cpu_time() -> Duration {
        let usage = nix::sys::resource::getrusage(nix::sys::resource::UsageWho::RUSAGE_SELF)
            .expect("getrusage");
        let time = |t: nix::sys::time::TimeVal| {
            Duration::from_secs(t.tv_sec() as u64) + Duration::from_micros(t.tv_usec() as u64)
        };
        time(usage.user_time()) + time(usage.system_time())
    }

    /// The process's voluntary context switches so far: how often its threads slept.
    fn sleeps() -> u64 {
        nix::sys::resource::getrusage(nix::sys::resource::UsageWho::RUSAGE_SELF)
            .map(|usage| usage.voluntary_context_switches() as u64)
            .unwrap_or(0)
    }

    #[derive(Default)]
    struct Totals {
        sleeps: u64,
        cpu: Duration,
        simulator_cpu: Duration,
        transactions: u64,
        errors: u64,
        elapsed: Duration,
        ratios: Vec<f64>,
    }

    /// The moment a statistics event came: the counters then.
    struct Mark {
        at: Instant,
        sleeps: u64,
        cpu: Duration,
        simulator_cpu: Duration,
        transactions: u64,
        errors: u64,
        bytes: u64,
    }

    async fn trial(simulator: &Simulator, port: Port, totals: &mut Totals) {
        let format = LineFormat::new(BAUD);
        let bytes = Arc::new(AtomicU64::new(0));
        let counter = Arc::clone(&bytes);
        let count = move |_: Flow, chunk: &[u8]| {
            counter.fetch_add(chunk.len() as u64, Ordering::Relaxed);
        };
        let file = common::bus_file(&format!("serial: bench, baud: {BAUD}"), &devices());
        let bus = optobus_bus::Bus::new(file);
        let bus = match port {
            Port::Transport => {
                let port = SerialSettings {
                    path: simulator.path.clone(),
                    line: format,
                }
                .open()
                .expect("open the pty");
                bus.with_stream("bench", Tap::new(port, count))
            }
            Port::Floor => unreachable!("the floor runs without a bus"),
            Port::TokioSerial => {
                use tokio_serial::SerialPortBuilderExt;
                let port = tokio_serial::new(&simulator.path, BAUD)
                    .open_native_async()
                    .expect("open the pty");
                bus.with_stream("bench", Tap::new(port, count))
            }
        };
        let mut events = bus.subscribe();
        let running = bus.start().expect("starts");
        let mut marks = Vec::new();
        while marks.len() < SECONDS as usize + 2 {
            match tokio::time::timeout(Duration::from_secs(5), events.recv()).await {
                Ok(Ok(Event::Line(line))) => marks.push(Mark {
                    at: Instant::now(),
                    sleeps: sleeps(),
                    cpu: cpu_time(),
                    simulator_cpu: simulator.cpu_time(),
                    transactions: line.transactions,
                    errors: line.errors.total(),
                    bytes: bytes.load(Ordering::Relaxed),
                }),
                Ok(Ok(_)) | Ok(Err(tokio::sync::broadcast::error::RecvError::Lagged(_))) => {}
                Ok(Err(e)) => panic!("{e}"),
                Err(_) => panic!("no statistics from the line in 5 s"),
            }
        }
        drop(running);
        // The first event ends the warm-up (the port opened, the schedule settled).
        let (first, last) = (&marks[1], &marks[marks.len() - 1]);
        let transactions = last.transactions - first.transactions;
        let elapsed = last.at - first.at;
        totals.cpu += last.cpu - first.cpu;
        totals.sleeps += last.sleeps - first.sleeps;
        totals.simulator_cpu += last.simulator_cpu - first.simulator_cpu;
        totals.transactions += transactions;
        totals.errors += last.errors - first.errors;
        totals.elapsed += elapsed;
        let ideal = format.transmit_time((last.bytes - first.bytes) as usize)
            + format.frame_gap() * 2 * transactions as u32;
        totals
            .ratios
            .push(ideal.as_secs_f64() / elapsed.as_secs_f64());
        // Let a request cut short be answered or dropped before the next trial.
        tokio::time::sleep(Duration::from_millis(100)).await;
    }

    /// The floor of any client that waits twice a transaction (for the reply, then t3.5):
    /// the bus's own requests, recorded from a running bus, replayed by a plain blocking loop
    /// on a thread of its own, with no runtime, bus, events or tracing; each reply slept
    /// through by the request's learned turnaround (`clock_nanosleep`, absolute, no timer
    /// slack) and read in one go, the rest awaited in `poll` when it is not whole, and t3.5
    /// kept after it in a second `clock_nanosleep`.
    mod floor {
        use std::os::fd::AsFd;
        use std::os::unix::fs::OpenOptionsExt;
        use std::time::{Duration, Instant};

        use nix::fcntl::OFlag;
        use nix::poll::{poll, PollFd, PollFlags, PollTimeout};
        use nix::sys::resource::{getrusage, UsageWho};
        use nix::sys::termios::{cfmakeraw, tcgetattr, tcsetattr, SetArg};
        use nix::sys::time::TimeSpec;
        use nix::time::{clock_gettime, clock_nanosleep, ClockId, ClockNanosleepFlags};
        use optobus_codec::crc::crc16;
        use optobus_codec::LineFormat;

        /// What a floor trial counted.
        pub(super) struct Counts {
            pub cpu: Duration,
            pub sleeps: u64,
            pub transactions: u64,
            pub errors: u64,
            pub elapsed: Duration,
            pub bytes: u64,
        }

        fn thread_usage() -> (Duration, u64) {
            let usage = getrusage(UsageWho::RUSAGE_THREAD).expect("getrusage");
            let time = |t: nix::sys::time::TimeVal| {
                Duration::from_secs(t.tv_sec() as u64) + Duration::from_micros(t.tv_usec() as u64)
            };
            (
                time(usage.user_time()) + time(usage.system_time()),
                usage.voluntary_context_switches() as u64,
            )
        }

        fn sleep_until(deadline: Instant) {
            let now = Instant::now();
            if deadline <= now {
                return;
            }
            let at = clock_gettime(ClockId::CLOCK_MONOTONIC).expect("clock_gettime")
                + TimeSpec::from_duration(deadline - now);
            while clock_nanosleep(
                ClockId::CLOCK_MONOTONIC,
                ClockNanosleepFlags::TIMER_ABSTIME,
                &at,
            )
            .is_err()
            {}
        }

        /// The reply's length to a register read (`FC03`/`FC04`), from its request.
        fn reply_len(request: &[u8]) -> usize {
            5 + 2 * usize::from(u16::from_be_bytes([request[4], request[5]]))
        }

        /// Replays `requests` in turn on the pty at `path` for `run`.
        pub(super) fn trial(
            path: &str,
            requests: &[Vec<u8>],
            format: LineFormat,
            run: Duration,
        ) -> Counts {
            let port = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .custom_flags((OFlag::O_NOCTTY | OFlag::O_NONBLOCK).bits())
                .open(path)
                .expect("open the pty");
            let mut raw = tcgetattr(port.as_fd()).expect("tcgetattr");
            cfmakeraw(&mut raw);
            tcsetattr(port.as_fd(), SetArg::TCSANOW, &raw).expect("tcsetattr");
            let mut turnarounds: Vec<Option<Duration>> = vec![None; requests.len()];
            let mut buffer = [0u8; 260];
            let mut last_activity = Instant::now();
            let (cpu, sleeps) = thread_usage();
            let started = Instant::now();
            let mut counts = Counts {
                cpu: Duration::ZERO,
                sleeps: 0,
                transactions: 0,
                errors: 0,
                elapsed: Duration::ZERO,
                bytes: 0,
            };
            for (index, request) in requests.iter().enumerate().cycle() {
                if started.elapsed() >= run {
                    break;
                }
                let len = reply_len(request);
                sleep_until(last_activity + format.frame_gap());
                let written = nix::unistd::write(&port, request).expect("write");
                assert_eq!(written, request.len(), "a request written whole");
                let sent = Instant::now() + format.transmit_time(request.len());
                let deadline = sent + Duration::from_millis(500);
                let slept = turnarounds[index].map(|turnaround| {
                    sleep_until(sent + turnaround + format.transmit_time(len));
                });
                let mut filled = 0;
                let mut reads = 0;
                while filled < len {
                    match nix::unistd::read(&port, &mut buffer[filled..len]) {
                        Ok(n) if n > 0 => {
                            filled += n;
                            reads += 1;
                            continue;
                        }
                        Ok(_) => panic!("the pty closed"),
                        Err(nix::errno::Errno::EAGAIN) => {}
                        Err(error) => panic!("read: {error}"),
                    }
                    let left = deadline.saturating_duration_since(Instant::now());
                    if left.is_zero() {
                        break;
                    }
                    let timeout = PollTimeout::try_from(left.as_millis().max(1) as u32)
                        .unwrap_or(PollTimeout::MAX);
                    let mut fds = [PollFd::new(port.as_fd(), PollFlags::POLLIN)];
                    poll(&mut fds, timeout).expect("poll");
                }
                last_activity = Instant::now();
                // A reply found whole at once says nothing of when it was in.
                if slept.is_none() || reads > 1 {
                    let turnaround = last_activity
                        .saturating_duration_since(sent)
                        .saturating_sub(format.transmit_time(len));
                    let known = &mut turnarounds[index];
                    *known = Some(known.map_or(turnaround, |known| known.min(turnaround)));
                }
                let whole = filled == len
                    && crc16(&buffer[..len - 2]).to_le_bytes() == buffer[len - 2..len]
                    && buffer[0] == request[0];
                counts.transactions += 1;
                counts.errors += u64::from(!whole);
                counts.bytes += (request.len() + filled) as u64;
            }
            let (cpu_after, sleeps_after) = thread_usage();
            counts.cpu = cpu_after - cpu;
            counts.sleeps = sleeps_after - sleeps;
            counts.elapsed = started.elapsed();
            counts
        }
    }

    /// The bus's requests, as many as differ, recorded from a bus run for a second.
    async fn recorded_requests(simulator: &Simulator) -> Vec<Vec<u8>> {
        let requests = Arc::new(std::sync::Mutex::new(Vec::<Vec<u8>>::new()));
        let recorded = Arc::clone(&requests);
        let record = move |flow: Flow, bytes: &[u8]| {
            let mut requests = recorded.lock().expect("not poisoned");
            if flow == Flow::Sent && !requests.iter().any(|known| known == bytes) {
                requests.push(bytes.to_vec());
            }
        };
        let port = SerialSettings {
            path: simulator.path.clone(),
            line: LineFormat::new(BAUD),
        }
        .open()
        .expect("open the pty");
        let file = common::bus_file(&format!("serial: bench, baud: {BAUD}"), &devices());
        let running = optobus_bus::Bus::new(file)
            .with_stream("bench", Tap::new(port, record))
            .start()
            .expect("starts");
        tokio::time::sleep(Duration::from_secs(1)).await;
        drop(running);
        tokio::time::sleep(Duration::from_millis(100)).await;
        let requests = requests.lock().expect("not poisoned").clone();
        assert!(
            requests
                .iter()
                .all(|request| matches!(request.get(1), Some(3 | 4)) && request.len() == 8),
            "the bus's requests are register reads"
        );
        requests
    }

    /// A floor trial, counted as a bus trial is.
    fn floor_trial(simulator: &Simulator, requests: &[Vec<u8>], totals: &mut Totals) {
        let format = LineFormat::new(BAUD);
        let path = simulator.path.clone();
        let simulator_cpu = simulator.cpu_time();
        let counts = std::thread::scope(|scope| {
            scope
                .spawn(|| floor::trial(&path, requests, format, Duration::from_secs(SECONDS)))
                .join()
                .expect("the floor's thread")
        });
        totals.cpu += counts.cpu;
        totals.sleeps += counts.sleeps;
        totals.simulator_cpu += simulator.cpu_time() - simulator_cpu;
        totals.transactions += counts.transactions;
        totals.errors += counts.errors;
        totals.elapsed += counts.elapsed;
        let ideal = format.transmit_time(counts.bytes as usize)
            + format.frame_gap() * 2 * counts.transactions as u32;
        totals
            .ratios
            .push(ideal.as_secs_f64() / counts.elapsed.as_secs_f64());
        std::thread::sleep(Duration::from_millis(100));
    }

    pub(super) fn main() {
        let Some(binary) = optobus() else {
            println!(
                "no optobus binary: build it with `cargo build --release -p optobus-cli` (or name it in OPTOBUS_BIN)"
            );
            return;
        };
        let runtime = common::runtime();
        let trials = std::env::var("OPTOBUS_CPU_TRIALS")
            .ok()
            .and_then(|trials| trials.parse().ok())
            .unwrap_or(TRIALS);
        println!(
            "{BAUD} baud, 8 devices, served on a pty by {} ({trials} trials of {SECONDS} s per way, interleaved)",
            binary.display()
        );
        // `OPTOBUS_CPU_LINE=untimed|line-timed` and `OPTOBUS_CPU_WAY=NAME|NAME` run only that line
        // and those ways (to look at one under strace or perf).
        let only_line = std::env::var("OPTOBUS_CPU_LINE").unwrap_or_default();
        let only_way = std::env::var("OPTOBUS_CPU_WAY").ok();
        for (line, timed) in [("untimed pty", false), ("line-timed pty", true)] {
            let chosen = |way: &str| {
                line.starts_with(&only_line)
                    && only_way
                        .as_deref()
                        .is_none_or(|only| only.split('|').any(|name| name == way))
            };
            if !WAYS.iter().any(|(way, _, _, _)| chosen(way)) {
                continue;
            }
            let simulator = Simulator::start(&binary, timed);
            let requests = runtime.block_on(recorded_requests(&simulator));
            let mut totals: Vec<Totals> = WAYS.iter().map(|_| Totals::default()).collect();
            for _ in 0..trials {
                for ((name, way, port, reply), totals) in WAYS.iter().zip(&mut totals) {
                    if !chosen(name) {
                        continue;
                    }
                    if *port == Port::Floor {
                        floor_trial(&simulator, &requests, totals);
                        continue;
                    }
                    set_precise_wait(*way);
                    set_reply(*reply);
                    runtime.block_on(trial(&simulator, *port, totals));
                }
            }
            set_precise_wait(PreciseWait::OwnTimer);
            set_reply(Reply::AsItComes);
            let per = |count: f64, totals: &Totals| count / totals.transactions.max(1) as f64;
            let cpu_of = |totals: &Totals| per(totals.cpu.as_secs_f64() * 1e6, totals);
            // The anchor: the first way that ran (the spin unless ways were chosen).
            let Some((anchor_name, anchor)) = WAYS
                .iter()
                .zip(&totals)
                .find(|(_, totals)| totals.transactions > 0)
                .map(|((name, _, _, _), totals)| (*name, cpu_of(totals)))
            else {
                continue;
            };
            let before = WAYS
                .iter()
                .zip(&totals)
                .find(|((name, _, _, _), totals)| *name == BEFORE && totals.transactions > 0)
                .map(|(_, totals)| cpu_of(totals));
            for ((name, _, _, _), totals) in WAYS.iter().zip(&totals) {
                if totals.transactions == 0 {
                    continue;
                }
                let cpu = cpu_of(totals);
                let of_before = before
                    .map(|before| format!(", {:.3} of {BEFORE}'s", cpu / before))
                    .unwrap_or_default();
                println!(
                    "{line:<14} {name:<26} bus CPU {cpu:>6.1} µs a transaction ({:.3} of {anchor_name}'s{of_before}), {:>5.1} sleeps a transaction  {:>5.0} transactions/s  line limit ratio median {:.3}  errors {}  simulator CPU {:>6.1} µs a transaction  (load {})",
                    cpu / anchor,
                    per(totals.sleeps as f64, totals),
                    totals.transactions as f64 / totals.elapsed.as_secs_f64(),
                    median(&totals.ratios),
                    totals.errors,
                    per(totals.simulator_cpu.as_secs_f64() * 1e6, totals),
                    load()
                );
            }
            for summary in simulator.stop() {
                if summary.contains("requests") {
                    println!("{line:<14} simulator: {summary}");
                }
            }
        }
    }
}
