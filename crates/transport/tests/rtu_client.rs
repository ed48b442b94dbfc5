//! The own RTU client against a scripted device on an in-memory duplex: real bytes both ways.

mod common;

use std::time::Duration;

use common::{counting_words, DeviceSide};
use optobus_codec::{rtu, ExceptionCode, ExceptionShape, FrameShape, Request, Response, Words};
use optobus_transport::{
    Error, LineFormat, Parity, ReadFunction, RtuClient, RtuConfig, Shared, Transport, WriteValue,
};
use tokio::io::{AsyncWriteExt, DuplexStream};
use tokio::sync::mpsc;

/// What the scripted device does with the next request.
#[derive(Clone, Debug)]
enum Act {
    /// Answer properly: reads get words `address + i`, writes are echoed.
    Answer,
    /// Answer with an exception in the given shape.
    Exception(ExceptionShape, u16),
    /// Say nothing.
    Silent,
    /// Send these bytes instead of a reply.
    Raw(Vec<u8>),
}

/// A device task: decodes requests with the codec, replies per script, and reports every
/// request it saw (slave, request) on `seen`.
fn device(
    stream: DuplexStream,
    script: Vec<Act>,
    four_byte: Vec<u16>,
) -> mpsc::UnboundedReceiver<(u8, Request)> {
    let (seen_tx, seen_rx) = mpsc::unbounded_channel();
    tokio::spawn(async move {
        let mut side = DeviceSide::new(stream, four_byte);
        let mut script = script.into_iter();
        while let Some((frame, _)) = side.next_request().await {
            let _ = seen_tx.send((frame.slave, frame.pdu));
            if frame.slave == 0 {
                continue;
            }
            let mut out = [0u8; rtu::MAX_FRAME_LEN];
            let reply = match script.next().unwrap_or(Act::Answer) {
                Act::Silent => continue,
                Act::Raw(bytes) => bytes,
                Act::Exception(shape, code) => {
                    let len = rtu::encode_exception(
                        &mut out,
                        frame.slave,
                        frame.pdu.function_code(),
                        ExceptionCode(code),
                        shape,
                    )
                    .unwrap();
                    out[..len].to_vec()
                }
                Act::Answer => {
                    let data: Vec<u8>;
                    let response = match frame.pdu {
                        Request::Read {
                            function,
                            address,
                            count,
                        } => {
                            data = counting_words(address, count);
                            Response::Read {
                                function,
                                words: Words::from_bytes(&data).unwrap(),
                            }
                        }
                        Request::Write { address, value } => Response::Write { address, value },
                    };
                    let len = rtu::encode_response(&mut out, frame.slave, &response).unwrap();
                    out[..len].to_vec()
                }
            };
            if !side.send(&reply).await {
                return;
            }
        }
    });
    seen_rx
}

fn client(stream: DuplexStream, config: RtuConfig) -> RtuClient<DuplexStream> {
    RtuClient::with_config(stream, config)
}

fn quick() -> RtuConfig {
    RtuConfig {
        timeout: Duration::from_millis(200),
        ..RtuConfig::default()
    }
}

#[tokio::test]
async fn reads_words_and_writes_both_widths() {
    let (a, b) = tokio::io::duplex(1024);
    let mut seen = device(b, vec![], vec![0x0004]);
    let mut client = client(a, quick());
    let words = client
        .read(0x19, ReadFunction::Holding, 0x10, 3)
        .await
        .unwrap();
    assert_eq!(words, [0x10, 0x11, 0x12]);
    client
        .write(0x19, 0x0004, WriteValue::DoubleWord(0x0100_E100))
        .await
        .unwrap();
    client
        .write(0x19, 0x0001, WriteValue::Word(2))
        .await
        .unwrap();
    assert_eq!(
        seen.recv().await.unwrap().1,
        Request::Read {
            function: ReadFunction::Holding,
            address: 0x10,
            count: 3
        }
    );
    assert_eq!(
        seen.recv().await.unwrap().1,
        Request::Write {
            address: 4,
            value: WriteValue::DoubleWord(0x0100_E100)
        }
    );
    assert_eq!(
        seen.recv().await.unwrap().1,
        Request::Write {
            address: 1,
            value: WriteValue::Word(2)
        }
    );
}

