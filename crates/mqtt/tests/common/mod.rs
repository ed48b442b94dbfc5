//! A real mosquitto on a free 127.0.0.1 port, a subscriber that keeps what it hears, a client
//! that publishes what a test sends, and the bus files and publishers the tests start.

#![allow(dead_code, unreachable_pub)]

pub mod proxy;

use std::path::PathBuf;
use std::process::{Child, Command};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use rumqttc::{AsyncClient, Event, MqttOptions, Packet, QoS};

/// Whether mosquitto was found when these tests were built (cfg `peer_mosquitto`, from the
/// build script through optobus-testkit): the tests that need it are ignored without it, and
/// run anyway (`--include-ignored`) they fail here rather than pass without a broker.
pub fn mosquitto_installed() -> bool {
    if !cfg!(peer_mosquitto) {
        panic!("mosquitto is not installed (Debian package mosquitto)");
    }
    true
}

/// The models the tests' bus files name.
const MODELS: [&optobus_device::DeviceInfo; 4] = [
    &optobus_p_series::DEVICE,
    &optobus_ccs::DEVICE,
    &optobus_lc_rs::DEVICE,
    &optobus_rangefinder::DEVICE,
];

/// A bus file and the settings of its `mqtt` output.
#[derive(Clone, Debug)]
pub struct File {
    /// The lines, devices and measurements.
    pub bus: optobus_bus::BusFile,
    /// `outputs: mqtt:`, if the file has it.
    pub mqtt: Option<optobus_mqtt::MqttConfig>,
}

/// `text` read as a bus file with its `mqtt` output; a mistake in it fails the test with the
/// rendered message.
pub fn parse(text: &str) -> File {
    try_parse(text).unwrap_or_else(|e| panic!("{}", e.render()))
}

/// `text` read as a bus file with its `mqtt` output, or every problem of it.
pub fn try_parse(text: &str) -> Result<File, Box<optobus_bus::Rejected>> {
    let catalogue = optobus_bus::Catalogue::new(MODELS);
    let mut mqtt = None;
    let bus = optobus_bus::BusFile::parse_with(
        "bus.yaml",
        text,
        std::path::Path::new("."),
        &catalogue,
        &mut mqtt,
    )?;
    Ok(File { bus, mqtt })
}

/// The text of a bus file with one device on a simulated line (115200 baud, any frame
/// format): the p-series `top` at slave 1 with the further settings `top` (the inside of a
/// flow mapping: `poll: [{ read: distance_1, every: 50ms }], writable: [light_power]`), and
/// an `mqtt` output of the settings `mqtt` (`broker: 127.0.0.1:1883, prefix: plant`).
pub fn top_alone(top: &str, mqtt: &str) -> String {
    on_a_simulated_line(&format!(
        "devices:
  - {{ name: top, model: p-series, slave: 1, {top} }}
outputs:
  mqtt: {{ {mqtt} }}
"
    ))
}

/// The text of a bus file on one simulated line `rs485` (115200 baud, any frame format):
/// `rest` follows its `lines:` (the `devices:`, the `outputs:`...).
pub fn on_a_simulated_line(rest: &str) -> String {
    format!(
        "lines:\n  - {{ name: rs485, simulated: true, baud: 115200, any_format: true }}\n{}",
        rest.trim_start_matches('\n')
    )
}

/// Starts `bus` and a publisher of `file`'s `mqtt` output that takes writes through the
/// running bus's handle (the publisher subscribes before the bus starts: it misses nothing).
pub fn start_taking_writes(
    bus: optobus_bus::Bus,
    file: &File,
) -> (optobus_bus::Running, optobus_mqtt::Publisher) {
    let events = bus.subscribe();
    let running = bus.start().expect("starts");
    let publisher = optobus_mqtt::Publisher::start(
        file.mqtt.as_ref().expect("the file has `mqtt`"),
        &file.bus,
        events,
        Some(running.handle()),
    )
    .expect("starts");
    (running, publisher)
}

