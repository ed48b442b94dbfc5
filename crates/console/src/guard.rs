//! Who may ask what: the `Host` names the console answers to, the origins whose pages may call
//! it, and the token every request for the line's time (a write, a command, a read now: each a
//! POST with a JSON body) must carry when one is set or the console listens beyond the
//! loopback.

use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr};
use std::sync::Arc;

use crate::settings::HttpConfig;
use axum::extract::{ConnectInfo, Request, State};
use axum::http::header::{
    ACCESS_CONTROL_ALLOW_HEADERS, ACCESS_CONTROL_ALLOW_METHODS, ACCESS_CONTROL_ALLOW_ORIGIN,
    AUTHORIZATION, HOST, ORIGIN, VARY,
};
use axum::http::{HeaderMap, HeaderValue, Method, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use crate::error::ApiError;
use crate::ConsoleError;

/// The shortest token accepted.
const TOKEN_MIN: usize = 16;

/// The most of a refused `Host` quoted back.
const HOST_EXCERPT: usize = 40;

/// The port a `Host` without one means (the console speaks plain HTTP).
const HTTP_PORT: u16 = 80;

/// A host as a `Host` header or the bus file's `hosts:` names it.
#[derive(Debug, PartialEq, Eq)]
enum Name {
    /// A DNS name, in lowercase (names are compared without case).
    Dns(String),
    /// An IP address: `192.0.2.7`, or `[2001:db8::7]` in a `Host`.
    Ip(IpAddr),
}

/// The host and port of `text` (`name`, `name:port`, `192.0.2.7:80`, `[::1]:8080`), the port
/// `default_port` where none is given; `None` for what names no host.
fn host_and_port(text: &str, default_port: u16) -> Option<(Name, u16)> {
    let port = |digits: &str| {
        (!digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit()))
            .then(|| digits.parse::<u16>().ok())
            .flatten()
    };
    if let Some(rest) = text.strip_prefix('[') {
        let (address, after) = rest.split_once(']')?;
        let ip = address.parse::<Ipv6Addr>().ok()?;
        let port = match after {
            "" => default_port,
            after => port(after.strip_prefix(':')?)?,
        };
        return Some((Name::Ip(ip.into()), port));
    }
    let (host, port) = match text.split_once(':') {
        Some((host, digits)) => (host, port(digits)?),
        None => (text, default_port),
    };
    if host.is_empty() {
        return None;
    }
    let name = match host.parse::<Ipv4Addr>() {
        Ok(ip) => Name::Ip(ip.into()),
        Err(_) => Name::Dns(host.to_ascii_lowercase()),
    };
    Some((name, port))
}

/// The `Host` names a console answers to, against DNS rebinding: a page of another site whose
/// name was made to resolve to the console's address still sends its own name as `Host`.
#[derive(Debug)]
struct Hosts {
    /// The port the console listens on.
    port: u16,
    /// Whether any IP address at `port` is answered.
    any_address: bool,
    /// The hosts and ports answered besides.
    names: Vec<(Name, u16)>,
}

impl Hosts {
    /// The names a console listening on `address` answers: the loopback's always (no page of
    /// another site can carry them), then `listed` (the bus file's `hosts:`) or by default the
    /// address it listens on.
    fn new(address: SocketAddr, listed: &[String]) -> Result<Self, ConsoleError> {
        let port = address.port();
        let mut names = vec![
            (Name::Ip(Ipv4Addr::LOCALHOST.into()), port),
            (Name::Dns("localhost".into()), port),
            (Name::Ip(Ipv6Addr::LOCALHOST.into()), port),
        ];
        for text in listed {
            let name = host_and_port(text.trim(), port)
                .ok_or_else(|| ConsoleError::Host { host: text.clone() })?;
            names.push(name);
        }
        // Bound to every address (0.0.0.0, ::), it cannot know which of the machine's
        // addresses it is reached at; an IP address as `Host` is safe, since DNS rebinding
        // needs a DNS name: the attacker's page is called by the attacker's name.
        let any_address = listed.is_empty() && address.ip().is_unspecified();
        if listed.is_empty() && !any_address {
            names.push((Name::Ip(address.ip()), port));
        }
        Ok(Self {
            port,
            any_address,
            names,
        })
    }

