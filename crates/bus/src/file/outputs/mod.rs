//! The bus file's `outputs:`: where the bus serves what it reads besides its event stream.

mod http;

pub use http::{HttpConfig, DEFAULT_HTTP_PORT};

use optobus_codegen::source::Node;

use super::read::{scalar, Reader};

/// The outputs a bus file asks for.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Outputs {
    /// The console in the browser (`http:`).
    pub http: Option<HttpConfig>,
}

const OUTPUT_KEYS: &[&str] = &["http"];

impl Reader<'_> {
    /// `outputs:`, each output read and checked by its own module.
    pub(super) fn outputs(&mut self, node: &Node) -> Outputs {
        let mut outputs = Outputs::default();
        let Some(pairs) = self.mapping(node, "`outputs`", OUTPUT_KEYS) else {
            return outputs;
        };
        for (key, value) in pairs {
            if scalar(key) == Some("http") {
                outputs.http = self.http(value);
            }
        }
        outputs
    }
}