#[tokio::test]
async fn exceptions_in_both_shapes_are_typed() {
    let (a, b) = tokio::io::duplex(1024);
    let _seen = device(
        b,
        vec![Act::Exception(ExceptionShape::CountedWord, 0x0001)],
        vec![],
    );
    let mut lc_rs = client(
        a,
        RtuConfig {
            exception: ExceptionShape::CountedWord,
            ..quick()
        },
    );
    match lc_rs.read(1, ReadFunction::Holding, 1, 1).await {
        Err(Error::Exception {
            function: 3,
            code: ExceptionCode(1),
        }) => {}
        other => panic!("{other:?}"),
    }
    let (a, b) = tokio::io::duplex(1024);
    let _seen = device(b, vec![Act::Exception(ExceptionShape::Standard, 2)], vec![]);
    let mut standard = client(a, quick());
    match standard.write(1, 100, WriteValue::Word(1)).await {
        Err(Error::Exception {
            function: 6,
            code: ExceptionCode::ILLEGAL_DATA_ADDRESS,
        }) => {}
        other => panic!("{other:?}"),
    }
}

#[tokio::test]
async fn a_silent_device_times_out_and_the_next_request_works() {
    let (a, b) = tokio::io::duplex(1024);
    let _seen = device(b, vec![Act::Silent], vec![]);
    let mut client = client(
        a,
        RtuConfig {
            timeout: Duration::from_millis(50),
            ..RtuConfig::default()
        },
    );
    match client.read(1, ReadFunction::Input, 0, 2).await {
        Err(Error::Timeout { after }) => assert_eq!(after, Duration::from_millis(50)),
        other => panic!("{other:?}"),
    }
    assert_eq!(
        client.read(1, ReadFunction::Input, 0, 2).await.unwrap(),
        [0, 1]
    );
}

/// Issue 28, point 6: a silent slave with a short timeout beside devices with the default one.
/// The quiet kept after its timeout is what a late reply to *its* request needs, not the next
/// request's timeout (which made each timeout of the absent device cost the line 1.1 s).
#[tokio::test(start_paused = true)]
async fn an_absent_device_costs_its_own_recovery_not_the_next_requests_timeout() {
    let (a, b) = tokio::io::duplex(1024);
    let mut seen = device(b, vec![Act::Silent, Act::Answer], vec![]);
    let mut client = client(
        a,
        RtuConfig {
            timeout: Duration::from_millis(100),
            line: None,
            ..RtuConfig::default()
        },
    );
    let asked = tokio::time::Instant::now();
    match client.read(25, ReadFunction::Holding, 0, 1).await {
        Err(Error::Timeout { after }) => assert_eq!(after, Duration::from_millis(100)),
        other => panic!("{other:?}"),
    }
    // The next device on the line has the default timeout of 1 s.
    client.config_mut().timeout = Duration::from_secs(1);
    assert_eq!(
        client.read(1, ReadFunction::Input, 7, 2).await.unwrap(),
        [7, 8]
    );
    let took = asked.elapsed();
    // Its timeout (100 ms) and the quiet a late reply to it needs (100 ms): the clock is
    // tokio's paused one, so this is the client's own arithmetic, not the machine's speed.
    assert!(
        took >= Duration::from_millis(200) && took < Duration::from_millis(300),
        "the absent device cost {took:?}"
    );
    assert_eq!(seen.recv().await.map(|(slave, _)| slave), Some(25));
    assert_eq!(seen.recv().await.map(|(slave, _)| slave), Some(1));
}

#[tokio::test]
async fn a_garbled_reply_resynchronises_without_losing_the_next_transaction() {
    let (a, b) = tokio::io::duplex(1024);
    // A valid reply with one corrupted data byte, then normal service.
    let mut garbled = {
        let mut out = [0u8; 16];
        let data = [0x00, 0x07];
        let len = rtu::encode_response(
            &mut out,
            1,
            &Response::Read {
                function: ReadFunction::Holding,
                words: Words::from_bytes(&data).unwrap(),
            },
        )
        .unwrap();
        out[..len].to_vec()
    };
    garbled[4] ^= 0x40;
    let _seen = device(b, vec![Act::Raw(garbled)], vec![]);
    let mut client = client(a, quick());
    match client.read(1, ReadFunction::Holding, 7, 1).await {
        Err(Error::Frame(optobus_codec::DecodeError::BadCrc { .. })) => {}
        other => panic!("{other:?}"),
    }
    assert_eq!(
        client.read(1, ReadFunction::Holding, 7, 1).await.unwrap(),
        [7]
    );
}