    /// Whether `host` (a `Host` header's value) is one the console answers.
    fn answers(&self, host: &str) -> bool {
        let Some((name, port)) = host_and_port(host, HTTP_PORT) else {
            return false;
        };
        (self.any_address && port == self.port && matches!(name, Name::Ip(_)))
            || self.names.iter().any(|(n, p)| *n == name && *p == port)
    }
}

/// The refusal of a request for a `Host` the console does not answer (never quoting more
/// than [`HOST_EXCERPT`] characters of it).
fn misdirected(host: Option<&str>) -> ApiError {
    let named = match host.filter(|h| !h.is_empty()) {
        None => "without a `Host`".to_owned(),
        Some(host) => {
            let mut shown: String = host.chars().take(HOST_EXCERPT).collect();
            if shown.len() < host.len() {
                shown.push('…');
            }
            format!("for `{shown}`")
        }
    };
    ApiError::new(
        StatusCode::MISDIRECTED_REQUEST,
        format!(
            "the console does not answer requests {named}: a name it answers is listed in \
             `hosts:` of the bus file's `http:` (against DNS rebinding)"
        ),
    )
}

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
    /// The `Host` names it answers to.
    hosts: Hosts,
    /// Other origins allowed.
    origins: Vec<String>,
}

impl Guard {
    pub(crate) fn new(config: &HttpConfig, address: SocketAddr) -> Result<Self, ConsoleError> {
        let token = match &config.token_file {
            Some(path) => Some(read_token(path)?),
            None => None,
        };
        if token.is_none() && !address.ip().is_loopback() {
            tracing::warn!(
                target: "optobus_console",
                "the console listens on {address}, beyond 127.0.0.1, without a `token_file`: \
                 writes and reads of the line are off"
            );
        }
        Ok(Self {
            token,
            loopback: address.ip().is_loopback(),
            hosts: Hosts::new(address, &config.hosts)?,
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

/// Checks every request: its `Host`, its `Origin`, the token of a request for the line (every
/// POST); answers a listed origin's preflight and marks its replies.
pub(crate) async fn check(
    State(guard): State<Arc<Guard>>,
    request: Request,
    next: Next,
) -> Response {
    let headers = request.headers();
    let host = headers.get(HOST).and_then(|v| v.to_str().ok());
    if !host.is_some_and(|h| guard.hosts.answers(h)) {
        return refused(&request, misdirected(host));
    }
    let origin = match headers.get(ORIGIN).map(|v| v.to_str()) {
        None => None,
        Some(Ok(origin)) if guard.allows_origin(origin, host) => Some(origin.to_owned()),
        Some(origin) => {
            let origin: String = origin.unwrap_or("?").chars().take(EXCERPT).collect();
            let refusal = ApiError::new(
                StatusCode::FORBIDDEN,
                format!("pages of {origin} may not call this console"),
            );
            return refused(&request, refusal);
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
            return refused(&request, refusal);
        }
    }
    let mut response = next.run(request).await;
    allow(response.headers_mut(), listed.as_deref(), false);
    response
}

/// The most of a request's path or origin a log line or a message quotes.
const EXCERPT: usize = 80;

/// Refuses `request` with `refusal`, told in the audit trail: who asked what, and why not.
fn refused(request: &Request, refusal: ApiError) -> Response {
    let who = match request.extensions().get::<ConnectInfo<SocketAddr>>() {
        Some(ConnectInfo(peer)) => format!("console {peer}"),
        None => "console".to_owned(),
    };
    let path: String = request.uri().path().chars().take(EXCERPT).collect();
    tracing::warn!(
        target: optobus_bus::AUDIT_TARGET,
        "{who}: {} {path}: refused, {}: {}",
        request.method(),
        refusal.status.as_u16(),
        refusal.message
    );
    refusal.into_response()
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
