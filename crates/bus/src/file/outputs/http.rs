//! `outputs: { http: … }`: the console's address, its write token and the origins it trusts.

use std::net::SocketAddr;
use std::path::PathBuf;

use optobus_codegen::source::{Node, Value};

use crate::file::reader::{listen_address, scalar, Reader};

/// Where the console listens when the file gives `http: true`.
pub const DEFAULT_HTTP_PORT: u16 = 8080;

const HTTP_KEYS: &[&str] = &["listen", "token_file", "origins"];
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
}

impl HttpConfig {
    /// A console on `listen`, no token, no other origin.
    pub fn new(listen: SocketAddr) -> Self {
        Self {
            listen,
            token_file: None,
            origins: Vec::new(),
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

impl Reader<'_> {
    pub(super) fn http(&mut self, node: &Node) -> Option<HttpConfig> {
        let (listen_node, pairs) = match &node.value {
            Value::Mapping(_) => {
                let pairs = self.mapping(node, "`http`", HTTP_KEYS)?;
                let listen = pairs
                    .iter()
                    .find(|(k, _)| scalar(k) == Some("listen"))
                    .map(|(_, v)| v);
                (listen, pairs)
            }
            _ => (Some(node), &[][..]),
        };
        let listen = match listen_node {
            None => Some(SocketAddr::from(([127, 0, 0, 1], DEFAULT_HTTP_PORT))),
            Some(node) if scalar(node) == Some("true") => {
                Some(SocketAddr::from(([127, 0, 0, 1], DEFAULT_HTTP_PORT)))
            }
            Some(node) => {
                let text = self.text(node, "`http`");
                let listen = text.and_then(listen_address);
                if let (Some(text), None) = (text, listen) {
                    self.error(
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
                .find(|(k, _)| scalar(k) == Some(key))
                .map(|(_, v)| v)
        };
        let token_file = get("token_file")
            .and_then(|v| self.text(v, "`token_file`"))
            .map(|path| self.base.join(path.trim()));
        let mut origins = Vec::new();
        if let Some(v) = get("origins") {
            for item in self.list(v, "`origins`").unwrap_or_default() {
                let Some(text) = self.text(item, "an origin") else {
                    continue;
                };
                let origin = text.trim().trim_end_matches('/');
                if is_origin(origin) {
                    origins.push(origin.to_owned());
                } else {
                    self.error(
                        item.span,
                        format!("`{text}` is no origin"),
                        "an origin is a scheme, a host and maybe a port: `https://scada.example:8443`",
                    );
                }
            }
        }
        Some(HttpConfig {
            listen: listen?,
            token_file,
            origins,
        })
    }
}