#[tokio::test]
async fn reads_retry_when_configured_but_writes_never_do() {
    let (a, b) = tokio::io::duplex(1024);
    let mut seen = device(b, vec![Act::Silent, Act::Silent], vec![]);
    let mut client = client(
        a,
        RtuConfig {
            timeout: Duration::from_millis(40),
            read_retries: 1,
            ..RtuConfig::default()
        },
    );
    // First attempt silent, retry silent too: fails after two requests.
    assert!(matches!(
        client.read(1, ReadFunction::Holding, 0, 1).await,
        Err(Error::Timeout { .. })
    ));
    assert!(seen.recv().await.is_some() && seen.recv().await.is_some());
    // A write is sent once even though the device would answer a second attempt.
    let (a, b) = tokio::io::duplex(1024);
    let mut seen = device(b, vec![Act::Silent], vec![]);
    let mut client = RtuClient::with_config(
        a,
        RtuConfig {
            timeout: Duration::from_millis(40),
            read_retries: 3,
            ..RtuConfig::default()
        },
    );
    assert!(matches!(
        client.write(1, 2, WriteValue::Word(5)).await,
        Err(Error::Timeout { .. })
    ));
    assert!(seen.recv().await.is_some());
    assert!(
        tokio::time::timeout(Duration::from_millis(100), seen.recv())
            .await
            .is_err(),
        "write was retried"
    );
}

#[tokio::test]
async fn broadcasts_do_not_wait_for_a_reply() {
    let (a, b) = tokio::io::duplex(1024);
    let mut seen = device(b, vec![], vec![]);
    let mut client = client(
        a,
        RtuConfig {
            timeout: Duration::from_secs(30),
            ..RtuConfig::default()
        },
    );
    let started = std::time::Instant::now();
    client.write(0, 0x18, WriteValue::Word(1)).await.unwrap();
    assert!(started.elapsed() < Duration::from_secs(5));
    assert_eq!(
        seen.recv().await.unwrap(),
        (
            0,
            Request::Write {
                address: 0x18,
                value: WriteValue::Word(1)
            }
        )
    );
    assert!(matches!(
        client.read(0, ReadFunction::Holding, 0, 1).await,
        Err(Error::Unsupported(_))
    ));
}

