//! A device that refuses reads bridging a reserved range (out of its manual's word, but real
//! gateways do it) is read around the range from then on: its samples arrive in full, and
//! the refused request is made once only.

use std::path::Path;
use std::sync::{Arc, Mutex};

use optobus_bus::{Bus, BusFile, Catalogue, Event};
use optobus_device::Table;
use optobus_simulator::{Quirks, Simulator, UnreadableReads};

#[tokio::test]
async fn a_device_refusing_bridged_reads_is_polled_around_the_reserved_range() {
    let device = &optobus_ccs::DEVICE;
    let reserved = device
        .reserved
        .iter()
        .find(|r| r.table == Table::Holding && r.readable)
        .expect("CCS has a readable reserved holding range");
    let before = device
        .registers
        .iter()
        .rfind(|r| r.table == Table::Holding && r.address < reserved.from && r.readable())
        .expect("a register before it");
    let after = device
        .registers
        .iter()
        .find(|r| r.table == Table::Holding && r.address > reserved.to && r.readable())
        .expect("a register after it");
    let refused = Arc::new(Mutex::new(0usize));
    let count = Arc::clone(&refused);
    let simulator = Simulator::new(device)
        .slave(1)
        .quirks(Quirks {
            readable_reserved: UnreadableReads::Refused,
            ..Quirks::STANDARD
        })
        .observe(move |exchange| {
            if matches!(exchange.reply, optobus_simulator::Reply::Exception { .. }) {
                *count.lock().unwrap() += 1;
            }
        });
    let (stream, _server) = simulator.duplex();
    let text = format!(
        "
lines: [{{ name: rs485, serial: memory, baud: 115200, any_format: true }}]
devices:
  - {{ name: confocal, model: ccs, slave: 1, poll: [{{ read: [{}, {}] }}] }}
",
        before.name, after.name
    );
    let catalogue = Catalogue::new([device]);
    let file = BusFile::parse("bus.yaml", &text, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()));
    let bus = Bus::new(file).with_stream("rs485", stream);
    let mut events = bus.subscribe();
    let _running = bus.start().unwrap();
    let mut samples = 0;
    while samples < 40 {
        if let Event::Sample(sample) = events.recv().await.unwrap() {
            let state = simulator.register(sample.register.name).unwrap();
            assert_eq!(
                sample.value,
                optobus_inspect::decode_value(state.info, &state.words)
            );
            samples += 1;
        }
    }
    assert_eq!(
        *refused.lock().unwrap(),
        1,
        "the bridged read was refused once, then avoided"
    );
}
