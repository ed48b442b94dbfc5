//! LC-RS end to end over our RTU client, which decodes its 7-byte exception replies.

use std::sync::{Arc, Mutex};

use optobus_codec::Request;
use optobus_device::Table;
use optobus_driver::transport::{Error as WireError, ReadFunction, WriteValue};
use optobus_driver::{Error, Transport};
use optobus_lc_rs::{LcRs, Parity, WorkMode, DEVICE};
use optobus_simulator::Simulator;
use optobus_tests::e2e;

#[tokio::test(start_paused = true)]
async fn every_register_and_group() {
    let (_sim, client) = e2e::simulated(&DEVICE);
    let mut sensor = LcRs::with_default_slave(client);
    // The six listed baud rates, three parities, two work modes.
    assert_eq!(e2e::sweep(sensor.core()).await, 11);
    sensor.read_measurements().await.unwrap();
    let serial = sensor.read_serial_settings().await.unwrap();
    assert_eq!(serial.slave_address, u16::from(DEVICE.default_slave));
    let version = sensor.firmware_version().await.unwrap();
    assert!(!version.to_string().is_empty());
}

#[tokio::test(start_paused = true)]
async fn settings_apply_after_save_and_power_cycle() {
    let sim = Simulator::new(&DEVICE);
    let mut sensor = LcRs::with_default_slave(e2e::rtu(&sim));
    sensor.set_parity(Parity::Even).await.unwrap();
    sensor.set_work_mode(WorkMode::Query).await.unwrap();
    sensor.set_baud_rate(9600).await.unwrap();
    // 32-bit baud rate in two FC06, high word first: 0x0000 2580.
    assert_eq!(
        [131, 132].map(|a| sim.peek(Table::Holding, a)),
        [Some(vec![0]), Some(vec![0x2580])]
    );
    assert_eq!(sensor.parity().await.unwrap(), Parity::Even);
    sensor.save_parameters().await.unwrap();
    sim.power_cycle();
    sensor.wait_ready().await.unwrap();
    assert_eq!(sensor.baud_rate().await.unwrap(), 9600);
}

#[tokio::test(start_paused = true)]
async fn seven_byte_exceptions() {
    let sim = Simulator::new(&DEVICE);
    let mut client = e2e::rtu(&sim);
    let slave = DEVICE.default_slave;
    // Undefined address (the manual's 0x0001 "register address error"), and more than 8 words
    // in one read: both the same exception.
    for (address, count) in [(0x0088, 1), (0x0080, 9)] {
        let error = client
            .read(slave, ReadFunction::Holding, address, count)
            .await
            .unwrap_err();
        assert!(
            matches!(error, WireError::Exception { code, .. } if code.0 == 0x0001),
            "{address:#06x} x{count}: {error}"
        );
    }
    // A bad value: 0x0002 "register write value error", register unchanged.
    let before = sim.peek(Table::Holding, 0x0086);
    let error = client
        .write(slave, 0x0086, WriteValue::Word(7))
        .await
        .unwrap_err();
    assert!(
        matches!(error, WireError::Exception { code, .. } if code.0 == 0x0002),
        "{error}"
    );
    assert_eq!(sim.peek(Table::Holding, 0x0086), before);
    // The next transaction is fine.
    assert_eq!(
        client
            .read(slave, ReadFunction::Holding, 0x0086, 1)
            .await
            .unwrap()
            .len(),
        1
    );
    // Through the driver, the exception code is reachable.
    let mut sensor = LcRs::with_default_slave(client);
    sim.set_silent(false);
    let error = sensor
        .core()
        .read_words(DEVICE.register("distance").unwrap())
        .await;
    assert!(error.is_ok());
    let error: Error = sensor
        .core()
        .transport_mut()
        .read(slave, ReadFunction::Input, 0, 1)
        .await
        .unwrap_err()
        .into();
    assert!(error.exception().is_some(), "{error}");
}

/// A simulator of LC-RS that records every request it is sent.
fn recording_sim() -> (Simulator, Arc<Mutex<Vec<Request>>>) {
    let requests: Arc<Mutex<Vec<Request>>> = Arc::default();
    let seen = Arc::clone(&requests);
    let sim = Simulator::new(&DEVICE).observe(move |exchange| {
        if let Some(request) = exchange.request {
            seen.lock().unwrap().push(*request);
        }
    });
    (sim, requests)
}

#[tokio::test(start_paused = true)]
async fn an_unlisted_baud_rate_is_refused_before_anything_is_sent() {
    let (sim, requests) = recording_sim();
    let mut sensor = LcRs::with_default_slave(e2e::rtu(&sim));
    // 57600 lies inside 2400 ..= 115200, but table 1 lists only six rates.
    let error = sensor.set_baud_rate(57_600).await.unwrap_err();
    assert!(
        matches!(
            error,
            Error::NotListed {
                register: "baud_rate",
                raw: 57_600,
                allowed: [2400, 4800, 9600, 19200, 38400, 115_200],
                scale: None,
                unit: None,
            }
        ),
        "{error:?}"
    );
    assert_eq!(
        error.to_string(),
        "57600 is not a value `baud_rate` accepts (only 2400, 4800, 9600, 19200, 38400, 115200)"
    );
    assert!(requests.lock().unwrap().is_empty(), "nothing on the wire");
    assert_eq!(
        [0x83, 0x84].map(|a| sim.peek(Table::Holding, a)),
        [Some(vec![0]), Some(vec![0x2580])],
        "still the factory 9600"
    );
    // A listed rate goes out as the two FC06 of 2.3, high word first: 115200 = 0x0001 C200.
    sensor.set_baud_rate(115_200).await.unwrap();
    let write = |address, value| Request::Write {
        address,
        value: WriteValue::Word(value),
    };
    assert_eq!(
        *requests.lock().unwrap(),
        [write(0x83, 0x0001), write(0x84, 0xC200)]
    );
}

#[tokio::test(start_paused = true)]
async fn factory_reset_is_written_but_never_read() {
    let (sim, requests) = recording_sim();
    let mut sensor = LcRs::with_default_slave(e2e::rtu(&sim));
    let register = &optobus_lc_rs::registers::FACTORY_RESET;
    let error = sensor.core().read_words(register).await.unwrap_err();
    assert!(
        matches!(
            error,
            Error::NotAllowed {
                register: "factory_reset",
                ..
            }
        ),
        "{error:?}"
    );
    let error = sensor
        .core()
        .read_group(&[&optobus_lc_rs::registers::WORK_MODE, register])
        .await
        .unwrap_err();
    assert!(matches!(error, Error::NotAllowed { .. }), "{error:?}");
    assert!(requests.lock().unwrap().is_empty(), "nothing on the wire");
    // Its neighbours are read without it: 0083H-0087H, one read stopping before 0088H.
    sensor.read_serial_settings().await.unwrap();
    // The command still writes it (2.3: 01 06 00 89 00 00).
    sensor.factory_reset().await.unwrap();
    let requests = requests.lock().unwrap();
    assert_eq!(
        *requests,
        [
            Request::Read {
                function: ReadFunction::Holding,
                address: 0x83,
                count: 5
            },
            Request::Write {
                address: 0x89,
                value: WriteValue::Word(0)
            }
        ]
    );
}
