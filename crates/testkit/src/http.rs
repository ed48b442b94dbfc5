//! For the tests of the HTTP listeners (feature `http`): limits short enough that the tests
//! wait little, and a read of all a server sends until it closes the connection.

use std::time::Duration;

use tokio::io::AsyncReadExt;

/// The listener's limits with short timeouts (header and idle 300 ms, request 500 ms) and a
/// cap of `max_connections`.
pub fn short_limits(max_connections: usize) -> optobus_http::Limits {
    optobus_http::Limits {
        header_read: Duration::from_millis(300),
        idle: Duration::from_millis(300),
        request: Duration::from_millis(500),
        max_connections,
    }
}

/// Reads until the server closes the connection (or 20 s pass): what it sent. A reset counts
/// as a close; 20 s without one fails the test.
pub async fn until_closed(stream: &mut tokio::net::TcpStream) -> String {
    let mut reply = Vec::new();
    let read = tokio::time::timeout(Duration::from_secs(20), stream.read_to_end(&mut reply));
    match read.await {
        Ok(Ok(_)) => {}
        Ok(Err(error)) if error.kind() == std::io::ErrorKind::ConnectionReset => {}
        Ok(Err(error)) => panic!("{error}"),
        Err(_) => panic!("the server kept the connection open for 20 s"),
    }
    String::from_utf8_lossy(&reply).into_owned()
}
