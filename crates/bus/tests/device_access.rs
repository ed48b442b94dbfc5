//! Device access the bus's lines and the `optobus` tool share from the driver: a group read
//! whose second request fails keeps what the first read, names the registers of the request
//! that failed, and decodes once (the inspector's decoding); a write to the slave-address
//! register says when the device answers at its new address; a scan finds the slave that
//! answers.

use std::time::Duration;

use optobus_device::{RegisterInfo, Table};
use optobus_driver::scan::{scan, ConnectAt, ScanStep};
use optobus_driver::{AddressChange, Core};
use optobus_inspect::{decode_readings, decode_value};
use optobus_transport::{Error, ReadFunction, ReadRequest, Transport, WriteValue};

/// Answers the first read with every word [`WORD`]; every later read times out. Keeps the functions it was asked for.
/// The word every answered read carries.
const WORD: u16 = 0x002A;

#[derive(Default)]
struct FirstReadOnly {
    functions: Vec<ReadFunction>,
}

impl Transport for FirstReadOnly {
    async fn read_words(&mut self, _slave: u8, read: ReadRequest) -> Result<Vec<u16>, Error> {
        self.functions.push(read.function);
        if self.functions.len() > 1 {
            return Err(Error::Timeout {
                after: Duration::from_secs(1),
            });
        }
        Ok(vec![WORD; usize::from(read.count)])
    }

    async fn write(&mut self, _slave: u8, _address: u16, _value: WriteValue) -> Result<(), Error> {
        Err(Error::Unsupported("the test only reads"))
    }
}

fn first_readable(table: Table) -> &'static RegisterInfo {
    optobus_p_series::DEVICE
        .registers
        .iter()
        .find(|r| r.table == table && r.readable())
        .expect("a readable register in the table")
}

#[tokio::test]
async fn a_failed_read_names_the_registers_of_its_request() {
    // One holding and one input register: two requests, whatever the plan's order.
    let registers = [first_readable(Table::Holding), first_readable(Table::Input)];
    let mut core = Core::new(FirstReadOnly::default(), 1, &optobus_p_series::DEVICE).unwrap();
    let partial = core
        .read_group_partly(&registers)
        .await
        .expect_err("the second request times out");
    let asked = &core.transport_mut().functions;
    assert_eq!(asked.len(), 2);
    let (answered, failed) = match asked[0] {
        ReadFunction::Holding => (registers[0], registers[1]),
        ReadFunction::Input => (registers[1], registers[0]),
    };
    assert_eq!(partial.failed_registers(&registers), [failed]);
    assert!(matches!(
        partial.error,
        optobus_driver::Error::Transport(Error::Timeout { .. })
    ));
    // The answered register decodes from the words the first request read.
    let words = vec![WORD; usize::from(answered.words)];
    let values = decode_readings(&[answered, failed], &partial.readings);
    assert_eq!(values[0], decode_value(answered, &words));
    assert!(partial.has(answered) && !partial.has(failed));
}

#[test]
fn a_write_to_the_slave_address_register_says_when_the_new_address_applies() {
    let devices = [
        &optobus_p_series::DEVICE,
        &optobus_ccs::DEVICE,
        &optobus_ccf::DEVICE,
        &optobus_lc_rs::DEVICE,
        &optobus_rangefinder::DEVICE,
    ];
    let mut with_register = 0;
    for device in devices {
        let Some(register) = device.slave_address_register() else {
            continue;
        };
        with_register += 1;
        let words = optobus_inspect::parse_value(register, "7").expect("7 is an address");
        let change = optobus_driver::address_change(device, register, &words);
        if device.needs_save_and_power_cycle {
            let Some(AddressChange::AfterSaveAndPowerCycle { address, save }) = change else {
                panic!("{}: {change:?}", device.family);
            };
            assert_eq!(address, 7);
            assert!(save.is_none_or(|c| c.effect == optobus_device::Effect::Save));
        } else {
            assert_eq!(change, Some(AddressChange::Now(7)), "{}", device.family);
        }
        let other = device
            .registers
            .iter()
            .find(|r| r.name != register.name && r.access.writable())
            .expect("another writable register");
        assert_eq!(optobus_driver::address_change(device, other, &words), None);
    }
    assert!(with_register > 0, "a model with a slave-address register");
}

/// Answers every read at slave [`AT`] with zeros; every other slave is silent.
struct OneSlave;

/// The slave address that answers.
const AT: u8 = 3;

impl Transport for OneSlave {
    async fn read_words(&mut self, slave: u8, read: ReadRequest) -> Result<Vec<u16>, Error> {
        if slave != AT {
            return Err(Error::Timeout {
                after: Duration::from_millis(1),
            });
        }
        Ok(vec![0; usize::from(read.count)])
    }

    async fn write(&mut self, _slave: u8, _address: u16, _value: WriteValue) -> Result<(), Error> {
        Err(Error::Unsupported("the test only reads"))
    }
}

/// Links to [`OneSlave`], counting the bauds they were opened at.
#[derive(Default)]
struct Line {
    opened_at: Vec<u32>,
}

impl ConnectAt for Line {
    type Link = OneSlave;
    type Error = optobus_driver::Error;

    async fn connect_at(
        &mut self,
        _model: &'static optobus_device::DeviceInfo,
        baud: u32,
    ) -> Result<OneSlave, optobus_driver::Error> {
        self.opened_at.push(baud);
        Ok(OneSlave)
    }
}

#[tokio::test]
async fn a_scan_finds_the_slave_that_answers_and_stops_there() {
    let device = &optobus_p_series::DEVICE;
    let mut line = Line::default();
    let mut probed = Vec::new();
    let found = scan(
        &mut line,
        device,
        &[9600, 115_200],
        &[1, 2, AT, 4],
        &[device],
        false,
        |step| {
            if let ScanStep::Probing { baud, slave } = step {
                probed.push((baud, slave));
            }
        },
    )
    .await
    .unwrap();
    assert_eq!(probed, [(9600, 1), (9600, 2), (9600, AT)]);
    let [found] = found.as_slice() else {
        panic!("one device: {found:?}");
    };
    assert_eq!((found.baud, found.slave), (9600, AT));
    let [asked] = found.identification.candidates.as_slice() else {
        panic!("asked as the one candidate");
    };
    assert_eq!(asked.slave, AT);
    // The probe's link, then one for the candidate identify asked.
    assert_eq!(line.opened_at, [9600, 9600]);
}
