//! User names and passwords, read from where the bus file says, never shown.

use std::fmt;

use crate::settings::SecretSource;

/// A secret's text; its `Debug` and `Display` never show it.
#[derive(Clone, PartialEq, Eq)]
pub struct Secret(String);

impl Secret {
    /// Reads the secret `source` names: an environment variable, or the first line of a file.
    pub fn read(source: &SecretSource) -> Result<Self, SecretError> {
        match source {
            SecretSource::Text(text) => Ok(Self(text.clone())),
            SecretSource::Env(name) => std::env::var(name)
                .map(Self)
                .map_err(|_| SecretError::Env(name.clone())),
            SecretSource::File(path) => match std::fs::read_to_string(path) {
                Ok(text) => Ok(Self(text.lines().next().unwrap_or("").to_owned())),
                Err(error) => Err(SecretError::File(path.display().to_string(), error.kind())),
            },
        }
    }

    /// The text, for the MQTT CONNECT packet only.
    pub(crate) fn expose(&self) -> &str {
        &self.0
    }
}

impl fmt::Debug for Secret {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Secret(..)")
    }
}

/// Why a secret could not be read (it names where it was looked for, never a value).
#[derive(Debug)]
#[non_exhaustive]
pub enum SecretError {
    /// The environment variable is not set (or not UTF-8).
    Env(String),
    /// The file cannot be read.
    File(String, std::io::ErrorKind),
}

impl fmt::Display for SecretError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Env(name) => write!(f, "the environment variable {name} is not set"),
            Self::File(path, kind) => write!(f, "cannot read {path}: {kind}"),
        }
    }
}

impl std::error::Error for SecretError {}
