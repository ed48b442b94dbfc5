//! Writes from the page: a register set from text, a command run, both through the bus's
//! allow-listed, validated path; every refusal a 4xx with the tool's one-line message.

use std::net::SocketAddr;
use std::sync::Arc;

use axum::extract::rejection::JsonRejection;
use axum::extract::{ConnectInfo, Path, State};
use axum::http::header::CONTENT_TYPE;
use axum::http::Extensions;
use axum::http::StatusCode;
use axum::response::IntoResponse;
use axum::Json;
use optobus_bus::{JobError, RefusalKind};
use serde::Deserialize;
use serde_json::value::RawValue;

use crate::error::ApiError;
use crate::reply::{Done, RegisterValue};
use crate::state::Shared;

/// `POST …/set`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Set {
    register: String,
    /// As `optobus set` takes it: `12.5 %`, `100us`, a code name; a JSON number is its text
    /// exactly as written in the body (kept raw: a float would round `0.49999999999999999999`
    /// to `0.5`).
    value: Box<RawValue>,
}

/// The most of a refused `value` quoted back.
const VALUE_EXCERPT: usize = 40;

/// The text `optobus set` would be given for `value`: a JSON string's content, a JSON number's
/// text as written; anything else is refused.
fn value_text(value: &RawValue) -> Result<String, ApiError> {
    let raw = value.get();
    match raw.as_bytes().first() {
        // A JSON number starts with a minus or a digit, and its text is already exact.
        Some(b'-' | b'0'..=b'9') => Ok(raw.to_owned()),
        Some(b'"') => serde_json::from_str(raw)
            .map_err(|e| ApiError::new(StatusCode::UNPROCESSABLE_ENTITY, format!("`value`: {e}"))),
        _ => {
            let mut shown: String = raw.chars().take(VALUE_EXCERPT).collect();
            if shown.len() < raw.len() {
                shown.push('…');
            }
            Err(ApiError::new(
                StatusCode::UNPROCESSABLE_ENTITY,
                format!("`value` is text such as \"12.5 %\" or a number, not {shown}"),
            ))
        }
    }
}

/// `POST …/do`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Do {
    command: String,
}

/// A body that is not the JSON asked for (or too large): its status and axum's one line.
pub(crate) fn body_error(rejection: JsonRejection) -> ApiError {
    let status = rejection.status();
    let message = match status {
        StatusCode::PAYLOAD_TOO_LARGE => {
            format!("the body is too large: at most {} bytes", crate::BODY_LIMIT)
        }
        _ => rejection.body_text(),
    };
    ApiError::new(status, message)
}

/// The status of a job's refusal or failure; its message is the bus's. The write policy's
/// refusals are `403` (not allowed here) or `422` (a name or value the spec refuses); a busy
/// line is a `429` with `Retry-After`.
pub(crate) fn job_error(device: &str, error: JobError) -> ApiError {
    let status = match &error {
        JobError::UnknownDevice(_) => return ApiError::unknown_device(device),
        JobError::Busy { .. } => return ApiError::busy(error.to_string()),
        JobError::Refused(refusal) => match refusal.kind() {
            RefusalKind::NotAllowed => StatusCode::FORBIDDEN,
            RefusalKind::Address | RefusalKind::Value => StatusCode::UNPROCESSABLE_ENTITY,
            RefusalKind::NoDevice => StatusCode::NOT_FOUND,
        },
        JobError::Stopped => StatusCode::SERVICE_UNAVAILABLE,
        JobError::Device(_) => StatusCode::BAD_GATEWAY,
        _ => StatusCode::INTERNAL_SERVER_ERROR,
    };
    ApiError::new(status, error.to_string())
}

/// The bus's handle with the audit trail told who asked: the client's address where the
/// listener gives it.
fn handle_for(shared: &Shared, extensions: &Extensions) -> optobus_bus::Handle {
    match extensions.get::<ConnectInfo<SocketAddr>>() {
        Some(ConnectInfo(peer)) => shared.handle.from_origin(peer),
        None => shared.handle.clone(),
    }
}

pub(crate) async fn set(
    State(shared): State<Arc<Shared>>,
    extensions: Extensions,
    Path(device): Path<String>,
    body: Result<Json<Set>, JsonRejection>,
) -> Result<Json<RegisterValue>, ApiError> {
    let Json(Set { register, value }) = body.map_err(body_error)?;
    let text = value_text(&value)?;
    let back = handle_for(&shared, &extensions)
        .set_listed(&device, &register, &text)
        .await
        .map_err(|e| job_error(&device, e))?;
    Ok(Json(RegisterValue {
        register,
        text: back
            .as_ref()
            .map_or_else(|| "written".to_owned(), ToString::to_string),
        value: back,
    }))
}

pub(crate) async fn run(
    State(shared): State<Arc<Shared>>,
    extensions: Extensions,
    Path(device): Path<String>,
    body: Result<Json<Do>, JsonRejection>,
) -> Result<Json<Done>, ApiError> {
    let Json(Do { command }) = body.map_err(body_error)?;
    handle_for(&shared, &extensions)
        .do_listed(&device, &command)
        .await
        .map_err(|e| job_error(&device, e))?;
    Ok(Json(Done {
        command,
        done: true,
    }))
}

/// `POST …/buffer`: the device's data buffer read out, as CSV: `index`, `time_s` (since the
/// first value, where the buffer's timing is known) and `value_UNIT` (empty where invalid).
pub(crate) async fn buffer(
    State(shared): State<Arc<Shared>>,
    extensions: Extensions,
    Path(device): Path<String>,
) -> Result<impl IntoResponse, ApiError> {
    let buffered = handle_for(&shared, &extensions)
        .download_buffer(&device)
        .await
        .map_err(|e| job_error(&device, e))?;
    let unit = buffered.register.unit.unwrap_or("");
    let value_column = if unit.is_empty() {
        "value".to_owned()
    } else {
        format!("value_{unit}")
    };
    let mut csv = match buffered.timing {
        Some(_) => format!("index,time_s,{value_column}\n"),
        None => format!("index,{value_column}\n"),
    };
    for (index, value) in buffered.values.iter().enumerate() {
        let value = value.as_ref().map(ToString::to_string).unwrap_or_default();
        match buffered.timing {
            Some(timing) => {
                let time = timing.time_of(index).as_secs_f64();
                csv.push_str(&format!("{index},{time},{value}\n"));
            }
            None => csv.push_str(&format!("{index},{value}\n")),
        }
    }
    Ok(([(CONTENT_TYPE, "text/csv; charset=utf-8")], csv))
}
