//! The MQTT output's settings, `outputs: mqtt:` of a bus file: the broker, how to log in,
//! the topics, the queue. Read here with the bus file's reading kit, as the file is read.

use std::path::PathBuf;
use std::time::Duration;

use optobus_bus::file::reading::{has_port, Node, Reader, Span};
use optobus_bus::file::{OutputSettings, Outputs};

/// The section of `outputs` these settings are read from.
pub const SECTION: &str = "mqtt";

/// Samples kept for the broker while it cannot be reached, unless the file says otherwise.
pub const DEFAULT_MQTT_QUEUE: usize = 10_000;

/// Every key the section takes.
pub const KEYS: &[&str] = &[
    "broker",
    "client_id",
    "prefix",
    "username",
    "password",
    "ca",
    "qos",
    "queue",
    "keep_alive",
    "homeassistant",
    "state_every",
    "refresh_every",
];

/// The shortest time between two messages on a register's state topic (what Home Assistant
/// reads) unless the file says otherwise.
pub const DEFAULT_STATE_EVERY: Duration = Duration::from_secs(1);

/// How often the values of the registers Home Assistant controls are read again unless the
/// file says otherwise.
pub const DEFAULT_REFRESH_EVERY: Duration = Duration::from_secs(60);

/// The shortest time between two messages on a register's state topic, for every device or
/// per device: `state_every: 1s`, or `state_every: { default: 1s, confocal: 100ms }`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StateEvery {
    /// For the devices not named in `devices`.
    pub default: Duration,
    /// Devices given their own interval.
    pub devices: Vec<(String, Duration)>,
}

impl StateEvery {
    /// The interval of device `device`.
    pub fn of(&self, device: &str) -> Duration {
        self.devices
            .iter()
            .find(|(name, _)| name == device)
            .map_or(self.default, |(_, every)| *every)
    }
}

impl Default for StateEvery {
    fn default() -> Self {
        Self {
            default: DEFAULT_STATE_EVERY,
            devices: Vec::new(),
        }
    }
}

/// Where a secret comes from; the bus file never holds a password itself.
#[derive(Clone, PartialEq, Eq)]
pub enum SecretSource {
    /// Written in the file (a user name only).
    Text(String),
    /// An environment variable of that name.
    Env(String),
    /// The first line of a file (relative paths are from the bus file's folder).
    File(PathBuf),
}

/// Says where the secret comes from, never what a `Text` holds.
impl std::fmt::Debug for SecretSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Text(_) => f.write_str("Text(..)"),
            Self::Env(name) => f.debug_tuple("Env").field(name).finish(),
            Self::File(path) => f.debug_tuple("File").field(path).finish(),
        }
    }
}

/// An MQTT broker and how to publish to it.
#[derive(Clone, Debug, PartialEq)]
pub struct MqttConfig {
    /// The broker's host name or address.
    pub host: String,
    /// Its port (1883, or 8883 with TLS, unless given).
    pub port: u16,
    /// The client id (`optobus` unless given; two gateways on one broker need two).
    pub client_id: String,
    /// The first topic level(s): samples go to `<prefix>/<device>/<register>`.
    pub prefix: String,
    /// The user name, if the broker wants one.
    pub username: Option<SecretSource>,
    /// The password, from the environment or a file.
    pub password: Option<SecretSource>,
    /// TLS with the broker's certificate checked against this CA file (verification is
    /// always on); `None` is plain TCP.
    pub ca: Option<PathBuf>,
    /// The QoS of samples (0 or 1; availability and discovery go at QoS 1).
    pub qos: u8,
    /// Samples kept while the broker cannot be reached; beyond it the oldest are dropped
    /// (and counted).
    pub queue: usize,
    /// The MQTT keep-alive interval.
    pub keep_alive: Duration,
    /// Home Assistant discovery under this prefix (`homeassistant: true` is `homeassistant`).
    pub homeassistant: Option<String>,
    /// With Home Assistant on: the shortest time between two messages on a register's state
    /// topic (`<prefix>/<device>/<register>/state`, what its entities read); zero publishes
    /// every sample there. The sample topics always carry every sample.
    pub state_every: StateEvery,
    /// With Home Assistant on: how often the registers it controls (and may read) are read
    /// again for their state topics, besides at start and after each write.
    pub refresh_every: Duration,
}

impl MqttConfig {
    /// The settings a bus file gets from `mqtt: { broker: TEXT }` alone (`HOST` or
    /// `HOST:PORT`), or why `text` is no broker address.
    pub fn for_broker(text: &str) -> Result<Self, String> {
        let (host, port) = broker_address(text, false)
            .ok_or_else(|| format!("`{text}` is no broker address: give HOST or HOST:PORT"))?;
        Ok(Self {
            host,
            port,
            client_id: "optobus".to_owned(),
            prefix: "optobus".to_owned(),
            username: None,
            password: None,
            ca: None,
            qos: 1,
            queue: DEFAULT_MQTT_QUEUE,
            keep_alive: Duration::from_secs(30),
            homeassistant: None,
            state_every: StateEvery::default(),
            refresh_every: DEFAULT_REFRESH_EVERY,
        })
    }
}

