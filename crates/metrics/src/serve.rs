//! `/metrics` over HTTP, and the task that feeds the metrics from the bus.

use std::net::SocketAddr;
use std::sync::Arc;

use axum::extract::State;
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::IntoResponse;
use axum::routing::get;
use axum::Router;
use optobus_bus::{BusFile, Event, Follower};

use crate::settings::MetricsConfig;
use optobus_http::Limits;
use tokio::net::TcpListener;
use tokio::sync::broadcast;
use tokio::task::JoinHandle;

use crate::exposition::{OPENMETRICS_TYPE, PROMETHEUS_TEXT_TYPE};
use crate::{Metrics, Reading};

/// The limits of the `/metrics` listener: those of every listener ([`Limits::DEFAULT`]: a
/// silent socket or a half-sent head closed within 10 s, an idle connection after 15 s, an answer
/// within 20 s) with at most 32 connections, which a few scrapers never reach.
pub const LIMITS: Limits = Limits {
    max_connections: 32,
    ..Limits::DEFAULT
};

fn router(metrics: Arc<Metrics>) -> Router {
    Router::new()
        .route("/", get(index))
        .route("/metrics", get(scrape))
        .fallback(not_found)
        .with_state(metrics)
}

/// The page at `/`, for whoever opens the listener's address in a browser.
const INDEX: &str = "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>optobus metrics</title></head>\n\
<body><h1>optobus metrics</h1><p>Prometheus metrics of the bus are at <a href=\"/metrics\">/metrics</a>.</p></body></html>\n";

async fn index() -> impl IntoResponse {
    ([(header::CONTENT_TYPE, "text/html; charset=utf-8")], INDEX)
}

/// Any other path: 404, saying where the metrics are.
async fn not_found() -> impl IntoResponse {
    (
        StatusCode::NOT_FOUND,
        [(header::CONTENT_TYPE, "text/plain; charset=utf-8")],
        "Not found: the metrics are at /metrics.\n",
    )
}

/// Answers `GET /metrics` on `listener` with `metrics`, with the listener's [`LIMITS`], until
/// the task is dropped (and `GET /` with a page linking it): OpenMetrics to a scraper that asks for it (`Accept:
/// application/openmetrics-text`), the Prometheus text format otherwise.
pub async fn serve(listener: TcpListener, metrics: Arc<Metrics>) -> std::io::Result<()> {
    optobus_http::serve(listener, router(metrics), LIMITS).await;
    Ok(())
}

async fn scrape(State(metrics): State<Arc<Metrics>>, headers: HeaderMap) -> impl IntoResponse {
    let openmetrics = headers
        .get_all(header::ACCEPT)
        .iter()
        .filter_map(|value| value.to_str().ok())
        .any(|value| value.contains("application/openmetrics-text"));
    if openmetrics {
        (
            [(header::CONTENT_TYPE, OPENMETRICS_TYPE)],
            metrics.openmetrics(),
        )
    } else {
        (
            [(header::CONTENT_TYPE, PROMETHEUS_TEXT_TYPE)],
            metrics.prometheus(),
        )
    }
}

/// A running exporter: the task that follows the bus's events and the HTTP server. Dropping
/// it stops both.
#[derive(Debug)]
pub struct Exporter {
    metrics: Arc<Metrics>,
    follow: JoinHandle<()>,
    server: optobus_http::Server,
}

impl Exporter {
    /// Listens on `config.listen` and follows `events` (subscribe before the bus starts to miss
    /// no event). Fails only when the address cannot be listened on.
    pub async fn start(
        config: &MetricsConfig,
        file: &BusFile,
        events: broadcast::Receiver<Event>,
    ) -> std::io::Result<Self> {
        Self::start_with_limits(config, file, events, LIMITS).await
    }

    /// As [`Exporter::start`], with `limits` for the listener. Its connections are series of
    /// the metrics too: `optobus_metrics_http_connections` open now, and the counters
    /// `optobus_metrics_http_connections_refused_total` (beyond the cap) and
    /// `optobus_metrics_http_connections_timed_out_total` (closed at a header, idle or
    /// request timeout).
    pub async fn start_with_limits(
        config: &MetricsConfig,
        file: &BusFile,
        events: broadcast::Receiver<Event>,
        limits: Limits,
    ) -> std::io::Result<Self> {
        let listener = TcpListener::bind(config.listen).await?;
        let metrics = Arc::new(Metrics::new(file));
        let server = optobus_http::Server::start(listener, router(Arc::clone(&metrics)), limits)?;
        let tally = server.tally();
        metrics
            .add_source(move || {
                let counts = tally.counts();
                vec![
                    Reading::gauge(
                        "optobus_metrics_http_connections",
                        "Connections open to /metrics.",
                        i64::try_from(counts.open).unwrap_or(i64::MAX),
                    ),
                    Reading::counter(
                        "optobus_metrics_http_connections_refused",
                        "Connections to /metrics refused beyond its cap.",
                        counts.refused,
                    ),
                    Reading::counter(
                        "optobus_metrics_http_connections_timed_out",
                        "Connections to /metrics closed at a header, idle or request timeout.",
                        counts.header_timeouts + counts.idle_closed + counts.request_timeouts,
                    ),
                ]
            })
            .map_err(|error| std::io::Error::other(error.to_string()))?;
        let follow = tokio::spawn(follow(events, Arc::clone(&metrics)));
        Ok(Self {
            metrics,
            follow,
            server,
        })
    }

    /// Where `/metrics` is served.
    pub fn address(&self) -> SocketAddr {
        self.server.address()
    }

    /// What the listener did with its connections so far.
    pub fn connections(&self) -> optobus_http::Counts {
        self.server.counts()
    }

    /// The metrics it serves.
    pub fn metrics(&self) -> &Arc<Metrics> {
        &self.metrics
    }
}

impl Drop for Exporter {
    fn drop(&mut self) {
        self.follow.abort();
    }
}

async fn follow(events: broadcast::Receiver<Event>, metrics: Arc<Metrics>) {
    let mut events = Follower::new(events, |missed| metrics.missed(missed));
    while let Some(event) = events.next().await {
        metrics.observe(&event);
    }
}
