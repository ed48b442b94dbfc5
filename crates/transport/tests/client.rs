//! One client for every port: a `Port` opened to a scripted server on a local socket, real
//! bytes both ways, for RTU over TCP and for Modbus TCP.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use optobus_codec::crc::crc16;
use optobus_transport::{
    Client, ClientConfig, Flow, Port, ReadFunction, Requests, Stream, Tap, Transport,
};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpListener;

/// `frame` with its CRC, low byte first.
fn with_crc(frame: &[u8]) -> Vec<u8> {
    let mut bytes = frame.to_vec();
    bytes.extend_from_slice(&crc16(frame).to_le_bytes());
    bytes
}

/// A server that takes one connection, reads `request_len` bytes, hands them back on the
/// join handle and answers with `reply(request)`.
async fn serve_once(
    request_len: usize,
    reply: impl FnOnce(&[u8]) -> Vec<u8> + Send + 'static,
) -> (u16, tokio::task::JoinHandle<Vec<u8>>) {
    let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let port = listener.local_addr().expect("address").port();
    let served = tokio::spawn(async move {
        let (mut socket, _) = listener.accept().await.expect("accept");
        let mut request = vec![0; request_len];
        socket.read_exact(&mut request).await.expect("request");
        socket.write_all(&reply(&request)).await.expect("reply");
        request
    });
    (port, served)
}

#[tokio::test]
async fn one_client_opens_rtu_over_tcp_and_modbus_tcp_ports() {
    // RTU over TCP: the request's bytes pass the tap, the reply's words come back.
    let (port, served) = serve_once(8, |_| with_crc(&[0x07, 0x03, 0x02, 0x01, 0x2C])).await;
    let seen = Arc::new(Mutex::new(Vec::new()));
    let tap_seen = Arc::clone(&seen);
    let tap = move |stream: Box<dyn Stream>| -> Box<dyn Stream> {
        Box::new(Tap::new(stream, move |flow: Flow, bytes: &[u8]| {
            tap_seen.lock().unwrap().push((flow, bytes.to_vec()));
        }))
    };
    let mut client = Port::RtuOverTcp(format!("127.0.0.1:{port}"))
        .open(ClientConfig::default(), tap)
        .await
        .expect("open");
    assert!(matches!(client, Client::Rtu(_)));
    let words = client
        .read(7, ReadFunction::Holding, 0x0010, 1)
        .await
        .expect("read");
    assert_eq!(words, [300]);
    let request = with_crc(&[0x07, 0x03, 0x00, 0x10, 0x00, 0x01]);
    assert_eq!(served.await.unwrap(), request);
    let sent: Vec<u8> = seen
        .lock()
        .unwrap()
        .iter()
        .filter(|(flow, _)| *flow == Flow::Sent)
        .flat_map(|(_, bytes)| bytes.clone())
        .collect();
    assert_eq!(sent, request);
    assert!(client.last_request().is_some());

    // Modbus TCP, the port from `default_port`: the reply echoes the transaction id.
    let (port, served) = serve_once(12, |request| {
        let mut reply = request[..4].to_vec();
        reply.extend_from_slice(&[0x00, 0x05, request[6], 0x04, 0x02, 0x00, 0x2A]);
        reply
    })
    .await;
    let mut client = Port::Tcp {
        address: "127.0.0.1".into(),
        default_port: port,
    }
    .open(ClientConfig::default(), |stream| stream)
    .await
    .expect("open");
    client.set_requests(Requests {
        timeout: Duration::from_secs(30),
        retries: 0,
        exception: optobus_codec::ExceptionShape::Standard,
    });
    let words = client
        .read(3, ReadFunction::Input, 0x0100, 1)
        .await
        .expect("read");
    assert_eq!(words, [42]);
    let request = served.await.unwrap();
    assert_eq!(
        &request[4..],
        [0x00, 0x06, 0x03, 0x04, 0x01, 0x00, 0x00, 0x01]
    );
}

#[tokio::test]
async fn the_next_read_of_a_series_is_one_interval_after_the_later_of_start_and_last_request() {
    let (port, _served) = serve_once(12, |request| {
        // Unit 1, FC03, one word: 0x002A.
        let mut reply = request[..4].to_vec();
        reply.extend_from_slice(&[0, 5, 1, 3, 2, 0, 42]);
        reply
    })
    .await;
    let address = format!("127.0.0.1:{port}");
    let port = Port::Tcp {
        address,
        default_port: 502,
    };
    let mut client = port
        .open(ClientConfig::default(), |stream| stream)
        .await
        .expect("opens");
    let interval = Duration::from_secs(3600);
    let started = tokio::time::Instant::now();
    // No request yet: one interval after the start.
    assert_eq!(client.next_read(started, interval), started + interval);
    let words = client
        .read(1, ReadFunction::Holding, 0, 1)
        .await
        .expect("the scripted reply");
    assert_eq!(words, [42]);
    let sent = client.last_request().expect("a request went out");
    assert!(sent >= started);
    assert_eq!(client.next_read(started, interval), sent + interval);
}
