//! A dump (every readable register, as `optobus dump` reads it) through the driver core to
//! the simulator: the requests counted on the simulator's side, per family, and what they
//! asked for. Reserved ranges the specs mark readable (inferred from the manuals' table sizes) join reads; action registers,
//! whose read no manual defines, are never asked for.

use std::sync::{Arc, Mutex};

use optobus_codec::Request;
use optobus_device::{DeviceInfo, RegisterInfo, Table};
use optobus_driver::Core;
use optobus_simulator::{Quirks, Reply, Simulator, UnreadableReads};
use optobus_tests::e2e;
use optobus_tests::generated::{ccf, ccs, lc_rs, p_series, rangefinder};

/// A read the simulator answered: table, first address, words.
type Read = (Table, u16, u16);

/// Each exchange as the simulator saw it: the read (`None` for anything else), and whether it
/// was answered with words.
type Seen = Arc<Mutex<Vec<(Option<Read>, bool)>>>;

/// A simulator of `device` with valid readings, and the exchanges it sees.
fn observed(device: &'static DeviceInfo) -> (Simulator, Seen) {
    let exchanges: Seen = Arc::default();
    let seen = Arc::clone(&exchanges);
    let sim = Simulator::new(device)
        .sentinel_every(0)
        .observe(move |exchange| {
            let read = match exchange.request {
                Some(Request::Read {
                    function,
                    address,
                    count,
                }) => Some((Table::read_by(*function), *address, *count)),
                _ => None,
            };
            let answered = matches!(exchange.reply, Reply::Read { .. });
            seen.lock().unwrap().push((read, answered));
        });
    (sim, exchanges)
}

/// Dumps `device` from a simulator and gives the reads it answered, in order; every one
/// answered with words (no exception).
async fn dump(device: &'static DeviceInfo) -> Vec<Read> {
    let (sim, exchanges) = observed(device);
    let mut core = Core::with_default_slave(e2e::rtu(&sim), device);
    let registers: Vec<&'static RegisterInfo> = device.dump_registers().collect();
    let readings = core.read_group(&registers).await.expect("dump");
    for register in &registers {
        assert_eq!(
            readings.words(register).len(),
            usize::from(register.words),
            "{} was read whole",
            register.name
        );
    }
    let exchanges = exchanges.lock().unwrap().clone();
    exchanges
        .into_iter()
        .map(|(read, answered)| {
            let read = read.expect("a dump only reads");
            assert!(answered, "{read:?} was refused");
            read
        })
        .collect()
}

#[tokio::test(start_paused = true)]
async fn p_series_dump_takes_three_requests() {
    let reads = dump(&p_series::DEVICE).await;
    // Holding 0-36 and the reserved 37-59 need not be read; input 0-17 (the buffer counts
    // last), then 140-154 over the reserved 141-149 (4.2.2 note 1). The 60 buffered values at
    // 18-137 are left out: reading them turns the buffer's page (appendix 3), which a dump
    // must not do. (Before: input 0-154 in two reads, the page turned by every dump.)
    assert_eq!(
        reads,
        [
            (Table::Holding, 0, 37),
            (Table::Input, 0, 18),
            (Table::Input, 140, 15)
        ]
    );
    let page = p_series::DEVICE
        .register("buffer_sample_1_buffered_value")
        .unwrap();
    assert!(!page.read_is_repeatable());
    assert!(!p_series::DEVICE
        .dump_registers()
        .any(|r| r.name == page.name));
}

#[tokio::test(start_paused = true)]
async fn ccs_dump_takes_two_requests() {
    let reads = dump(&ccs::DEVICE).await;
    // Holding 0-14 over the reserved 4-7 (4.1.1 note 1); input 0-11. (Before: 3.)
    assert_eq!(reads, [(Table::Holding, 0, 15), (Table::Input, 0, 12)]);
}

#[tokio::test(start_paused = true)]
async fn ccf_dump_takes_two_requests() {
    let reads = dump(&ccf::DEVICE).await;
    // Holding 0-38 over the reserved gaps between channel blocks (4.1.1 note 1); input 0-41.
    // (Before: 6, one holding read per channel block and one for the globals.)
    assert_eq!(reads, [(Table::Holding, 0, 39), (Table::Input, 0, 42)]);
}

#[tokio::test(start_paused = true)]
async fn lc_rs_dump_takes_three_requests_and_never_reads_factory_reset() {
    let reads = dump(&lc_rs::DEVICE).await;
    // Distance, version, 0083H-0087H; the undefined addresses are never bridged, and
    // factory reset (0089H), an action register, is not read. (Before: 4, 0089H read alone.)
    assert_eq!(
        reads,
        [
            (Table::Holding, 0x00, 1),
            (Table::Holding, 0x06, 2),
            (Table::Holding, 0x83, 5)
        ]
    );
    let factory_reset = lc_rs::DEVICE.register("factory_reset").unwrap();
    assert!(factory_reset.action && !factory_reset.readable());
    assert!(!lc_rs::DEVICE
        .readable_registers()
        .any(|r| r.name == "factory_reset"));
}

#[tokio::test(start_paused = true)]
async fn rangefinder_dump_takes_one_request_per_field() {
    let reads = dump(&rangefinder::DEVICE).await;
    // One address per field: 26 fields, the write-only save register left out.
    assert_eq!(reads.len(), 25);
    let readable = rangefinder::DEVICE.readable_registers().count();
    assert_eq!(reads.len(), readable);
}

