//! `/metrics` over HTTP, and the task that feeds the metrics from the bus.

use std::net::SocketAddr;
use std::sync::Arc;

use axum::extract::State;
use axum::http::{header, HeaderMap};
use axum::response::IntoResponse;
use axum::routing::get;
use axum::Router;
use optobus_bus::{BusFile, Event, MetricsConfig};
use tokio::net::TcpListener;
use tokio::sync::broadcast::{self, error::RecvError};
use tokio::task::JoinHandle;

use crate::exposition::{OPENMETRICS_TYPE, PROMETHEUS_TEXT_TYPE};
use crate::Metrics;

/// Answers `GET /metrics` on `listener` with `metrics` until the task is dropped: OpenMetrics
/// to a scraper that asks for it (`Accept: application/openmetrics-text`), the Prometheus text
/// format otherwise.
pub async fn serve(listener: TcpListener, metrics: Arc<Metrics>) -> std::io::Result<()> {
    let router = Router::new()
        .route("/metrics", get(scrape))
        .with_state(metrics);
    axum::serve(listener, router).await
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
    address: SocketAddr,
    metrics: Arc<Metrics>,
    tasks: [JoinHandle<()>; 2],
}

impl Exporter {
    /// Listens on `config.listen` and follows `events` (subscribe before the bus starts to miss
    /// no event). Fails only when the address cannot be listened on.
    pub async fn start(
        config: &MetricsConfig,
        file: &BusFile,
        events: broadcast::Receiver<Event>,
    ) -> std::io::Result<Self> {
        let listener = TcpListener::bind(config.listen).await?;
        let address = listener.local_addr()?;
        let metrics = Arc::new(Metrics::new(file));
        let follow = tokio::spawn(follow(events, Arc::clone(&metrics)));
        let server = {
            let metrics = Arc::clone(&metrics);
            tokio::spawn(async move {
                if let Err(error) = serve(listener, metrics).await {
                    tracing::error!(%error, "/metrics stopped");
                }
            })
        };
        Ok(Self {
            address,
            metrics,
            tasks: [follow, server],
        })
    }

    /// Where `/metrics` is served.
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// The metrics it serves.
    pub fn metrics(&self) -> &Arc<Metrics> {
        &self.metrics
    }
}

impl Drop for Exporter {
    fn drop(&mut self) {
        for task in &self.tasks {
            task.abort();
        }
    }
}

async fn follow(mut events: broadcast::Receiver<Event>, metrics: Arc<Metrics>) {
    loop {
        match events.recv().await {
            Ok(event) => metrics.observe(&event),
            Err(RecvError::Lagged(missed)) => metrics.missed(missed),
            Err(RecvError::Closed) => return,
        }
    }
}