/// `HOST`, `HOST:PORT` or `[IPv6]:PORT`; the port is 1883, or 8883 with TLS, when not given.
fn broker_address(text: &str, tls: bool) -> Option<(String, u16)> {
    let text = text.trim();
    let default = if tls { 8883 } else { 1883 };
    if has_port(text) {
        text.rsplit_once(':').and_then(|(host, port)| {
            let host = host.trim_start_matches('[').trim_end_matches(']');
            Some((host.to_owned(), port.parse().ok()?))
        })
    } else if !text.is_empty() && !text.contains([':', '/', ' ']) {
        Some((text.to_owned(), default))
    } else {
        None
    }
}

impl OutputSettings for MqttConfig {
    const SECTION: &'static str = SECTION;

    fn read(outputs: &Outputs<'_>, reader: &mut Reader<'_>) -> Option<Self> {
        let (key, value) = outputs.section(SECTION)?;
        mqtt(reader, value, key.span, outputs.devices())
    }
}

/// `mqtt: { broker: HOST[:PORT], … }`.
/// `at` is where `mqtt` is written: a password written in the file is reported there, so
/// that the message does not show the line that holds it.
fn mqtt(
    reader: &mut Reader<'_>,
    node: &Node,
    at: Span,
    devices: &[(&str, Span)],
) -> Option<MqttConfig> {
    let pairs = reader.mapping(node, "`mqtt`", KEYS)?;
    let get = |key: &str| {
        pairs
            .iter()
            .find(|(k, _)| k.scalar() == Some(key))
            .map(|(_, v)| v)
    };
    let mut ok = true;
    let ca = match get("ca") {
        Some(v) => reader
            .text(v, "`ca`")
            .map(|path| Some(reader.base().join(path))),
        None => Some(None),
    };
    let tls = matches!(ca, Some(Some(_)));
    let broker = match get("broker") {
        Some(v) => broker(reader, v, tls),
        None => {
            reader.error(
                node.span,
                "`mqtt` needs a `broker`",
                "e.g. `broker: 127.0.0.1:1883`",
            );
            None
        }
    };
    let client_id = match get("client_id") {
        Some(v) => client_id(reader, v),
        None => Some("optobus".to_owned()),
    };
    let prefix = match get("prefix") {
        Some(v) => topic_prefix(reader, v, "`prefix`"),
        None => Some("optobus".to_owned()),
    };
    let username = match get("username") {
        Some(v) => secret(reader, v, v.span, "`username`", true).map(Some),
        None => Some(None),
    };
    let password = match get("password") {
        Some(v) => secret(reader, v, at, "`password`", false).map(Some),
        None => Some(None),
    };
    let qos = match get("qos") {
        Some(v) => reader.number::<u8>(v, "`qos`", (0, 1)),
        None => Some(1),
    };
    let queue = match get("queue") {
        Some(v) => reader.number::<usize>(v, "`queue`", (1, 1_000_000)),
        None => Some(DEFAULT_MQTT_QUEUE),
    };
    let keep_alive = match get("keep_alive") {
        Some(v) => reader.duration(v, "`keep_alive`", Duration::from_secs(5)),
        None => Some(Duration::from_secs(30)),
    };
    let homeassistant = match get("homeassistant") {
        Some(v) => match v.scalar() {
            Some("true") => Some(Some("homeassistant".to_owned())),
            Some("false") => Some(None),
            // YAML 1.1's booleans: a prefix `yes` would hide every entity from Home
            // Assistant, which listens under `homeassistant`.
            Some(word)
                if ["yes", "no", "on", "off", "y", "n"]
                    .contains(&word.to_ascii_lowercase().as_str()) =>
            {
                reader.error(
                    v.span,
                    format!("`homeassistant: {word}` reads as a discovery prefix `{word}`"),
                    "write `true` (discovery under `homeassistant`) or `false`; a prefix of \
                     your own is a topic such as `ha`",
                );
                None
            }
            _ => topic_prefix(
                reader,
                v,
                "`homeassistant` (true, false or a discovery prefix)",
            )
            .map(Some),
        },
        None => Some(None),
    };
    let state_every = match get("state_every") {
        Some(v) => state_every(reader, v, devices),
        None => Some(StateEvery::default()),
    };
    let refresh_every = match get("refresh_every") {
        Some(v) => reader.duration(v, "`refresh_every`", Duration::from_secs(1)),
        None => Some(DEFAULT_REFRESH_EVERY),
    };
    for (name, span) in devices {
        if !is_topic_level(name) {
            reader.error(
                *span,
                format!("device `{name}` cannot be an MQTT topic level"),
                "MQTT topics take a device name without `/`, `+`, `#` or control characters",
            );
            ok = false;
        }
    }
    if matches!(username, Some(None)) && matches!(password, Some(Some(_))) {
        reader.error(
            at,
            "a `password` without a `username`",
            "MQTT sends a password only with a user name",
        );
        ok = false;
    }
    let (host, port) = broker?;
    if !ok {
        return None;
    }
    Some(MqttConfig {
        host,
        port,
        client_id: client_id?,
        prefix: prefix?,
        username: username?,
        password: password?,
        ca: ca?,
        qos: qos?,
        queue: queue?,
        keep_alive: keep_alive?,
        homeassistant: homeassistant?,
        state_every: state_every?,
        refresh_every: refresh_every?,
    })
}

