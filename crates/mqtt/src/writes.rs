//! Writes from MQTT: `<prefix>/<device>/<register>/set` with the value as text, and
//! `<prefix>/<device>/<command>/do`, done through the bus's handle exactly as `optobus set`
//! and `optobus do` do them, for what the bus file's `writable` lists only. The value read
//! back is published to the register's topic; a refusal or failure goes to
//! `<prefix>/<device>/<name>/error` with the tool's one-line message, and then nothing was
//! sent to the device unless the device itself failed.

use optobus_bus::{Handle, JobError, NETWORK_QUEUE};
use rumqttc::QoS;
use tokio::sync::mpsc;

use crate::outbox::{Kind, Message};
use crate::payload::read_json;
use crate::text::excerpt;
use crate::topics::Topics;

/// What a message on a write topic asks for.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum Request<'a> {
    /// Set a register from text.
    Set { device: &'a str, register: &'a str },
    /// Run a command.
    Do { device: &'a str, command: &'a str },
}

/// The request `topic` carries, if it is a write topic under `prefix`.
pub(crate) fn request<'a>(topics: &Topics, topic: &'a str) -> Option<Request<'a>> {
    let rest = topic.strip_prefix(topics.prefix())?.strip_prefix('/')?;
    let mut levels = rest.split('/');
    let (device, name, verb) = (levels.next()?, levels.next()?, levels.next()?);
    if levels.next().is_some() {
        return None;
    }
    match verb {
        "set" => Some(Request::Set {
            device,
            register: name,
        }),
        "do" => Some(Request::Do {
            device,
            command: name,
        }),
        _ => None,
    }
}

/// The largest payload taken on a write topic: a value as `optobus set` takes it is a few
/// dozen bytes. A larger one is refused on `…/error` without being read as a value, and the
/// refusal never repeats it.
pub const MAX_WRITE_PAYLOAD: usize = 4 * 1024;

/// Writes from MQTT waiting for their turn; they are done one at a time, in the order they
/// came, by one task. One more is refused at once on `…/error` as busy (counted).
pub const WRITE_QUEUE: usize = NETWORK_QUEUE;

/// How much of a value an `…/error` message quotes at most.
const VALUE_EXCERPT: usize = 40;

/// The longest `…/error` message (a device or register name from the topic may be long).
const MAX_ERROR_TEXT: usize = 400;

/// A write taken from a topic, waiting for its turn.
#[derive(Debug)]
pub(crate) struct Write {
    device: String,
    name: String,
    /// The payload of a `/set` (`None` for a `/do`), at most [`MAX_WRITE_PAYLOAD`] bytes.
    value: Option<Vec<u8>>,
}

/// What became of a message on a subscribed topic.
#[derive(Debug)]
pub(crate) enum Taken {
    /// Not a write topic.
    NotAWrite,
    /// Queued for the writer.
    Queued,
    /// Refused at once: its payload is over [`MAX_WRITE_PAYLOAD`].
    TooLarge(Message),
    /// Refused at once: it came retained.
    Retained(Message),
    /// Refused at once: [`WRITE_QUEUE`] writes already wait.
    Busy(Message),
}

/// Takes the message on `topic` as a write if it is one: checked (retain flag, size) and
/// queued for the writer, or refused at once with the answer to publish.
pub(crate) fn take(
    topics: &Topics,
    queue: &mpsc::Sender<Write>,
    topic: &str,
    payload: &[u8],
    retained: bool,
) -> Taken {
    let Some(request) = request(topics, topic) else {
        return Taken::NotAWrite;
    };
    let (device, name, is_set) = match request {
        Request::Set { device, register } => (device, register, true),
        Request::Do { device, command } => (device, command, false),
    };
    if retained {
        return Taken::Retained(error(
            topics,
            device,
            name,
            "a retained write is not carried out (the broker would hand it over again at every \
             connection); nothing was sent: publish it without the retain flag, and clear the \
             retained one with an empty retained message on this topic",
        ));
    }
    if payload.len() > MAX_WRITE_PAYLOAD {
        return Taken::TooLarge(error(
            topics,
            device,
            name,
            &format!(
                "the payload is {} bytes, over the {MAX_WRITE_PAYLOAD} bytes a write takes; \
                 nothing was sent",
                payload.len()
            ),
        ));
    }
    let write = Write {
        device: device.to_owned(),
        name: name.to_owned(),
        value: is_set.then(|| payload.to_vec()),
    };
    match queue.try_send(write) {
        Ok(()) => Taken::Queued,
        // A writer that stopped takes nothing more: the same answer.
        Err(_) => Taken::Busy(error(
            topics,
            device,
            name,
            &format!(
                "{WRITE_QUEUE} writes from MQTT already wait for their turn; nothing was sent, \
                 try again later"
            ),
        )),
    }
}

