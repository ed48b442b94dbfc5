//! Writes, commands and reads asked for through the bus's handle: checked before they are
//! queued, carried out ahead of the polls, and a command's busy time held by its device alone.

mod common;

use std::sync::{Arc, Mutex};
use std::time::Duration;

use common::file;
use optobus_bus::{Bus, Event, JobError, Refusal, Source};
use optobus_device::Table;
use optobus_inspect::parse_value;
use optobus_simulator::Simulator;

const TWO: &str = "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 50ms, poll: [{ read: measurements }] }
  - { name: confocal, model: ccs, slave: 2, timeout: 50ms, poll: [{ read: measurements }] }
";

#[tokio::test]
async fn a_write_is_checked_before_it_is_queued_and_then_made() {
    let running = Bus::new(file(TWO)).start().unwrap();
    let handle = running.handle();
    let head = running.simulator("head").unwrap();
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    let words = parse_value(power, "12.5").unwrap();
    handle.write("head", power, words, false).await.unwrap();
    assert_eq!(head.peek(Table::Holding, power.address), Some(vec![125]));
    // Beyond the range: refused by the spec, the device keeps 12.5 %.
    let error = handle
        .write("head", power, vec![1001], false)
        .await
        .unwrap_err();
    assert!(
        matches!(
            error,
            JobError::Refused(Refusal::Invalid {
                register: "light_power",
                ..
            })
        ),
        "{error}"
    );
    assert_eq!(head.peek(Table::Holding, power.address), Some(vec![125]));
    let distance = optobus_p_series::DEVICE.register("distance_1").unwrap();
    assert!(matches!(
        handle.write("head", distance, vec![0, 0], false).await,
        Err(JobError::Refused(Refusal::NotWritable("distance_1")))
    ));
    assert!(matches!(
        handle.write("tail", power, vec![100], false).await,
        Err(JobError::UnknownDevice(_))
    ));
    let values = handle.read("head", vec![power]).await.unwrap();
    assert_eq!(values[0].to_string(), "12.5 %");
}

