//! Who may ask what: the `Host` a loopback console answers to, the origins whose pages may call
//! it, and the token every request for the line's time (a write, a command, a read now: each a
//! POST with a JSON body) must carry when one is set or the console listens beyond the
//! loopback.

use std::net::SocketAddr;
use std::sync::Arc;

use axum::extract::{Request, State};
use axum::http::header::{
    ACCESS_CONTROL_ALLOW_HEADERS, ACCESS_CONTROL_ALLOW_METHODS, ACCESS_CONTROL_ALLOW_ORIGIN,
    AUTHORIZATION, HOST, ORIGIN, VARY,
};
use axum::http::{HeaderMap, HeaderValue, Method, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use optobus_bus::HttpConfig;

use crate::error::ApiError;
use crate::ConsoleError;

/// The shortest token accepted.
const TOKEN_MIN: usize = 16;

/// The token of an `Authorization` header of the `Bearer` scheme: the scheme in any case
/// (RFC 9110, 11.1), then one space or more.
fn bearer_token(authorization: &str) -> Option<&str> {
    let (scheme, token) = authorization.split_once(' ')?;
    scheme
        .eq_ignore_ascii_case("Bearer")
        .then(|| token.trim_matches(' '))
}

/// The console's rules for requests.
#[derive(Debug)]
pub(crate) struct Guard {
    /// The token writes must carry, if any.
    token: Option<String>,
    /// Whether it listens on the loopback only.
    loopback: bool,
    /// The `Host` values a loopback console answers to.
    hosts: Vec<String>,
    /// Other origins allowed.
    origins: Vec<String>,
}

impl Guard {
    pub(crate) fn new(config: &HttpConfig, address: SocketAddr) -> Result<Self, ConsoleError> {
        let token = match &config.token_file {
            Some(path) => Some(read_token(path)?),
            None => None,
        };
        let port = address.port();
        Ok(Self {
            token,
            loopback: address.ip().is_loopback(),
            hosts: vec![
                format!("127.0.0.1:{port}"),
                format!("localhost:{port}"),
                format!("[::1]:{port}"),
                address.to_string(),
            ],
            origins: config.origins.clone(),
        })
    }

    /// Whether `origin` may call the console: its own (the same host) or one listed.
    fn allows_origin(&self, origin: &str, host: Option<&str>) -> bool {
        let own = host.is_some_and(|host| origin.strip_prefix("http://") == Some(host));
        own || self.origins.iter().any(|o| o == origin)
    }

    /// Why a request for the line (a POST: write, command, read now) is refused, if it is.
    fn refuses_write(&self, headers: &HeaderMap) -> Option<ApiError> {
        let Some(token) = &self.token else {
            return (!self.loopback).then(|| {
                ApiError::new(
                    StatusCode::FORBIDDEN,
                    "writes and reads of the line are off: the console listens beyond \
                     127.0.0.1 and the bus file gives it no `token_file`",
                )
            });
        };
        let given = headers
            .get(AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .and_then(bearer_token);
        match given {
            Some(given) if same(given.as_bytes(), token.as_bytes()) => None,
            Some(_) => Some(ApiError::new(
                StatusCode::UNAUTHORIZED,
                "the token is not the console's",
            )),
            None => Some(ApiError::new(
                StatusCode::UNAUTHORIZED,
                "writes and reads of the line need the console's token (Authorization: \
                 Bearer …)",
            )),
        }
    }

    /// Whether writes and reads of the line need a token (the page asks for one).
    pub(crate) fn needs_token(&self) -> bool {
        self.token.is_some() || !self.loopback
    }
}

/// Compares in a time that does not depend on where the texts differ.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

fn read_token(path: &std::path::Path) -> Result<String, ConsoleError> {
    let refused = |why: String| ConsoleError::Token {
        path: path.to_path_buf(),
        why,
    };
    let text = std::fs::read_to_string(path).map_err(|e| refused(e.to_string()))?;
    let token = text.trim();
    if token.len() < TOKEN_MIN || !token.bytes().all(|b| b.is_ascii_graphic()) {
        return Err(refused(format!(
            "a token is at least {TOKEN_MIN} visible ASCII characters on one line"
        )));
    }
    Ok(token.to_owned())
}

/// Checks every request: its `Host` (on the loopback), its `Origin`, the token of a request for
/// the line (every POST); answers
/// a listed origin's preflight and marks its replies.
pub(crate) async fn check(
    State(guard): State<Arc<Guard>>,
    request: Request,
    next: Next,
) -> Response {
    let headers = request.headers();
    let host = headers.get(HOST).and_then(|v| v.to_str().ok());
    if guard.loopback && !host.is_some_and(|h| guard.hosts.iter().any(|known| known == h)) {
        return ApiError::new(
            StatusCode::MISDIRECTED_REQUEST,
            "the console answers requests to 127.0.0.1 or localhost only",
        )
        .into_response();
    }
    let origin = match headers.get(ORIGIN).map(|v| v.to_str()) {
        None => None,
        Some(Ok(origin)) if guard.allows_origin(origin, host) => Some(origin.to_owned()),
        Some(origin) => {
            let origin = origin.unwrap_or("?");
            return ApiError::new(
                StatusCode::FORBIDDEN,
                format!("pages of {origin} may not call this console"),
            )
            .into_response();
        }
    };
    let listed = origin.filter(|o| guard.origins.contains(o));
    if request.method() == Method::OPTIONS {
        let mut response = StatusCode::NO_CONTENT.into_response();
        allow(response.headers_mut(), listed.as_deref(), true);
        return response;
    }
    if request.method() == Method::POST {
        if let Some(refusal) = guard.refuses_write(headers) {
            return refusal.into_response();
        }
    }
    let mut response = next.run(request).await;
    allow(response.headers_mut(), listed.as_deref(), false);
    response
}

/// Marks a reply to a listed origin as readable by its page.
fn allow(headers: &mut HeaderMap, origin: Option<&str>, preflight: bool) {
    let Some(value) = origin.and_then(|o| HeaderValue::from_str(o).ok()) else {
        return;
    };
    headers.insert(ACCESS_CONTROL_ALLOW_ORIGIN, value);
    headers.insert(VARY, HeaderValue::from_static("Origin"));
    if preflight {
        headers.insert(
            ACCESS_CONTROL_ALLOW_METHODS,
            HeaderValue::from_static("GET, POST"),
        );
        headers.insert(
            ACCESS_CONTROL_ALLOW_HEADERS,
            HeaderValue::from_static("authorization, content-type"),
        );
    }
}