/// A client `id` that publishes what a test sends (packets up to 2 MiB); its task ends when
/// the returned guard is dropped.
pub fn controller(port: u16, id: &str) -> (AsyncClient, Polling) {
    let mut options = MqttOptions::new(id, "127.0.0.1", port);
    options.set_max_packet_size(2 << 20, 2 << 20);
    let (client, mut eventloop) = AsyncClient::new(options, 1000);
    let task = tokio::spawn(async move { while eventloop.poll().await.is_ok() {} });
    (client, Polling(task))
}

/// A client's event loop, polled until it fails or this is dropped.
pub struct Polling(tokio::task::JoinHandle<()>);

impl Drop for Polling {
    fn drop(&mut self) {
        self.0.abort();
    }
}

/// Starts a bus of `file` with a publisher of its samples to the broker its `mqtt` output
/// names (taking no writes), and a receiver of the bus's events; both subscribe before the
/// bus starts.
pub fn start_publishing(
    file: &File,
) -> (
    optobus_bus::Running,
    optobus_mqtt::Publisher,
    tokio::sync::broadcast::Receiver<optobus_bus::Event>,
) {
    let bus = optobus_bus::Bus::new(file.bus.clone());
    let events = bus.subscribe();
    let publisher = publish(file, &bus);
    let running = bus.start().expect("starts");
    (running, publisher, events)
}

/// A publisher of `bus`'s samples to the broker its file's `mqtt` output names, taking no
/// writes.
pub fn publish(file: &File, bus: &optobus_bus::Bus) -> optobus_mqtt::Publisher {
    optobus_mqtt::Publisher::start(
        file.mqtt.as_ref().expect("the file has `mqtt`"),
        &file.bus,
        bus.subscribe(),
        None,
    )
    .expect("starts")
}

/// A mosquitto of its own: a free port, a folder for its config and persistence (so that a
/// subscriber's session survives a restart).
pub struct Broker {
    pub port: u16,
    dir: PathBuf,
    child: Option<Child>,
}

