//! The console's settings, `outputs: { http: … }` of a bus file: its address, its write
//! token, the origins it trusts and the `Host` names it answers. Read here with the bus
//! file's reading kit, as the file is read.

use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr};
use std::path::PathBuf;

use optobus_bus::file::reading::{listen_address, Node, Reader, Value};
use optobus_bus::file::{OutputSettings, Outputs};

/// The section of `outputs` these settings are read from.
pub const SECTION: &str = "http";

/// Where the console listens when the file gives `http: true`.
pub const DEFAULT_HTTP_PORT: u16 = 8080;

/// Every key the section takes (besides an address alone, `http: ADDRESS`).
pub const KEYS: &[&str] = &["listen", "token_file", "origins", "hosts"];
const HELP: &str =
    "e.g. `http: 127.0.0.1:8080`, or `http: { listen: 0.0.0.0:8080, token_file: console.token }`";

/// The console in the browser, as the bus file gives it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HttpConfig {
    /// Where it listens (127.0.0.1 unless the file names another address).
    pub listen: SocketAddr,
    /// A file holding the token every write must carry (relative paths are the bus file's
    /// folder's); without it, a console listening beyond the loopback refuses every write.
    pub token_file: Option<PathBuf>,
    /// Origins (`scheme://host[:port]`) besides the console's own whose pages may call it.
    pub origins: Vec<String>,
    /// The `Host` names it answers besides the loopback's (against DNS rebinding), in
    /// lowercase: `name`, `name:port`, an IPv4 address or a bracketed IPv6 one, maybe with a
    /// port (without one, the console's). Empty: the address it listens on, or any IP address
    /// at its port when that is 0.0.0.0 or `::`.
    pub hosts: Vec<String>,
}

impl HttpConfig {
    /// A console on `listen`, no token, no other origin.
    pub fn new(listen: SocketAddr) -> Self {
        Self {
            listen,
            token_file: None,
            origins: Vec::new(),
            hosts: Vec::new(),
        }
    }
}

/// Whether `origin` is `http://` or `https://`, a host, and maybe a port: nothing more.
fn is_origin(origin: &str) -> bool {
    let Some(rest) = origin
        .strip_prefix("http://")
        .or_else(|| origin.strip_prefix("https://"))
    else {
        return false;
    };
    !rest.is_empty()
        && rest
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"-.:[]".contains(&b))
}

/// `text` as the console's `hosts:` keeps it (in lowercase), if it names a host as a `Host`
/// header does: a DNS name, an IPv4 address or a bracketed IPv6 one, maybe with `:PORT`.
fn host_name(text: &str) -> Option<String> {
    let port_ok = |port: &str| {
        port.bytes().all(|b| b.is_ascii_digit()) && port.parse::<u16>().is_ok_and(|p| p > 0)
    };
    if let Some(rest) = text.strip_prefix('[') {
        let (address, after) = rest.split_once(']')?;
        address.parse::<Ipv6Addr>().ok()?;
        if !(after.is_empty() || after.strip_prefix(':').is_some_and(port_ok)) {
            return None;
        }
        return Some(text.to_ascii_lowercase());
    }
    let (host, port) = match text.split_once(':') {
        Some((host, port)) => (host, Some(port)),
        None => (text, None),
    };
    if port.is_some_and(|port| !port_ok(port)) {
        return None;
    }
    let label_ok = |label: &str| {
        (1..=63).contains(&label.len())
            && !label.starts_with('-')
            && !label.ends_with('-')
            && label
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
    };
    let name_ok = host.len() <= 253 && host.split('.').all(label_ok);
    (host.parse::<Ipv4Addr>().is_ok() || name_ok).then(|| text.to_ascii_lowercase())
}

impl OutputSettings for HttpConfig {
    const SECTION: &'static str = SECTION;

    fn read(outputs: &Outputs<'_>, reader: &mut Reader<'_>) -> Option<Self> {
        let (_, node) = outputs.section(SECTION)?;
        http(reader, node)
    }
}

/// `http: true`, `http: ADDRESS` or `http: { listen: ADDRESS, token_file, origins, hosts }`.
fn http(reader: &mut Reader<'_>, node: &Node) -> Option<HttpConfig> {
    let (listen_node, pairs) = match &node.value {
        Value::Mapping(_) => {
            let pairs = reader.mapping(node, "`http`", KEYS)?;
            let listen = pairs
                .iter()
                .find(|(k, _)| k.scalar() == Some("listen"))
                .map(|(_, v)| v);
            (listen, pairs)
        }
        _ => (Some(node), &[][..]),
    };
    let listen = match listen_node {
        None => Some(SocketAddr::from(([127, 0, 0, 1], DEFAULT_HTTP_PORT))),
        Some(node) if node.scalar() == Some("true") => {
            Some(SocketAddr::from(([127, 0, 0, 1], DEFAULT_HTTP_PORT)))
        }
        Some(node) => {
            let text = reader.text(node, "`http`");
            let listen = text.and_then(listen_address);
            if let (Some(text), None) = (text, listen) {
                reader.error(
                    node.span,
                    format!("`{text}` is no address to listen on"),
                    HELP,
                );
            }
            listen
        }
    };
    let get = |key: &str| {
        pairs
            .iter()
            .find(|(k, _)| k.scalar() == Some(key))
            .map(|(_, v)| v)
    };
    let token_file = get("token_file")
        .and_then(|v| reader.text(v, "`token_file`"))
        .map(|path| reader.base().join(path.trim()));
    let mut origins = Vec::new();
    if let Some(v) = get("origins") {
        for item in reader.list(v, "`origins`").unwrap_or_default() {
            let Some(text) = reader.text(item, "an origin") else {
                continue;
            };
            let origin = text.trim().trim_end_matches('/');
            if is_origin(origin) {
                origins.push(origin.to_owned());
            } else {
                reader.error(
                    item.span,
                    format!("`{text}` is no origin"),
                    "an origin is a scheme, a host and maybe a port: `https://scada.example:8443`",
                );
            }
        }
    }
    let mut hosts = Vec::new();
    if let Some(v) = get("hosts") {
        let items = reader.list(v, "`hosts`").unwrap_or_default();
        if items.is_empty() && matches!(v.value, Value::Sequence(_)) {
            reader.error(
                v.span,
                "`hosts` lists no name",
                "leave `hosts` out to answer the address the console listens on",
            );
        }
        for item in items {
            let Some(text) = reader.text(item, "a host name") else {
                continue;
            };
            match host_name(text.trim()) {
                Some(host) => hosts.push(host),
                None => reader.error(
                    item.span,
                    format!("`{text}` is no host name"),
                    "a host is a DNS name or an IP address (IPv6 in brackets), maybe with a \
                     port: `plant-gw.example`, `192.0.2.7:8080`, `[2001:db8::7]`",
                ),
            }
        }
    }
    Some(HttpConfig {
        listen: listen?,
        token_file,
        origins,
        hosts,
    })
}
