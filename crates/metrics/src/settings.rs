//! The metrics output's settings, `outputs: metrics:` of a bus file: where `/metrics` is
//! served. Read here with the bus file's reading kit, as the file is read.

use std::net::SocketAddr;

use optobus_bus::file::reading::{listen_address, Node, Reader, Value};
use optobus_bus::file::{OutputSettings, Outputs};

/// The section of `outputs` these settings are read from.
pub const SECTION: &str = "metrics";

/// Every key the section takes (besides an address alone, `metrics: ADDRESS`).
pub const KEYS: &[&str] = &["listen"];

/// Where `/metrics` is served.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MetricsConfig {
    /// The address it listens on (127.0.0.1 unless the file names another).
    pub listen: SocketAddr,
}

impl MetricsConfig {
    /// Where `metrics: TEXT` listens: a port alone (on 127.0.0.1) or `IP:PORT`.
    pub fn for_address(text: &str) -> Result<Self, String> {
        listen_address(text)
            .map(|listen| Self { listen })
            .ok_or_else(|| {
                format!(
                    "`{text}` is no address to listen on: give a port (on 127.0.0.1) or IP:PORT"
                )
            })
    }
}

impl OutputSettings for MetricsConfig {
    const SECTION: &'static str = SECTION;

    fn read(outputs: &Outputs<'_>, reader: &mut Reader<'_>) -> Option<Self> {
        let (_, node) = outputs.section(SECTION)?;
        metrics(reader, node)
    }
}

/// `metrics: ADDRESS` or `metrics: { listen: ADDRESS }`.
fn metrics(reader: &mut Reader<'_>, node: &Node) -> Option<MetricsConfig> {
    let listen = match &node.value {
        Value::Mapping(_) => {
            let pairs = reader.mapping(node, "`metrics`", KEYS)?;
            let Some((_, listen)) = pairs.iter().find(|(k, _)| k.scalar() == Some("listen")) else {
                reader.error(
                    node.span,
                    "`metrics` needs `listen`",
                    "e.g. `listen: 127.0.0.1:9464`",
                );
                return None;
            };
            listen
        }
        _ => node,
    };
    let text = reader.text(listen, "`metrics`")?;
    match listen_address(text) {
        Some(listen) => Some(MetricsConfig { listen }),
        None => {
            reader.error(
                listen.span,
                format!("`{text}` is no address to listen on"),
                "give a port (listens on 127.0.0.1) or IP:PORT, e.g. 127.0.0.1:9464",
            );
            None
        }
    }
}