#[tokio::test]
async fn stale_bytes_are_drained_before_a_request() {
    let (a, mut b) = tokio::io::duplex(1024);
    // A late reply from an earlier exchange sits in the buffer before we ask.
    b.write_all(&[0x01, 0x03, 0x02, 0xDE, 0xAD, 0x00, 0x00])
        .await
        .unwrap();
    let _seen = device(b, vec![], vec![]);
    let mut client = client(a, quick());
    tokio::time::sleep(Duration::from_millis(10)).await;
    assert_eq!(
        client.read(1, ReadFunction::Holding, 40, 1).await.unwrap(),
        [40]
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_slaves_on_one_port_from_two_tasks() {
    let (a, b) = tokio::io::duplex(1024);
    let mut seen = device(b, vec![], vec![]);
    let bus = Shared::new(client(a, quick()));
    let tasks: Vec<_> = [1u8, 2u8]
        .into_iter()
        .map(|slave| {
            let mut bus = bus.clone();
            tokio::spawn(async move {
                for i in 0..25u16 {
                    let words = bus
                        .read(slave, ReadFunction::Input, u16::from(slave) * 100 + i, 2)
                        .await
                        .unwrap();
                    assert_eq!(
                        words,
                        [u16::from(slave) * 100 + i, u16::from(slave) * 100 + i + 1]
                    );
                }
            })
        })
        .collect();
    for task in tasks {
        task.await.unwrap();
    }
    let mut per_slave = [0; 3];
    while let Ok((slave, _)) = seen.try_recv() {
        per_slave[usize::from(slave)] += 1;
    }
    assert_eq!(per_slave, [0, 25, 25]);
}

#[test]
fn frame_gap_is_t3_5_of_the_actual_character_format() {
    let at = |line| {
        RtuConfig {
            line,
            ..RtuConfig::default()
        }
        .frame_gap()
    };
    // 8N1: 10-bit characters, 35 bit times.
    assert_eq!(
        at(Some(LineFormat::new(115_200))),
        Duration::from_nanos(303_820)
    );
    assert_eq!(
        at(Some(LineFormat::new(19_200))),
        Duration::from_nanos(1_822_917)
    );
    // 8E1: 11-bit characters, 38.5 bit times.
    let even = LineFormat {
        parity: Parity::Even,
        ..LineFormat::new(9_600)
    };
    assert_eq!(at(Some(even)), Duration::from_nanos(4_010_417));
    // No line (memory, TCP tunnel): no gap; or a fixed one for a device that needs it.
    assert_eq!(at(None), Duration::ZERO);
    let fixed = RtuConfig {
        frame_gap: Some(Duration::from_micros(1_750)),
        ..RtuConfig::default()
    };
    assert_eq!(fixed.frame_gap(), Duration::from_micros(1_750));
    // Recovery defaults to the timeout, capped, and never undercuts the gap.
    assert_eq!(RtuConfig::default().recovery(), Duration::from_secs(1));
    let forever = RtuConfig {
        timeout: Duration::MAX,
        ..RtuConfig::default()
    };
    assert_eq!(forever.recovery(), Duration::from_secs(10));
}

// The bridge exists with the `tokio-modbus` feature only.
#[cfg(feature = "tokio-modbus")]
#[tokio::test]
async fn tokio_modbus_backend_reads_writes_and_maps_exceptions() {
    use optobus_transport::ModbusContext;
    let (a, b) = tokio::io::duplex(1024);
    let _seen = device(
        b,
        vec![
            Act::Answer,
            Act::Answer,
            Act::Exception(ExceptionShape::Standard, 2),
        ],
        vec![],
    );
    let context = tokio_modbus::client::rtu::attach(a);
    let mut modbus = ModbusContext::new(context).with_timeout(Duration::from_millis(200));
    assert_eq!(
        modbus.read(3, ReadFunction::Input, 20, 4).await.unwrap(),
        [20, 21, 22, 23]
    );
    modbus.write(3, 6, WriteValue::Word(0x14)).await.unwrap();
    match modbus.read(3, ReadFunction::Holding, 999, 1).await {
        Err(Error::Exception {
            function: 3,
            code: ExceptionCode::ILLEGAL_DATA_ADDRESS,
        }) => {}
        other => panic!("{other:?}"),
    }
    // Frames tokio-modbus cannot carry are refused before anything is sent.
    assert!(matches!(
        modbus.write(3, 4, WriteValue::DoubleWord(1)).await,
        Err(Error::Unsupported(_))
    ));
    assert!(matches!(
        modbus.write(0, 4, WriteValue::Word(1)).await,
        Err(Error::Unsupported(_))
    ));
}

/// The PDU of a frame: what lies between the slave address and the CRC.
fn pdu_of(frame: &[u8]) -> &[u8] {
    &frame[1..frame.len() - 2]
}

#[tokio::test]
async fn a_pdu_passed_through_gets_the_reply_pdu_as_it_came() {
    use optobus_codec::passthrough::PassPdu;
    let (a, b) = tokio::io::duplex(1024);
    let mut seen = device(
        b,
        vec![Act::Answer, Act::Exception(ExceptionShape::Standard, 2)],
        vec![],
    );
    let mut client = client(a, quick());
    let read = [0x03, 0x00, 0x10, 0x00, 0x02];
    let reply = client
        .transact_pdu(7, &PassPdu::new(&read).unwrap(), &FrameShape::STANDARD)
        .await
        .unwrap()
        .expect("a reply");
    assert_eq!(reply, [0x03, 0x04, 0x00, 0x10, 0x00, 0x11]);
    // An exception is a reply like any other: passed back, not an error.
    let reply = client
        .transact_pdu(7, &PassPdu::new(&read).unwrap(), &FrameShape::STANDARD)
        .await
        .unwrap()
        .expect("a reply");
    assert_eq!(reply, [0x83, 0x02]);
    assert_eq!(
        seen.recv().await.unwrap(),
        (
            7,
            Request::Read {
                function: ReadFunction::Holding,
                address: 0x10,
                count: 2
            }
        )
    );
    // A broadcast gets no reply, and none is awaited.
    let write = [0x06, 0x00, 0x01, 0x00, 0x05];
    assert_eq!(
        client
            .transact_pdu(0, &PassPdu::new(&write).unwrap(), &FrameShape::STANDARD)
            .await
            .unwrap(),
        None
    );
}

#[tokio::test]
async fn a_garbled_reply_to_a_passed_pdu_is_an_error_and_the_next_one_works() {
    use optobus_codec::passthrough::PassPdu;
    let (a, b) = tokio::io::duplex(1024);
    let mut good = [0u8; rtu::MAX_FRAME_LEN];
    let words = [0x00, 0x10];
    let len = rtu::encode_response(
        &mut good,
        7,
        &Response::Read {
            function: ReadFunction::Holding,
            words: Words::from_bytes(&words).unwrap(),
        },
    )
    .unwrap();
    let mut garbled = good[..len].to_vec();
    garbled[3] ^= 0x40;
    let _seen = device(b, vec![Act::Raw(garbled), Act::Silent, Act::Answer], vec![]);
    let mut client = client(a, quick());
    let read = PassPdu::new(&[0x03, 0x00, 0x10, 0x00, 0x01]).unwrap();
    let error = client
        .transact_pdu(7, &read, &FrameShape::STANDARD)
        .await
        .unwrap_err();
    assert!(matches!(error, Error::Frame(_)), "{error:?}");
    let error = client
        .transact_pdu(7, &read, &FrameShape::STANDARD)
        .await
        .unwrap_err();
    assert!(matches!(error, Error::Timeout { .. }), "{error:?}");
    let reply = client
        .transact_pdu(7, &read, &FrameShape::STANDARD)
        .await
        .unwrap()
        .unwrap();
    assert_eq!(reply, pdu_of(&good[..len]));
}

/// The reply to one read, as the scripted device gives it (words `first`, `first + 1` …).
fn read_reply(slave: u8, first: u16, count: u16) -> Vec<u8> {
    let data: Vec<u8> = (0..count)
        .flat_map(|i| first.wrapping_add(i).to_be_bytes())
        .collect();
    let mut out = [0u8; rtu::MAX_FRAME_LEN];
    let len = rtu::encode_response(
        &mut out,
        slave,
        &Response::Read {
            function: ReadFunction::Holding,
            words: Words::from_bytes(&data).unwrap(),
        },
    )
    .unwrap();
    out[..len].to_vec()
}

/// A reply to an earlier request still under way when this one left (a restarted master, a
/// second master): two well-formed replies come to one request, and RTU cannot tell which is
/// its answer. Neither is taken; the line is recovered and the next read gets its own.
#[tokio::test]
async fn two_replies_to_one_request_give_neither_value() {
    let (a, b) = tokio::io::duplex(1024);
    let mut both = read_reply(1, 900, 2);
    both.extend(read_reply(1, 7, 2));
    let _seen = device(b, vec![Act::Raw(both)], vec![]);
    let mut client = client(a, quick());
    match client.read(1, ReadFunction::Holding, 7, 2).await {
        Err(Error::Frame(optobus_codec::DecodeError::SecondReply)) => {}
        other => panic!("two replies must give no value, got {other:?}"),
    }
    assert_eq!(
        client.read(1, ReadFunction::Holding, 7, 2).await.unwrap(),
        [7, 8]
    );
}

/// A lone byte behind a good reply (a transceiver letting go of the line) is no second
/// reply: the value is the device's answer, and the line is recovered before the next request.
#[tokio::test]
async fn a_lone_byte_behind_a_reply_keeps_the_reply() {
    let (a, b) = tokio::io::duplex(1024);
    let mut reply = read_reply(1, 7, 2);
    reply.push(0x00);
    let _seen = device(b, vec![Act::Raw(reply)], vec![]);
    let mut client = client(a, quick());
    assert_eq!(
        client.read(1, ReadFunction::Holding, 7, 2).await.unwrap(),
        [7, 8]
    );
    assert_eq!(
        client.read(1, ReadFunction::Holding, 7, 2).await.unwrap(),
        [7, 8]
    );
}
