//! A buffered read-out as asked for, checked against the model's buffer before anything is
//! opened or sent: the count within what the buffer hands out, and what is buffered (a code
//! of the buffer's source register, by default its first).

use std::fmt;

use optobus_device::{BufferInfo, DeviceInfo, RegisterInfo};

/// What is buffered: a code of the buffer's source register, by raw value and name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BufferSource {
    /// The code written to the source register.
    pub code: u32,
    /// The code's name (its number where the spec names none).
    pub name: String,
}

/// A buffered read-out that the model's buffer allows.
#[derive(Clone, Debug)]
pub struct BufferRequest {
    /// The model's buffer.
    pub buffer: &'static BufferInfo,
    /// How many values to buffer and read out.
    pub count: u32,
    /// The register the values are read from (their unit and decoding).
    pub values: &'static RegisterInfo,
    /// What is buffered; `None` for a buffer of one kind of value.
    pub source: Option<BufferSource>,
}

/// Why a buffered read-out was refused, before anything was sent; `E` is why the source
/// given was not a value of the source register.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BufferRefusal<E> {
    /// The model has no data buffer.
    NoBuffer,
    /// The count is outside 1 to what the buffer hands out.
    Count {
        /// The model as its manual names it.
        model: &'static str,
        /// The count asked for.
        count: u32,
        /// The most values the buffer hands out.
        most: u32,
    },
    /// A source was given, and the buffer holds one kind of value only.
    OneKindOnly {
        /// The model as its manual names it.
        model: &'static str,
    },
    /// The spec's buffer names an item the spec lacks.
    NotInSpec(&'static str),
    /// The source register has no codes to choose from.
    NoCodes(&'static str),
    /// The source given is no value of the source register.
    Source(E),
}

impl<E: fmt::Display> fmt::Display for BufferRefusal<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoBuffer => f.write_str("the model has no data buffer"),
            Self::Count { model, most, .. } => {
                write!(f, "the {model} buffers 1 to {most} values for reading out")
            }
            Self::OneKindOnly { model } => {
                write!(f, "the {model} buffers one kind of value only")
            }
            Self::NotInSpec(name) => write!(f, "the spec has no `{name}`"),
            Self::NoCodes(name) => write!(f, "`{name}` has no codes to choose from"),
            Self::Source(error) => error.fmt(f),
        }
    }
}

impl<E: fmt::Debug + fmt::Display> std::error::Error for BufferRefusal<E> {}

/// The model as the manual names it: its title up to any parenthesis (`P series`).
fn short_title(device: &DeviceInfo) -> &'static str {
    device
        .title
        .split(" (")
        .next()
        .unwrap_or(device.title)
        .trim()
}

impl BufferRequest {
    /// `count` values of `source` (parsed against the source register by `parse`; default:
    /// its first code) from `device`'s buffer, checked in that order.
    pub fn check<E>(
        device: &'static DeviceInfo,
        count: u32,
        source: Option<&str>,
        parse: impl FnOnce(&'static RegisterInfo, &str) -> Result<u32, E>,
    ) -> Result<Self, BufferRefusal<E>> {
        let buffer = device.buffer.ok_or(BufferRefusal::NoBuffer)?;
        let model = short_title(device);
        let most = buffer.most;
        if !(1..=most).contains(&count) {
            return Err(BufferRefusal::Count { model, count, most });
        }
        let values = device
            .members(buffer.values)
            .next()
            .ok_or(BufferRefusal::NotInSpec(buffer.values))?;
        let source = match (buffer.source, source) {
            (None, Some(_)) => return Err(BufferRefusal::OneKindOnly { model }),
            (None, None) => None,
            (Some(name), given) => {
                let register = device
                    .register(name)
                    .ok_or(BufferRefusal::NotInSpec(name))?;
                let code = match given {
                    Some(text) => parse(register, text).map_err(BufferRefusal::Source)?,
                    None => register
                        .codes
                        .first()
                        .map(|c| c.code)
                        .ok_or(BufferRefusal::NoCodes(name))?,
                };
                let name = register
                    .codes
                    .iter()
                    .find(|c| c.code == code)
                    .map_or_else(|| code.to_string(), |c| c.name.to_owned());
                Some(BufferSource { code, name })
            }
        };
        Ok(Self {
            buffer,
            count,
            values,
            source,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A parser that takes codes by name only.
    fn by_name(register: &'static RegisterInfo, text: &str) -> Result<u32, String> {
        register
            .codes
            .iter()
            .find(|c| c.name == text)
            .map(|c| c.code)
            .ok_or_else(|| format!("no code `{text}`"))
    }

    /// Issue 31, buffer checks in the driver: a count outside 1 to what the buffer hands
    /// out, a source for a buffer of one kind, or a source that is no code, are refused
    /// before anything is opened; the default source is the first code, named.
    #[test]
    fn a_buffer_request_is_checked_against_the_models_buffer_before_anything_is_sent() {
        let device = &optobus_p_series::DEVICE;
        let refused = BufferRequest::check(device, 2501, None, by_name).unwrap_err();
        assert_eq!(
            refused.to_string(),
            "the P series buffers 1 to 2500 values for reading out"
        );
        assert!(matches!(
            BufferRequest::check(device, 0, None, by_name),
            Err(BufferRefusal::Count {
                count: 0,
                most: 2500,
                ..
            })
        ));
        let request = BufferRequest::check(device, 10, None, by_name).expect("allowed");
        let source_register = device
            .register(device.buffer.and_then(|b| b.source).expect("a source"))
            .expect("in the spec");
        let first = source_register.codes.first().expect("codes");
        assert_eq!(
            request.source,
            Some(BufferSource {
                code: first.code,
                name: first.name.to_owned()
            })
        );
        // The values are decoded as the first copy of the page's values member.
        assert_eq!(request.values.name, "buffer_sample_1_buffered_value");
        let refused = BufferRequest::check(device, 10, Some("nonsense"), by_name).unwrap_err();
        assert_eq!(
            refused,
            BufferRefusal::Source("no code `nonsense`".to_owned())
        );

        let no_buffer = &optobus_rangefinder::DEVICE;
        assert!(matches!(
            BufferRequest::check(no_buffer, 10, None, by_name),
            Err(BufferRefusal::NoBuffer)
        ));
    }
}