// ------------------------------------------------ a device refusing reads of reserved ranges

/// A simulator of `device` that answers a read crossing a reserved range with exception 02
/// (the specs infer such reads are allowed; a device or gateway may refuse them), and the
/// reads it saw, each with whether it was answered with words.
fn refusing_reserved(device: &'static DeviceInfo) -> (Simulator, Seen) {
    let (sim, exchanges) = observed(device);
    let quirks = Quirks {
        readable_reserved: UnreadableReads::Refused,
        ..sim.current_quirks()
    };
    sim.set_quirks(quirks);
    (sim, exchanges)
}

/// The exchanges seen since the last call, emptied.
fn take(seen: &Seen) -> Vec<(Read, bool)> {
    std::mem::take(&mut *seen.lock().unwrap())
        .into_iter()
        .map(|(read, answered)| (read.expect("only reads"), answered))
        .collect()
}

/// Reads every register a dump reads through `core` and checks each against the simulator's
/// settings (the measurements move, so their length only).
async fn dump_in_full<T: optobus_driver::Transport>(core: &mut Core<T>, sim: &Simulator) {
    let device = sim.device();
    let registers: Vec<&'static RegisterInfo> = device.dump_registers().collect();
    let readings = core.read_group(&registers).await.expect("dump");
    for register in &registers {
        let words = readings.words(register);
        assert_eq!(
            words.len(),
            usize::from(register.words),
            "{}",
            register.name
        );
        if register.table == Table::Holding {
            let state = sim.register(register.name).unwrap();
            assert_eq!(words, state.words, "{}", register.name);
        }
    }
}

#[tokio::test(start_paused = true)]
async fn ccs_refusing_reserved_ranges_is_dumped_in_full_and_not_asked_again() {
    let (sim, seen) = refusing_reserved(&ccs::DEVICE);
    let mut core = Core::with_default_slave(e2e::rtu(&sim), &ccs::DEVICE);
    dump_in_full(&mut core, &sim).await;
    // Holding 0-14 over the reserved 4-7 is refused, then read as 0-3 and 8-14 (4.1.1 table
    // 4-1); input 0-11 crosses nothing.
    assert_eq!(
        take(&seen),
        [
            ((Table::Holding, 0, 15), false),
            ((Table::Holding, 0, 4), true),
            ((Table::Holding, 8, 7), true),
            ((Table::Input, 0, 12), true),
        ]
    );
    assert!(core.memory().refuses_reserved_reads());
    dump_in_full(&mut core, &sim).await;
    assert_eq!(
        take(&seen),
        [
            ((Table::Holding, 0, 4), true),
            ((Table::Holding, 8, 7), true),
            ((Table::Input, 0, 12), true),
        ],
        "the second dump makes no refused attempt"
    );
}

#[tokio::test(start_paused = true)]
async fn p_series_refusing_reserved_ranges_is_dumped_in_full_and_not_asked_again() {
    let (sim, seen) = refusing_reserved(&p_series::DEVICE);
    let mut core = Core::with_default_slave(e2e::rtu(&sim), &p_series::DEVICE);
    dump_in_full(&mut core, &sim).await;
    // Input 140-154 over the reserved 141-149 is refused, then read as 140 and 150-154.
    let around = [
        ((Table::Holding, 0, 37), true),
        ((Table::Input, 0, 18), true),
        ((Table::Input, 140, 1), true),
        ((Table::Input, 150, 5), true),
    ];
    let mut first = around.to_vec();
    first.insert(2, ((Table::Input, 140, 15), false));
    assert_eq!(take(&seen), first);
    dump_in_full(&mut core, &sim).await;
    assert_eq!(
        take(&seen),
        around,
        "the second dump makes no refused attempt"
    );
}

#[tokio::test(start_paused = true)]
async fn ccf_group_reads_refused_over_reserved_ranges_answer_in_full_and_not_again() {
    let (sim, seen) = refusing_reserved(&ccf::DEVICE);
    let mut core = Core::with_default_slave(e2e::rtu(&sim), &ccf::DEVICE);
    // The exposure settings of the four channels sit at holding 0-2, 8-10, 16-18, 24-26
    // (stride 8, 4.1.1 table 4-1), with reserved rows between the blocks.
    let group = ccf::DEVICE.group("exposure_settings").unwrap();
    let members: Vec<&'static RegisterInfo> = group
        .registers
        .iter()
        .flat_map(|name| ccf::DEVICE.members(name))
        .collect();
    for round in 0..2 {
        let readings = core.read_declared_group(group).await.expect("group read");
        for register in &members {
            let state = sim.register(register.name).unwrap();
            assert_eq!(readings.words(register), state.words, "{}", register.name);
        }
        let exchanges = take(&seen);
        let refused = exchanges.iter().filter(|(_, answered)| !answered).count();
        assert_eq!(
            refused,
            usize::from(round == 0),
            "round {round}: {exchanges:?}"
        );
        let answered: Vec<Read> = exchanges
            .iter()
            .filter(|(_, answered)| *answered)
            .map(|(read, _)| *read)
            .collect();
        assert!(answered.iter().all(|&(table, address, count)| !ccf::DEVICE
            .reserved
            .iter()
            .any(|r| { r.table == table && r.from < address + count && address <= r.to })));
        assert_eq!(
            answered.len(),
            4,
            "one read per channel block: {answered:?}"
        );
    }
}
