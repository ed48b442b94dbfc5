//! Code enums for scripts: `{"code": 0, "name": "distance"}` (`"name": null` for a code the
//! manual does not define), the shape `optobus --json` prints. Generated enums implement
//! `Serialize` and `Deserialize` with these two functions (feature `serde`).

use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::convert::CodeEnum;
use crate::shapes::Code;

/// `{"code": 0, "name": "distance"}`.
pub fn serialize<V: CodeEnum, S: Serializer>(value: &V, serializer: S) -> Result<S::Ok, S::Error> {
    Code {
        code: value.to_raw(),
        name: value.name().map(Into::into),
    }
    .serialize(serializer)
}

/// The code, or the name alone; a name that contradicts the code, or that the enum does not
/// define, is refused rather than guessed.
pub fn deserialize<'de, V: CodeEnum, D: Deserializer<'de>>(deserializer: D) -> Result<V, D::Error> {
    let given = Code::deserialize(deserializer)?;
    let by_name = |name: &str| {
        V::CODES
            .iter()
            .find(|c| c.name == name)
            .map(|c| V::from_raw(c.code))
            .ok_or_else(|| D::Error::custom(format_args!("no code is named `{name}`")))
    };
    match (given.code, given.name.as_deref()) {
        (Some(code), name) => {
            let value = V::from_raw(code);
            match name {
                Some(name) if value.name() != Some(name) => Err(D::Error::custom(format_args!(
                    "code {code} is not named `{name}`"
                ))),
                _ => Ok(value),
            }
        }
        (None, Some(name)) => by_name(name),
        (None, None) => Err(D::Error::custom("a code or a name is needed")),
    }
}
