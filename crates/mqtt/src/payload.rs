//! What a sample looks like on MQTT: JSON with the number for consumers, the exact text, the
//! unit and the reply's time.

use optobus_bus::{rfc3339, Sample};
use optobus_inspect::Value;
use serde_json::{json, Map, Value as Json};

/// The JSON of one sample: its value's members (see [`value_json`]) and `time`, the reply's
/// time in RFC 3339.
pub fn sample_json(sample: &Sample) -> Json {
    let mut object = match value_json(&sample.value) {
        Json::Object(object) => object,
        other => Map::from_iter([("value".to_owned(), other)]),
    };
    object.insert("time".into(), rfc3339(sample.replied).into());
    Json::Object(object)
}

/// A value's members: a quantity as `value` (a number, rounded once), `text` (exact) and
/// `unit`; an integer or boolean as `value`; a code as `code` and `name` (null when the
/// spec names no such code); an invalid reading as `value: null`; packed fields and record
/// members as `fields`, each shaped the same; an address or version as `text`.
pub fn value_json(value: &Value) -> Json {
    match value {
        Value::Invalid => json!({ "value": null }),
        Value::Bool(on) => json!({ "value": on }),
        Value::Integer(number) => json!({ "value": number }),
        Value::Quantity(number, unit) => {
            let mut object = Map::new();
            object.insert("value".into(), finite(number.to_f64()));
            object.insert("text".into(), number.to_string().into());
            if let Some(unit) = unit {
                object.insert("unit".into(), (*unit).into());
            }
            Json::Object(object)
        }
        Value::Code(code, name) => json!({ "code": code, "name": name }),
        Value::Fields(fields) => {
            let members: Map<String, Json> = fields
                .iter()
                .map(|(name, value)| ((*name).to_owned(), value_json(value)))
                .collect();
            json!({ "fields": members })
        }
        Value::Ipv4(_) | Value::Version(_) => json!({ "text": value.to_string() }),
    }
}

/// The JSON of a value read now (a read-back, a refresh): its members and `time`, now.
pub(crate) fn read_json(value: &Value) -> Vec<u8> {
    let mut json = value_json(value);
    if let Json::Object(object) = &mut json {
        object.insert("time".into(), rfc3339(std::time::SystemTime::now()).into());
    }
    json.to_string().into_bytes()
}

fn finite(number: f64) -> Json {
    serde_json::Number::from_f64(number).map_or(Json::Null, Json::Number)
}