#[tokio::test]
async fn a_write_goes_ahead_of_the_polls() {
    // The line's requests in the order the devices saw them: `R` a read, `W` a write.
    let seen = Arc::new(Mutex::new(String::new()));
    let log = Arc::clone(&seen);
    let head = Simulator::new(&optobus_p_series::DEVICE)
        .slave(1)
        .observe(move |exchange| {
            log.lock()
                .unwrap()
                .push(if exchange.function == 6 { 'W' } else { 'R' });
        });
    let confocal = Simulator::new(&optobus_ccs::DEVICE).slave(2);
    let (stream, _server) = optobus_simulator::Slaves::new([head.clone(), confocal]).duplex();
    let text = TWO.replace("simulated: true", "serial: memory");
    let bus = Bus::new(file(&text)).with_stream("rs485", stream);
    let running = bus.start().unwrap();
    let handle = running.handle();
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    // Let the polls run, then ask for a write: at most the poll already on the line comes
    // before it.
    while seen.lock().unwrap().len() < 20 {
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    let asked = seen.lock().unwrap().len();
    handle.write("head", power, vec![333], false).await.unwrap();
    let order = seen.lock().unwrap().clone();
    let written = order.find('W').expect("the write reached the device");
    assert!(
        written <= asked + 1,
        "{} requests of the head's before the write: {order}",
        written - asked
    );
    assert_eq!(head.peek(Table::Holding, power.address), Some(vec![333]));
}

#[tokio::test]
async fn a_commands_busy_time_holds_its_device_and_not_the_line() {
    let running = Bus::new(file(TWO)).start().unwrap();
    let handle = running.handle();
    let mut events = running.subscribe();
    let save = optobus_ccs::DEVICE.command("save_parameters").unwrap();
    let register = optobus_ccs::DEVICE.register(save.register).unwrap();
    assert!(save.busy_ms > 0);
    let job = tokio::spawn(async move { handle.run("confocal", save, register).await });
    // Until the job reports back, only the head is read.
    let mut head_samples = 0;
    let mut confocal_samples = 0;
    tokio::pin!(job);
    let outcome = loop {
        tokio::select! {
            outcome = &mut job => break outcome,
            event = events.recv() => {
                if let Ok(Event::Sample(sample)) = event {
                    match &*sample.source.device {
                        "head" => head_samples += 1,
                        _ => confocal_samples += 1,
                    }
                }
            }
        }
    };
    outcome.unwrap().unwrap();
    assert!(head_samples > 0, "the line went on with the head");
    // Samples of the confocal's poll that was on the line when the job came may still arrive.
    assert!(
        confocal_samples
            <= optobus_ccs::DEVICE
                .group("measurements")
                .unwrap()
                .registers
                .len()
                * 2,
        "{confocal_samples}"
    );
}

#[tokio::test]
async fn network_writes_are_refused_unless_listed_and_read_as_optobus_set_reads_them() {
    // The function codes of the writes the head saw.
    let writes = Arc::new(Mutex::new(Vec::new()));
    let log = Arc::clone(&writes);
    let head = Simulator::new(&optobus_p_series::DEVICE)
        .slave(1)
        .observe(move |exchange| {
            if !matches!(exchange.function, 3 | 4) {
                log.lock().unwrap().push(exchange.function);
            }
        });
    let (stream, _server) = optobus_simulator::Slaves::new([head.clone()]).duplex();
    let text = "
lines: [{ name: rs485, serial: memory, baud: 115200 }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 50ms,
      writable: [light_power, zero_position_1] }
";
    let running = Bus::new(file(text))
        .with_stream("rs485", stream)
        .start()
        .unwrap();
    let handle = running.handle();
    let device = &optobus_p_series::DEVICE;
    let power = device.register("light_power").unwrap();

    // Listed: written from text as `optobus set` reads it, and read back.
    let back = handle
        .set_listed("head", "light_power", "12.5")
        .await
        .unwrap();
    assert_eq!(back.map(|v| v.to_string()).as_deref(), Some("12.5 %"));
    assert_eq!(head.peek(Table::Holding, power.address), Some(vec![125]));
    handle.do_listed("head", "zero_position_1").await.unwrap();
    let zero = device.register("position_1_zero").unwrap();
    assert_eq!(head.peek(Table::Holding, zero.address), Some(vec![1]));
    assert_eq!(writes.lock().unwrap().len(), 2, "one set, one command");

    // Refused with the tool's own messages, and nothing sent.
    for text in ["150", "12.5 mm", "0.1", "lots"] {
        let error = handle
            .set_listed("head", "light_power", text)
            .await
            .unwrap_err();
        let tool = parse_value(power, text).unwrap_err().to_string();
        assert!(
            matches!(error, JobError::Refused(Refusal::Text(_))),
            "{text}: {error}"
        );
        assert_eq!(error.to_string(), tool, "{text}");
    }
    let unlisted = handle
        .set_listed("head", "laser_enabled", "true")
        .await
        .unwrap_err();
    assert_eq!(
        unlisted.to_string(),
        "`laser_enabled` of `head` is not writable here: the bus file's `writable` does not list it"
    );
    assert!(matches!(
        handle.do_listed("head", "save_parameters").await,
        Err(JobError::Refused(Refusal::NotListed { .. }))
    ));
    let unknown = handle.do_listed("head", "warp").await.unwrap_err();
    assert!(
        unknown
            .to_string()
            .starts_with("`warp` is no command of p-series"),
        "{unknown}"
    );
    let unknown = handle
        .set_listed("head", "lihgt_power", "1")
        .await
        .unwrap_err();
    assert!(
        unknown.to_string().contains("light_power"),
        "did you mean: {unknown}"
    );
    assert_eq!(
        writes.lock().unwrap().len(),
        2,
        "nothing refused reached the device"
    );
    assert_eq!(head.peek(Table::Holding, power.address), Some(vec![125]));
}

/// The bus runs a command through the driver's own completion wait: P series
/// `save_parameters` is done only once its flag reads 0 again (4.1.2, 0020), and the line
/// goes on with the other devices meanwhile.
#[tokio::test(start_paused = true)]
async fn a_save_is_done_through_the_bus_only_once_its_flag_reads_0() {
    let running = Bus::new(file(TWO)).start().unwrap();
    let handle = running.handle();
    let head = running.simulator("head").unwrap().clone();
    let head = head.finish_time(Duration::from_millis(300));
    let save = optobus_p_series::DEVICE.command("save_parameters").unwrap();
    let register = optobus_p_series::DEVICE.register(save.register).unwrap();
    let started = tokio::time::Instant::now();
    handle.run("head", save, register).await.unwrap();
    assert!(started.elapsed() >= Duration::from_millis(300));
    assert_eq!(head.peek(Table::Holding, register.address), Some(vec![0]));
    // One that never finishes: the driver's typed error, within the spec's bound.
    let head = head.finish_time(Duration::MAX);
    let started = tokio::time::Instant::now();
    let error = handle.run("head", save, register).await.unwrap_err();
    assert!(
        matches!(
            error,
            JobError::Device(optobus_driver::Error::CommandNotFinished {
                expected: 0,
                last_read: Some(1),
                ..
            })
        ),
        "{error}"
    );
    assert!(started.elapsed() <= Duration::from_millis(2000));
    assert_eq!(head.peek(Table::Holding, register.address), Some(vec![1]));
}

/// Issue 28, point 3: a flood of reads from the network (10,000 MQTT writes or 16 console
/// clients stopped every poll for minutes). Each network source has a bounded queue per line,
/// one more job is refused at once, and the line serves at most one job of each source
/// between two polls: the polls keep their turns however many jobs are asked for.
#[tokio::test]
async fn a_flood_of_network_jobs_is_refused_beyond_its_queue_and_the_polls_keep_their_turns() {
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    // The head's requests in the order it saw them: `J` a read of light_power (a job), `P`
    // any other read (a poll).
    let seen = Arc::new(Mutex::new(String::new()));
    let log = Arc::clone(&seen);
    let head = Simulator::new(&optobus_p_series::DEVICE)
        .slave(1)
        .observe(move |exchange| {
            if let Some(optobus_codec::Request::Read { address, .. }) = exchange.request {
                let job = *address == power.address;
                log.lock().unwrap().push(if job { 'J' } else { 'P' });
            }
        });
    let (stream, _server) = optobus_simulator::Slaves::new([head.clone()]).duplex();
    let text = "
lines: [{ name: rs485, serial: memory, baud: 115200 }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 50ms, poll: [{ read: measurements }] }
";
    let running = Bus::new(file(text))
        .with_stream("rs485", stream)
        .start()
        .unwrap();
    running
        .handle()
        .write("head", power, vec![125], false)
        .await
        .unwrap();
    let network = running.handle().for_source(Source::Mqtt);
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let mut flood = Vec::new();
    for _ in 0..40 {
        let (network, stop) = (network.clone(), Arc::clone(&stop));
        flood.push(tokio::spawn(async move {
            let (mut read, mut busy) = (0u32, 0u32);
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                match network.read("head", vec![power]).await {
                    Ok(values) => {
                        assert_eq!(values[0].to_string(), "12.5 %");
                        read += 1;
                    }
                    Err(JobError::Busy { line, source }) => {
                        assert_eq!((line.as_str(), source), ("rs485", Source::Mqtt));
                        busy += 1;
                        tokio::task::yield_now().await;
                    }
                    Err(other) => panic!("{other}"),
                }
            }
            (read, busy)
        }));
    }
    let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
    while seen.lock().unwrap().matches('P').count() < 100 {
        assert!(
            tokio::time::Instant::now() < deadline,
            "the polls starved: {}",
            seen.lock().unwrap()
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let (mut read, mut busy) = (0, 0);
    for task in flood {
        let (r, b) = task.await.unwrap();
        (read, busy) = (read + r, busy + b);
    }
    let order = seen.lock().unwrap().clone();
    assert!(read > 20, "jobs were done too: {read}");
    assert!(busy > 0, "beyond its queue a job is refused at once");
    assert_eq!(u64::from(busy), network.busy_refusals(Source::Mqtt));
    // Between two polls, at most one job of the one source that asks.
    let polls_at: Vec<usize> = order.match_indices('P').map(|(at, _)| at).collect();
    for pair in polls_at.windows(2) {
        assert!(pair[1] - pair[0] <= 2, "{order}");
    }
}