impl Broker {
    /// A broker on a free port, not started yet.
    pub fn reserve(name: &str) -> Self {
        let port = {
            let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("a free port");
            listener.local_addr().unwrap().port()
        };
        let dir =
            std::env::temp_dir().join(format!("optobus-mqtt-{name}-{}-{port}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        // Started as root, mosquitto drops to its own user: it must still write its log and
        // its sessions (or a subscriber's session does not survive a restart).
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o777)).unwrap();
        }
        std::fs::write(
            dir.join("mosquitto.conf"),
            format!(
                "listener {port} 127.0.0.1\nallow_anonymous true\npersistence true\n\
                 persistence_location {}/\nmax_queued_messages 0\nautosave_interval 1\n\
                 log_dest file {}/log\nlog_type all\n",
                dir.display(),
                dir.display()
            ),
        )
        .unwrap();
        Self {
            port,
            dir,
            child: None,
        }
    }

    /// A started broker on a free port.
    pub async fn start(name: &str) -> Self {
        let mut broker = Self::reserve(name);
        broker.run().await;
        broker
    }

    /// Starts it (again) and waits until it accepts connections.
    pub async fn run(&mut self) {
        let child = optobus_testkit::spawn_mosquitto(&self.dir.join("mosquitto.conf"));
        self.child = Some(child);
        for _ in 0..200 {
            if tokio::net::TcpStream::connect(("127.0.0.1", self.port))
                .await
                .is_ok()
            {
                return;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        panic!("mosquitto does not listen on {}", self.port);
    }

    /// Stops it as an operator would (SIGTERM: it saves its sessions) and waits for it.
    pub fn stop(&mut self) {
        if let Some(mut child) = self.child.take() {
            let _ = Command::new("kill")
                .args(["-TERM", &child.id().to_string()])
                .status();
            let _ = child.wait();
        }
    }
}

impl Broker {
    /// The broker's log so far.
    pub fn log(&self) -> String {
        std::fs::read_to_string(self.dir.join("log")).unwrap_or_default()
    }

    /// Its folder (removed with it): room for a test's own files, such as certificates.
    pub fn dir(&self) -> &std::path::Path {
        &self.dir
    }

    /// Adds `lines` to its configuration (before it starts), such as another listener.
    pub fn configure(&self, lines: &str) {
        use std::io::Write;
        let mut config = std::fs::OpenOptions::new()
            .append(true)
            .open(self.dir.join("mosquitto.conf"))
            .unwrap();
        config.write_all(lines.as_bytes()).unwrap();
    }
}

impl Drop for Broker {
    fn drop(&mut self) {
        if let Some(child) = self.child.as_mut() {
            let _ = child.kill();
            let _ = child.wait();
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// One message a watcher heard.
#[derive(Clone, Debug)]
pub struct Heard {
    pub topic: String,
    pub payload: String,
    pub retain: bool,
    /// When the watcher's task stored it.
    pub arrived: std::time::SystemTime,
}

/// A subscriber to `filter` with a persistent session (QoS 1), reconnecting on its own.
pub struct Watcher {
    pub heard: Arc<Mutex<Vec<Heard>>>,
    task: tokio::task::JoinHandle<()>,
}

impl Watcher {
    pub async fn start(port: u16, id: &str, filter: &str) -> Self {
        let mut options = MqttOptions::new(id, "127.0.0.1", port);
        options
            .set_clean_session(false)
            .set_max_packet_size(1 << 20, 1 << 20)
            .set_keep_alive(Duration::from_secs(5));
        let (client, mut eventloop) = AsyncClient::new(options, 100);
        let heard = Arc::new(Mutex::new(Vec::new()));
        let (subscribed_tx, subscribed) = tokio::sync::oneshot::channel();
        let task = {
            let heard = Arc::clone(&heard);
            let filter = filter.to_owned();
            tokio::spawn(async move {
                let mut subscribed_tx = Some(subscribed_tx);
                loop {
                    match eventloop.poll().await {
                        Ok(Event::Incoming(Packet::ConnAck(_))) => {
                            let _ = client.try_subscribe(filter.clone(), QoS::AtLeastOnce);
                        }
                        Ok(Event::Incoming(Packet::SubAck(_))) => {
                            if let Some(tx) = subscribed_tx.take() {
                                let _ = tx.send(());
                            }
                        }
                        Ok(Event::Incoming(Packet::Publish(publish))) => {
                            heard.lock().unwrap().push(Heard {
                                topic: publish.topic.clone(),
                                payload: String::from_utf8_lossy(&publish.payload).into_owned(),
                                retain: publish.retain,
                                arrived: std::time::SystemTime::now(),
                            });
                        }
                        Ok(_) => {}
                        Err(_) => tokio::time::sleep(Duration::from_millis(50)).await,
                    }
                }
            })
        };
        tokio::time::timeout(Duration::from_secs(10), subscribed)
            .await
            .expect("the watcher subscribes")
            .unwrap();
        Self { heard, task }
    }

    /// What it heard on `topic`.
    pub fn on(&self, topic: &str) -> Vec<Heard> {
        self.heard
            .lock()
            .unwrap()
            .iter()
            .filter(|h| h.topic == topic)
            .cloned()
            .collect()
    }

    /// Waits up to `within` for a message on `topic` that `matches`: whether one came.
    pub async fn hears(
        &self,
        within: Duration,
        topic: &str,
        matches: impl Fn(&Heard) -> bool,
    ) -> bool {
        self.wait_for(within, |heard| {
            heard.iter().any(|h| h.topic == topic && matches(h))
        })
        .await
    }

    /// Waits up to `within` for `done` to hold of what it heard.
    pub async fn wait_for(&self, within: Duration, done: impl Fn(&[Heard]) -> bool) -> bool {
        let deadline = tokio::time::Instant::now() + within;
        loop {
            if done(&self.heard.lock().unwrap()) {
                return true;
            }
            if tokio::time::Instant::now() > deadline {
                return false;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }
}

impl Drop for Watcher {
    fn drop(&mut self) {
        self.task.abort();
    }
}
