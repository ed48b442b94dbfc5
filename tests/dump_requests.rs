//! A dump (every readable register, as `optobus dump` reads it) through the driver core to
//! the simulator: the requests counted on the simulator's side, per family, and what they
//! asked for. Reserved ranges the manuals sanction reading join reads; action registers,
//! whose read no manual defines, are never asked for.

use std::sync::{Arc, Mutex};

use optobus_codec::Request;
use optobus_device::{DeviceInfo, RegisterInfo, Table};
use optobus_driver::Core;
use optobus_simulator::{Reply, Simulator};
use optobus_tests::e2e;
use optobus_tests::generated::{ccf, ccs, lc_rs, p_series, rangefinder};

/// A read the simulator answered: table, first address, words.
type Read = (Table, u16, u16);

/// Each exchange as the simulator saw it: the read (`None` for anything else), and whether it
/// was answered with words.
type Seen = Arc<Mutex<Vec<(Option<Read>, bool)>>>;

/// Dumps `device` from a simulator and gives the reads it answered, in order; every one
/// answered with words (no exception).
async fn dump(device: &'static DeviceInfo) -> Vec<Read> {
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