/// `state_every: DURATION`, or a mapping of `default` and device names to durations.
fn state_every(
    reader: &mut Reader<'_>,
    node: &Node,
    devices: &[(&str, Span)],
) -> Option<StateEvery> {
    const WHAT: &str = "`state_every`";
    if node.entries().is_none() {
        let every = reader.duration(node, WHAT, Duration::ZERO)?;
        return Some(StateEvery {
            default: every,
            devices: Vec::new(),
        });
    }
    let mut keys = vec!["default"];
    keys.extend(devices.iter().map(|(name, _)| *name));
    let pairs = reader.mapping(node, WHAT, &keys)?;
    let mut every = StateEvery::default();
    let mut ok = true;
    for (key, value) in pairs {
        let (Some(name), Some(duration)) =
            (key.scalar(), reader.duration(value, WHAT, Duration::ZERO))
        else {
            ok = false;
            continue;
        };
        if name == "default" {
            every.default = duration;
        } else if keys.contains(&name) {
            every.devices.push((name.to_owned(), duration));
        } else {
            ok = false;
        }
    }
    ok.then_some(every)
}

/// `HOST`, `HOST:PORT` or `[IPv6]:PORT`.
fn broker(reader: &mut Reader<'_>, node: &Node, tls: bool) -> Option<(String, u16)> {
    let text = reader.text(node, "`broker`")?;
    let parsed = broker_address(text, tls);
    if parsed.is_none() {
        reader.error(
            node.span,
            format!("`{}` is no broker address", text.trim()),
            "give HOST or HOST:PORT, e.g. 127.0.0.1:1883",
        );
    }
    parsed
}

fn client_id(reader: &mut Reader<'_>, node: &Node) -> Option<String> {
    let text = reader.text(node, "`client_id`")?;
    if text.is_empty() || text.len() > 256 || text.chars().any(char::is_control) {
        reader.error(
            node.span,
            "`client_id` must be 1 to 256 characters, none of them control characters",
            "e.g. `client_id: optobus-hall-2`",
        );
        return None;
    }
    Some(text.to_owned())
}

/// One or more topic levels: no wildcards, no empty level, not a `$` system topic.
fn topic_prefix(reader: &mut Reader<'_>, node: &Node, what: &str) -> Option<String> {
    let text = reader.text(node, what)?;
    if text.starts_with('$') || !text.split('/').all(is_topic_level) {
        reader.error(
            node.span,
            format!("{what} `{text}` is no topic prefix"),
            "topic levels joined by `/`, none empty, without `+`, `#` or a leading `$`",
        );
        return None;
    }
    Some(text.to_owned())
}

/// `NAME` (a user name only), `{ env: VARIABLE }` or `{ file: PATH }`.
fn secret(
    reader: &mut Reader<'_>,
    node: &Node,
    at: Span,
    what: &str,
    text_allowed: bool,
) -> Option<SecretSource> {
    if let Some(pairs) = node.entries() {
        reader.mapping(node, what, &["env", "file"])?;
        return match pairs {
            [(key, value)] if key.scalar() == Some("env") => {
                let name = reader.text(value, "`env`")?;
                if name.is_empty() || name.contains(['=', '\0']) {
                    reader.error(
                        value.span,
                        "`env` names no variable",
                        "e.g. `env: MQTT_PASSWORD`",
                    );
                    return None;
                }
                Some(SecretSource::Env(name.to_owned()))
            }
            [(key, value)] if key.scalar() == Some("file") => {
                let path = reader.text(value, "`file`")?;
                Some(SecretSource::File(reader.base().join(path)))
            }
            _ => {
                reader.error(
                    node.span,
                    format!("{what} takes one of `env` or `file`"),
                    "e.g. `{ env: MQTT_PASSWORD }` or `{ file: /run/secrets/mqtt }`",
                );
                None
            }
        };
    }
    if !text_allowed {
        // Neither echoed nor shown: the text may be the very password.
        reader.error(
            at,
            format!("{what} is never written in the bus file"),
            "give `{ env: VARIABLE }` or `{ file: PATH }`",
        );
        return None;
    }
    let text = reader.text(node, what)?;
    Some(SecretSource::Text(text.to_owned()))
}

/// Whether `level` can be one level of an MQTT topic name.
fn is_topic_level(level: &str) -> bool {
    !level.is_empty() && !level.contains(['/', '+', '#']) && !level.chars().any(char::is_control)
}
