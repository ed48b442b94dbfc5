//! The transport's serial port (`SerialSettings::open`) on a pty that the simulator serves
//! from its own thread, timed as the line: real request bytes out, real reply bytes in.
#![cfg(target_os = "linux")]

use std::path::PathBuf;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Duration;

use optobus_codec::LineFormat;
use optobus_simulator::{Line, Reply, Simulator};
use optobus_tests::generated::ccs;
use optobus_tests::wire::{holding, rtu_frame, with_crc};
use optobus_transport::{SerialSettings, SerialStream};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWriteExt, ReadBuf};
use tokio::sync::oneshot;
use tokio::time::timeout;

const BAUD: u32 = 9_600;

/// A CCS served on a pty timed as a `BAUD` line by a runtime on its own thread (so that the
/// bytes it sends wake nothing in the runtime under test); its path, the simulator, and the
/// sender that stops it when dropped.
fn served_ccs() -> (PathBuf, Simulator, oneshot::Sender<()>) {
    let simulator = Simulator::new(&ccs::DEVICE);
    let served = simulator.clone();
    let (path_sent, path) = std::sync::mpsc::channel();
    let (stop, stopped) = oneshot::channel::<()>();
    std::thread::spawn(move || {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        runtime.block_on(async move {
            let pty = served
                .serve_pty_line(Line::new(LineFormat::new(BAUD)))
                .expect("a pty");
            path_sent.send(pty.path().to_owned()).unwrap();
            let _ = stopped.await;
        });
    });
    (path.recv().unwrap(), simulator, stop)
}

/// The reply `simulator` gives to a read of holding registers 0 to 59 (125 bytes).
fn expected_reply(simulator: &Simulator) -> Vec<u8> {
    let Reply::Read { words, .. } = simulator.request(1, &holding(0, 60)) else {
        panic!("the CCS does not answer a read of its 60 holding registers");
    };
    let mut body = vec![1, 3, 120];
    for word in words {
        body.extend_from_slice(&word.to_be_bytes());
    }
    with_crc(&body)
}

/// A current-thread runtime that counts each time its thread is woken.
fn runtime_counting_wakes() -> (tokio::runtime::Runtime, Arc<AtomicU64>) {
    let unparks = Arc::new(AtomicU64::new(0));
    let counted = Arc::clone(&unparks);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .on_thread_unpark(move || {
            counted.fetch_add(1, Ordering::Relaxed);
        })
        .build()
        .unwrap();
    (runtime, unparks)
}

/// The transport's port on the served pty, at the tests' baud rate.
fn open(path: &std::path::Path) -> SerialStream {
    SerialSettings {
        path: path.display().to_string(),
        line: LineFormat::new(BAUD),
    }
    .open()
    .expect("open the pty")
}

/// Sends the read of holding registers 0 to 59 (the request of [`expected_reply`]).
async fn ask_for_the_reply(port: &mut SerialStream) {
    port.write_all(&rtu_frame(1, &holding(0, 60)))
        .await
        .unwrap();
    port.flush().await.unwrap();
}

/// Asks for the reply of [`expected_reply`] and leaves it unread while it arrives: how many
/// times the runtime's thread (counted by `unparks`) woke meanwhile.
async fn wakes_while_the_reply_arrives_unread(port: &mut SerialStream, unparks: &AtomicU64) -> u64 {
    ask_for_the_reply(port).await;
    let before = unparks.load(Ordering::Relaxed);
    // The reply takes 130 ms to cross a 9600 baud line.
    tokio::time::sleep(Duration::from_millis(600)).await;
    unparks.load(Ordering::Relaxed) - before
}

/// Reads the 125 bytes of the reply of [`expected_reply`] (within 10 s).
async fn read_reply(port: &mut SerialStream) -> Vec<u8> {
    let mut reply = vec![0; 125];
    timeout(Duration::from_secs(10), port.read_exact(&mut reply))
        .await
        .expect("the reply within 10 s")
        .unwrap();
    reply
}