/// What a write done by the bus gives.
#[derive(Debug)]
pub(crate) struct Done {
    /// The value read back (on the register's topic) or why it failed (on `…/error`).
    pub(crate) reply: Option<Message>,
    /// The line refused it as busy (its queue for MQTT was full).
    pub(crate) busy: bool,
    /// The value read back for the register's state topic: (topic, payload).
    pub(crate) state: Option<(String, Vec<u8>)>,
}

/// Does `write` through `handle` (whose source is MQTT) as `optobus set` or `optobus do`
/// would.
pub(crate) async fn carry_out(handle: &Handle, topics: &Topics, write: Write) -> Done {
    let Write {
        device,
        name,
        value,
    } = write;
    let failed = |why: JobError, value: Option<&str>| Done {
        busy: matches!(why, JobError::Busy { .. }),
        state: None,
        reply: Some(error(
            topics,
            &device,
            &name,
            &quoting_at_most(&why.to_string(), value),
        )),
    };
    let Some(value) = value else {
        return match handle.do_listed(&device, &name).await {
            Ok(()) => Done {
                reply: None,
                busy: false,
                state: None,
            },
            Err(why) => failed(why, None),
        };
    };
    let Ok(text) = std::str::from_utf8(&value).map(str::trim) else {
        return Done {
            reply: Some(error(topics, &device, &name, "the value is not UTF-8 text")),
            busy: false,
            state: None,
        };
    };
    match handle.set_listed(&device, &name, text).await {
        Ok(Some(value)) => {
            let payload = read_json(&value);
            Done {
                state: Some((topics.state(&device, &name), payload.clone())),
                reply: Some(Message {
                    topic: topics.sample(&device, &name),
                    payload,
                    qos: QoS::AtLeastOnce,
                    retain: false,
                    kind: Kind::Reply,
                }),
                busy: false,
            }
        }
        Ok(None) => Done {
            reply: None,
            busy: false,
            state: None,
        },
        Err(why) => failed(why, Some(text)),
    }
}

/// An answer on `<prefix>/<device>/<name>/error`, at most [`MAX_ERROR_TEXT`] bytes.
fn error(topics: &Topics, device: &str, name: &str, why: &str) -> Message {
    Message {
        topic: format!("{}/error", topics.sample(device, name)),
        payload: excerpt(why, MAX_ERROR_TEXT).into_owned().into_bytes(),
        qos: QoS::AtLeastOnce,
        retain: false,
        kind: Kind::Reply,
    }
}

/// `message`, where it quotes `value`, quoting at most [`VALUE_EXCERPT`] bytes of it.
fn quoting_at_most(message: &str, value: Option<&str>) -> String {
    match value {
        Some(value) if value.len() > VALUE_EXCERPT => {
            message.replace(value, &excerpt(value, VALUE_EXCERPT))
        }
        _ => message.to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_refusal_quotes_a_long_value_cut_short() {
        let long = "9".repeat(3000);
        let message = format!("`{long}` is not a number");
        let quoted = quoting_at_most(&message, Some(&long));
        assert_eq!(
            quoted,
            format!("`{}…` is not a number", "9".repeat(VALUE_EXCERPT))
        );
    }

    #[test]
    fn write_topics_name_the_device_and_register_or_command() {
        let topics = Topics::new("plant/hall");
        assert_eq!(
            request(&topics, "plant/hall/top/light_power/set"),
            Some(Request::Set {
                device: "top",
                register: "light_power"
            })
        );
        assert_eq!(
            request(&topics, "plant/hall/top/zero/do"),
            Some(Request::Do {
                device: "top",
                command: "zero"
            })
        );
        for other in [
            "plant/hall/top/light_power",
            "plant/hall/top/light_power/set/more",
            "plant/other/top/light_power/set",
            "plant/hallway/top/x/set",
        ] {
            assert_eq!(request(&topics, other), None, "{other}");
        }
    }
}
