//! `outputs: metrics:`: the Prometheus endpoint.

use std::net::SocketAddr;

use optobus_spec::source::{Node, Value};

use super::super::reader::{listen_address, Reader};

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

impl Reader<'_> {
    /// `metrics: ADDRESS` or `metrics: { listen: ADDRESS }`.
    pub(super) fn metrics(&mut self, node: &Node) -> Option<MetricsConfig> {
        let listen = match &node.value {
            Value::Mapping(_) => {
                let pairs = self.mapping(node, "`metrics`", &["listen"])?;
                let Some((_, listen)) = pairs.iter().find(|(k, _)| k.scalar() == Some("listen"))
                else {
                    self.error(
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
        let text = self.text(listen, "`metrics`")?;
        match listen_address(text) {
            Some(listen) => Some(MetricsConfig { listen }),
            None => {
                self.error(
                    listen.span,
                    format!("`{text}` is no address to listen on"),
                    "give a port (listens on 127.0.0.1) or IP:PORT, e.g. 127.0.0.1:9464",
                );
                None
            }
        }
    }
}
