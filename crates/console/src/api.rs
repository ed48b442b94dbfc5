//! The routes and the JSON API's handlers.

use std::sync::atomic::Ordering;
use std::sync::Arc;

use axum::extract::rejection::JsonRejection;
use axum::extract::{DefaultBodyLimit, Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::routing::{any, get, post};
use axum::{Json, Router};
use optobus_bus::{rfc3339, Direction, Source};
use optobus_device::DeviceInfo;
use optobus_inspect::{did_you_mean, hex};

use crate::error::ApiError;
use crate::reply::{
    unix_ms, Connections, DeviceJson, DeviceMap, Devices, FrameJson, LatestSample,
    MeasurementState, Measurements, RegisterValue, Status, Values,
};
use crate::state::Shared;
use crate::{guard, map, page, stream, write, BODY_LIMIT};

pub(crate) fn router(shared: Arc<Shared>) -> Router {
    Router::new()
        .route("/", get(page::index))
        .route("/app.js", get(page::script))
        .route("/style.css", get(page::style))
        .route("/api/devices", get(devices))
        .route("/api/values", get(values))
        .route("/api/measurements", get(measurements))
        .route("/api/status", get(status))
        .route("/api/stream", get(stream::stream))
        .route("/api/devices/{device}", get(device_map))
        .route("/api/devices/{device}/frames", get(frames))
        .route("/api/devices/{device}/read", post(read))
        .route("/api/devices/{device}/read/{register}", any(read_moved))
        .route("/api/devices/{device}/set", post(write::set))
        .route("/api/devices/{device}/do", post(write::run))
        .route("/api/devices/{device}/buffer", post(write::buffer))
        .fallback(no_route)
        .layer(axum::middleware::from_fn_with_state(
            Arc::clone(&shared.guard),
            guard::check,
        ))
        .layer(DefaultBodyLimit::max(BODY_LIMIT))
        .with_state(shared)
}

/// `GET /api/devices`: each device with its health, and each line's statistics.
async fn devices(State(shared): State<Arc<Shared>>) -> Response {
    let board = shared.board();
    let devices = board
        .devices
        .iter()
        .map(|d| DeviceJson {
            health: d.health_json(),
            model: Arc::clone(&d.id.model),
            line: Arc::clone(&d.id.line),
            slave: d.id.slave,
            title: d.info.title,
        })
        .collect();
    let lines = board.lines.iter().map(|(_, json)| json).collect();
    // Sent while the board is held: the reply borrows from it.
    Json(Devices {
        devices,
        lines,
        needs_token: shared.guard.needs_token(),
    })
    .into_response()
}

/// `GET /api/values`: the latest sample of every register polled, per device, in the map's
/// order, each saying whether it is `current`: a down device's last values are not.
async fn values(State(shared): State<Arc<Shared>>) -> Response {
    let board = shared.board();
    let devices = board
        .devices
        .iter()
        .map(|device| {
            let samples = device
                .info
                .registers
                .iter()
                .filter_map(|r| device.values.get(r.name))
                .map(|(sample, current)| LatestSample {
                    sample,
                    current: *current,
                })
                .collect();
            (&*device.id.device, samples)
        })
        .collect();
    Json(Values(devices)).into_response()
}

/// `GET /api/measurements`: each of the bus file's measurements with its limits, latest value,
/// recent values and judgement counts, as the bus computed them.
async fn measurements(State(shared): State<Arc<Shared>>) -> Response {
    let board = shared.board();
    let measurements = board
        .measurements
        .iter()
        .map(|m| MeasurementState {
            measurement: &m.name,
            unit: &m.unit,
            limits: m.limits,
            latest: m.latest.as_ref(),
            history: m.history.iter().copied().collect(),
            counts: shared.handle.judgement_counts(&m.name).map(Into::into),
        })
        .collect();
    // Sent while the board is held: the reply borrows from it.
    Json(Measurements { measurements }).into_response()
}

/// `GET /api/status`: the live stream's clients and what was dropped, the console's requests
/// the lines refused as busy (answered `429`), and the listener's connections.
async fn status(State(shared): State<Arc<Shared>>) -> Json<Status> {
    Json(Status {
        stream_clients: shared.clients().len(),
        dropped_batches: shared.dropped(),
        missed_events: shared.missed.load(Ordering::Relaxed),
        busy_refusals: shared.handle.busy_refusals(Source::Console),
        connections: shared
            .connections
            .get()
            .map(|tally| Connections::from(tally.counts())),
    })
}

/// `GET /api/devices/{device}`: its register map, commands and groups.
async fn device_map(
    State(shared): State<Arc<Shared>>,
    Path(device): Path<String>,
) -> Result<Json<DeviceMap>, ApiError> {
    let info = shared
        .handle
        .device_info(&device)
        .ok_or_else(|| ApiError::unknown_device(&device))?;
    let writable = shared.handle.writable(&device).cloned().unwrap_or_default();
    Ok(Json(map::device_map(&device, info, &writable)))
}

/// `GET /api/devices/{device}/frames`: its recent frames, oldest first.
async fn frames(
    State(shared): State<Arc<Shared>>,
    Path(device): Path<String>,
) -> Result<Json<Vec<FrameJson>>, ApiError> {
    let frames = shared
        .handle
        .frames(&device)
        .map_err(|_| ApiError::unknown_device(&device))?;
    let frames = frames
        .iter()
        .map(|frame| FrameJson {
            direction: match frame.direction {
                Direction::Sent => "sent",
                Direction::Received => "received",
            },
            hex: hex(&frame.bytes),
            time: rfc3339(frame.at),
            unix_ms: unix_ms(frame.at),
            after_us: frame.after_request.map(|d| d.as_micros() as u64),
        })
        .collect();
    Ok(Json(frames))
}

/// `POST /api/devices/{device}/read`.
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct Read {
    register: String,
}

/// `POST /api/devices/{device}/read` with `{"register": "light_power"}`: reads the register
/// now, between the polls, if the write policy allows it (a register whose read changes the
/// device only where its buffer's commands are listed: `403` else). A POST with
/// a JSON body, never a simple cross-site request (an `<img>` or a form of another site cannot
/// send it), and with the token where writes need it: a read takes the line's time. A line
/// that already has the console's share of work waiting answers `429`.
async fn read(
    State(shared): State<Arc<Shared>>,
    Path(device): Path<String>,
    body: Result<Json<Read>, JsonRejection>,
) -> Result<Json<RegisterValue>, ApiError> {
    let Json(Read { register }) = body.map_err(write::body_error)?;
    let info = shared
        .handle
        .device_info(&device)
        .ok_or_else(|| ApiError::unknown_device(&device))?;
    let found = info
        .register(&register)
        .ok_or_else(|| unknown_register(info, &register, ""))?;
    let value = shared
        .handle
        .read_checked(&device, found)
        .await
        .map_err(|e| write::job_error(&device, e))?;
    Ok(Json(RegisterValue {
        register: found.name.to_owned(),
        text: value.to_string(),
        value: Some(value),
    }))
}

/// Where reads went, for a request of `/api/devices/{device}/read/{register}`.
const READ_WITH_POST: &str = "a register is read with POST /api/devices/{device}/read and a \
                              JSON body {\"register\": \"…\"}";

/// A `404` for a register `info` does not have, with the nearest names as the CLI gives
/// them (`did you mean …?`), then `more` (where it is not empty).
fn unknown_register(info: &DeviceInfo, name: &str, more: &str) -> ApiError {
    let mut message = format!("{} has no register `{name}`", info.model_name());
    let names = info.registers.iter().map(|register| register.name);
    if let Some(hint) = did_you_mean(name, names) {
        message.push_str("; ");
        message.push_str(&hint);
    }
    if !more.is_empty() {
        message.push_str(" (");
        message.push_str(more);
        message.push(')');
    }
    ApiError::not_found(message)
}

/// `/api/devices/{device}/read/{register}`, which a GET once read: refused with where reads
/// went (`405`), or `404` with a "did you mean" where the device or register is not there.
async fn read_moved(
    State(shared): State<Arc<Shared>>,
    Path((device, register)): Path<(String, String)>,
) -> ApiError {
    let Some(info) = shared.handle.device_info(&device) else {
        return ApiError::unknown_device(&device);
    };
    if info.register(&register).is_none() {
        return unknown_register(info, &register, READ_WITH_POST);
    }
    ApiError::new(StatusCode::METHOD_NOT_ALLOWED, READ_WITH_POST)
}

/// Any other path: a `404` in the API's own shape, saying where the routes are listed.
async fn no_route() -> ApiError {
    ApiError::not_found(
        "no such route: the console's routes are listed in its README (GET /api/devices, \
         POST /api/devices/{device}/set, …)",
    )
}