/// Opens the port, `prepares` it, asks for the reply of [`expected_reply`] and leaves it
/// unread while it arrives a character at a time: the runtime's thread woke fewer than 10
/// times meanwhile (the sleep's own end wakes it once), and the reply then read is whole and
/// right.
fn an_unread_reply_wakes_nobody(prepare: impl AsyncFnOnce(&mut SerialStream)) {
    let (path, simulator, _stop) = served_ccs();
    let (runtime, unparks) = runtime_counting_wakes();
    runtime.block_on(async {
        let mut port = open(&path);
        prepare(&mut port).await;
        let while_unread = wakes_while_the_reply_arrives_unread(&mut port, &unparks).await;
        assert_eq!(read_reply(&mut port).await, expected_reply(&simulator));
        assert!(
            while_unread < 10,
            "the runtime's thread woke {while_unread} times while 125 bytes arrived unread"
        );
    });
}

/// Issue 28, point 9: a reply arriving a character at a time while nobody reads the port
/// wakes nobody. tokio-serial's stream stays in tokio's edge-triggered reactor, which wakes
/// the runtime's thread for each of the 125 characters (and the RTU client, which sleeps
/// through a reply in flight, paid a thread wake per byte); the transport's port is in the
/// reactor only while a read waits, so the thread sleeps until its own timer ends.
#[test]
fn bytes_arriving_unread_wake_nobody() {
    an_unread_reply_wakes_nobody(async |_| {});
}

/// Issue 28, point 9: a read that waited and was given up (the RTU client's look for stray
/// bytes before a request finds none, then sleeps through the reply) takes the port out of the
/// reactor once a read with no room says so, so the reply arriving a character at a time
/// while the client sleeps wakes nobody; before, the port stayed in the reactor and the thread
/// woke for each of the 125 characters.
#[test]
fn a_read_given_up_lets_bytes_arriving_unread_wake_nobody() {
    an_unread_reply_wakes_nobody(async |port| {
        // Nothing to read: the read waits in the reactor; then it is given up.
        let mut byte = [0; 1];
        let waited = std::future::poll_fn(|cx| {
            let mut buf = ReadBuf::new(&mut byte);
            Poll::Ready(Pin::new(&mut *port).poll_read(cx, &mut buf).is_pending())
        })
        .await;
        assert!(waited, "a byte to read before any request");
        std::future::poll_fn(|cx| {
            let given_up = Pin::new(&mut *port).poll_read(cx, &mut ReadBuf::new(&mut []));
            Poll::Ready(given_up.is_ready())
        })
        .await;
    });
}

/// Issue 28, point 9: a look for bytes that nobody will wait for (polled with
/// `nobody_waits()`, as the RTU client looks for stray bytes before a request) leaves the port
/// out of the reactor: the reply then arriving a character at a time wakes nobody, and no
/// system calls go to putting the port in and out of epoll. Before, the look registered the
/// port and each of the 125 characters woke the thread until a read with no room gave it up.
#[test]
fn a_look_nobody_waits_for_leaves_the_port_out_of_the_reactor() {
    an_unread_reply_wakes_nobody(async |port| {
        let mut byte = [0; 1];
        let mut nobody = Context::from_waker(optobus_transport::nobody_waits());
        let looked = Pin::new(port).poll_read(&mut nobody, &mut ReadBuf::new(&mut byte));
        assert!(looked.is_pending(), "a byte to read before any request");
    });
}

/// A read dropped while it waits (a timeout) leaves the port usable: the reply that then
/// arrives is read whole by the next read, and the port writes and reads again after it.
#[tokio::test]
async fn a_read_dropped_while_waiting_leaves_the_port_usable() {
    let (path, simulator, _stop) = served_ccs();
    let mut port = open(&path);
    let expected = expected_reply(&simulator);
    for _ in 0..2 {
        let mut byte = [0; 1];
        // Nothing to read yet: the read waits in the reactor and is dropped.
        assert!(timeout(Duration::from_millis(20), port.read(&mut byte))
            .await
            .is_err());
        ask_for_the_reply(&mut port).await;
        assert_eq!(read_reply(&mut port).await, expected);
    }
}
