//! TLS to a real mosquitto: the publisher trusts the broker only when the bus file's `ca`
//! vouches for its certificate. The test makes its own throwaway CAs and server certificate
//! with the `openssl` tool; a subscriber listens on a second, plain listener of the same broker.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use common::{Broker, Watcher};
use serde_json::Value as Json;
use tracing::field::{Field, Visit};
use tracing::{Level, Subscriber};
use tracing_subscriber::layer::{Context, Layer, SubscriberExt};

/// Runs `openssl` with `args` in `dir`; panics with its output if it fails.
fn openssl(dir: &Path, args: &[&str]) {
    let output = Command::new("openssl")
        .args(args)
        .current_dir(dir)
        .output()
        .expect("openssl runs");
    assert!(
        output.status.success(),
        "openssl {args:?}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// Runs `openssl req` in `dir` with a new P-256 key, written to `key`, and the further `args`.
fn request_with_new_key(dir: &Path, key: &str, args: &[&str]) {
    let new_key = [
        "req",
        "-newkey",
        "ec",
        "-pkeyopt",
        "ec_paramgen_curve:prime256v1",
        "-nodes",
        "-keyout",
        key,
    ];
    openssl(dir, &[&new_key[..], args].concat());
}

/// A throwaway CA in `dir`: `<name>.pem` (its certificate) and `<name>.key`.
fn make_ca(dir: &Path, name: &str) -> PathBuf {
    request_with_new_key(
        dir,
        &format!("{name}.key"),
        &[
            "-x509",
            "-out",
            &format!("{name}.pem"),
            "-days",
            "2",
            "-subj",
            &format!("/CN=optobus test {name}"),
            "-addext",
            "basicConstraints=critical,CA:TRUE",
            "-addext",
            "keyUsage=critical,keyCertSign,cRLSign",
        ],
    );
    dir.join(format!("{name}.pem"))
}

/// A server certificate for 127.0.0.1 and localhost signed by the CA `ca`:
/// `server.pem` and `server.key` in `dir`.
fn make_server_certificate(dir: &Path, ca: &str) {
    std::fs::write(
        dir.join("server.ext"),
        "subjectAltName=IP:127.0.0.1,DNS:localhost\nbasicConstraints=critical,CA:FALSE\n\
         keyUsage=critical,digitalSignature\nextendedKeyUsage=serverAuth\n",
    )
    .unwrap();
    request_with_new_key(
        dir,
        "server.key",
        &["-out", "server.csr", "-subj", "/CN=127.0.0.1"],
    );
    openssl(
        dir,
        &[
            "x509",
            "-req",
            "-in",
            "server.csr",
            "-CA",
            &format!("{ca}.pem"),
            "-CAkey",
            &format!("{ca}.key"),
            "-set_serial",
            "2",
            "-days",
            "2",
            "-extfile",
            "server.ext",
            "-out",
            "server.pem",
        ],
    );
    // Started as root, mosquitto reads its key as its own user.
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(
        dir.join("server.key"),
        std::fs::Permissions::from_mode(0o644),
    )
    .unwrap();
}

/// A started mosquitto with a plain listener (`broker.port`) and a TLS listener (the port
/// returned) whose certificate the CA `<dir>/ca.pem` signed; also makes `<dir>/other-ca.pem`,
/// a CA that signed nothing of this broker.
async fn tls_broker(name: &str) -> (Broker, u16) {
    let mut broker = Broker::reserve(name);
    let dir = broker.dir().to_owned();
    make_ca(&dir, "ca");
    make_ca(&dir, "other-ca");
    make_server_certificate(&dir, "ca");
    let tls_port = {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("a free port");
        listener.local_addr().unwrap().port()
    };
    broker.configure(&format!(
        "listener {tls_port} 127.0.0.1\ncafile {0}/ca.pem\ncertfile {0}/server.pem\n\
         keyfile {0}/server.key\n",
        dir.display()
    ));
    broker.run().await;
    for _ in 0..200 {
        if tokio::net::TcpStream::connect(("127.0.0.1", tls_port))
            .await
            .is_ok()
        {
            return (broker, tls_port);
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    panic!(
        "mosquitto does not listen on {tls_port} (TLS): {}",
        broker.log()
    );
}

/// A bus of one simulated P-series whose MQTT output goes to `port` over TLS, trusting `ca`.
fn file(port: u16, ca: &Path) -> common::File {
    common::parse(&common::top_alone(
        "timeout: 100ms, poll: [{ read: [light_power, distance_1], every: 50ms }]",
        &format!(
            "broker: 127.0.0.1:{port}, prefix: plant/hall, ca: {}",
            ca.display()
        ),
    ))
}

/// The client addresses mosquitto logged as connecting on `port`
/// (`New connection from 127.0.0.1:54321 on port 8883.`).
fn connections_on(log: &str, port: u16) -> Vec<String> {
    let end = format!(" on port {port}.");
    log.lines()
        .filter_map(|line| {
            let from = line.split_once("New connection from ")?.1;
            Some(from.strip_suffix(&end)?.to_owned())
        })
        .collect()
}

/// The lines in which mosquitto logged a TLS handshake that failed because the client knew
/// no CA that signed the broker's certificate: `OpenSSL Error[0]: error:0A000418:SSL
/// routines::tlsv1 alert unknown ca`, `Client connection from 127.0.0.1 failed: error:0A000418:…`
/// or both, for one handshake.
fn refusals(log: &str) -> usize {
    log.lines()
        .filter(|line| line.contains("alert unknown ca"))
        .count()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(all(peer_mosquitto, peer_openssl)),
    ignore = "mosquitto or openssl is not installed (Debian packages mosquitto, openssl)"
)]
async fn samples_reach_a_tls_broker_whose_certificate_the_ca_file_vouches_for() {
    let (broker, tls_port) = tls_broker("tls-samples").await;
    let watcher = Watcher::start(broker.port, "watcher-tls", "plant/#").await;
    let file = file(tls_port, &broker.dir().join("ca.pem"));
    let (running, publisher, _) = common::start_publishing(&file);
    running
        .simulator("top")
        .unwrap()
        .set("light_power", &[425])
        .unwrap();
    assert!(
        watcher
            .wait_for(Duration::from_secs(10), |heard| {
                heard.iter().any(|h| h.topic == "plant/hall/top/distance_1")
                    && heard.iter().any(|h| {
                        h.topic == "plant/hall/top/light_power" && h.payload.contains("42.5")
                    })
            })
            .await,
        "heard {:?}; broker log:\n{}",
        watcher.heard.lock().unwrap(),
        broker.log()
    );
    // Real samples, decoded by the bus and carried over TLS.
    let powers = watcher.on("plant/hall/top/light_power");
    let set = powers.iter().find(|h| h.payload.contains("42.5")).unwrap();
    let power: Json = serde_json::from_str(&set.payload).expect("JSON");
    assert_eq!(power["value"].as_f64(), Some(42.5));
    assert_eq!(power["text"], "42.5");
    assert_eq!(power["unit"], "%");
    for heard in watcher.on("plant/hall/top/distance_1") {
        let distance: Json = serde_json::from_str(&heard.payload).expect("JSON");
        let text = distance["text"].as_str().expect("text");
        assert_eq!(distance["unit"], "mm");
        assert_eq!(
            distance["value"].as_f64(),
            Some(text.parse::<f64>().unwrap())
        );
    }
    assert!(watcher
        .on("plant/hall/status")
        .iter()
        .any(|h| h.payload == "online"));
    // The publisher came in on the TLS listener, once.
    let log = broker.log();
    let publishers: Vec<&str> = log
        .lines()
        .filter_map(|line| {
            let from = line.split_once("New client connected from ")?.1;
            from.strip_suffix(" as optobus (p2, c1, k30).")
        })
        .collect();
    assert_eq!(publishers.len(), 1, "{log}");
    assert!(
        connections_on(&log, tls_port).contains(&publishers[0].to_owned()),
        "{log}"
    );
    // The broker acknowledges over TLS too (the subscriber may hear a sample before the
    // publisher reads its acknowledgement).
    for _ in 0..500 {
        if publisher.counts().published > 0 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let counts = publisher.counts();
    assert!(counts.connected && counts.connections == 1, "{counts:?}");
    assert!(counts.published > 0, "{counts:?}");
    running.stop();
}

/// The warnings a test's tasks logged: their message and `error` field.
#[derive(Clone, Default)]
struct Warnings(Arc<Mutex<Vec<String>>>);

impl<S: Subscriber> Layer<S> for Warnings {
    fn on_event(&self, event: &tracing::Event<'_>, _: Context<'_, S>) {
        struct Text(String);
        impl Visit for Text {
            fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
                self.0 += &format!("{}={value:?} ", field.name());
            }
        }
        if *event.metadata().level() == Level::WARN {
            let mut text = Text(String::new());
            event.record(&mut text);
            self.0.lock().unwrap().push(text.0);
        }
    }
}

#[test]
#[cfg_attr(
    not(all(peer_mosquitto, peer_openssl)),
    ignore = "mosquitto or openssl is not installed (Debian packages mosquitto, openssl)"
)]
fn a_broker_certificate_the_ca_does_not_vouch_for_is_refused() {
    // One thread, so that every task of the publisher logs to this test's subscriber.
    let warnings = Warnings::default();
    let subscriber = tracing_subscriber::registry().with(warnings.clone());
    let _default = tracing::subscriber::set_default(subscriber);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    runtime.block_on(async {
        let (broker, tls_port) = tls_broker("tls-refused").await;
        let watcher = Watcher::start(broker.port, "watcher-tls-refused", "plant/#").await;
        let file = file(tls_port, &broker.dir().join("other-ca.pem"));
        // A valid CA file: the publisher starts, the refusal comes at the handshake.
        let (running, publisher, _) = common::start_publishing(&file);
        // The bus polls on; the publisher tries, is refused, and tries again with backoff.
        for _ in 0..500 {
            if publisher.counts().queued >= 5 && refusals(&broker.log()) >= 3 {
                break;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        let log = broker.log();
        assert!(refusals(&log) >= 3, "{log}");
        // Refused at every attempt (at least 2 by now: 3 lines), by the client: rustls tells
        // the broker it knows no such CA, and never logs in.
        assert!(!log.contains("as optobus"), "{log}");
        let counts = publisher.counts();
        assert_eq!(counts.connections, 0, "{counts:?}");
        assert!(!counts.connected, "{counts:?}");
        assert_eq!(counts.published, 0, "{counts:?}");
        assert!(counts.queued >= 5, "the samples wait: {counts:?}");
        // Nothing reached the broker, not even the status.
        assert!(
            watcher.heard.lock().unwrap().is_empty(),
            "{:?}",
            watcher.heard.lock().unwrap()
        );
        // The operator is told why, once.
        let warned = warnings.0.lock().unwrap().clone();
        assert_eq!(warned.len(), 1, "{warned:?}");
        assert!(
            warned[0].contains("cannot be reached")
                && warned[0].contains("invalid peer certificate: UnknownIssuer"),
            "{warned:?}"
        );
        running.stop();
        drop(publisher);
    });
}
