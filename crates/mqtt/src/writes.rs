//! Writes from MQTT: `<prefix>/<device>/<register>/set` with the value as text, and
//! `<prefix>/<device>/<command>/do`, done through the bus's handle exactly as `optobus set`
//! and `optobus do` do them, for what the bus file's `writable` lists only. The value read
//! back is published to the register's topic; a refusal or failure goes to
//! `<prefix>/<device>/<name>/error` with the tool's one-line message, and then nothing was
//! sent to the device unless the device itself failed.

use std::time::SystemTime;

use optobus_bus::{rfc3339, Handle};
use rumqttc::QoS;
use serde_json::Value as Json;

use crate::outbox::{Kind, Message};
use crate::payload::value_json;
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

/// Does the write `topic` asks for in the background and hands the answers to `reply`.
pub(crate) fn handle_write(
    topics: &Topics,
    handle: &Handle,
    topic: &str,
    payload: &[u8],
    reply: impl Fn(Message) + Send + 'static,
) {
    let Some(request) = request(topics, topic) else {
        return;
    };
    let (device, name) = match request {
        Request::Set { device, register } => (device.to_owned(), register.to_owned()),
        Request::Do { device, command } => (device.to_owned(), command.to_owned()),
    };
    let is_set = matches!(request, Request::Set { .. });
    let topics = topics.clone();
    let handle = handle.clone();
    let text = std::str::from_utf8(payload)
        .map(str::trim)
        .map(str::to_owned);
    tokio::spawn(async move {
        let error = |message: String| Message {
            topic: format!("{}/error", topics.sample(&device, &name)),
            payload: message.into_bytes(),
            qos: QoS::AtLeastOnce,
            retain: false,
            kind: Kind::Reply,
        };
        if !is_set {
            if let Err(why) = handle.do_listed(&device, &name).await {
                reply(error(why.to_string()));
            }
            return;
        }
        let Ok(text) = text else {
            reply(error("the value is not UTF-8 text".to_owned()));
            return;
        };
        match handle.set_listed(&device, &name, &text).await {
            Ok(Some(value)) => {
                let mut json = value_json(&value);
                if let Json::Object(object) = &mut json {
                    object.insert("time".into(), rfc3339(SystemTime::now()).into());
                }
                reply(Message {
                    topic: topics.sample(&device, &name),
                    payload: json.to_string().into_bytes(),
                    qos: QoS::AtLeastOnce,
                    retain: false,
                    kind: Kind::Reply,
                });
            }
            Ok(None) => {}
            Err(why) => reply(error(why.to_string())),
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

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
