//! Requests per second per client address (`[server] max_requests_per_s_per_ip`): a token
//! bucket per IP address (the GCRA of the `governor` crate) allowing bursts of twice the rate;
//! a request over it is answered 429 with `Retry-After`, before any handler runs, and counted
//! in `rtls_http_requests_limited_total`.

use std::net::IpAddr;
use std::num::NonZeroU32;
use std::sync::Arc;

use axum::extract::{ConnectInfo, Request, State};
use axum::http::{header, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use governor::clock::{Clock, DefaultClock};
use governor::{DefaultKeyedRateLimiter, Quota, RateLimiter};

use super::listener::Peer;
use super::ApiError;
use crate::metrics::Metrics;

/// Addresses tracked before idle ones are forgotten.
const FORGET_ABOVE: usize = 10_000;

/// The per-address limiter and where it counts what it refuses.
#[derive(Clone)]
pub struct RateLimit {
    limiter: Arc<DefaultKeyedRateLimiter<IpAddr>>,
    metrics: Arc<Metrics>,
}

impl RateLimit {
    /// `per_second` requests per second per address, bursts of twice that; `None` for 0 (no
    /// limit).
    #[must_use]
    pub fn new(per_second: u32, metrics: Arc<Metrics>) -> Option<Self> {
        let rate = NonZeroU32::new(per_second)?;
        let burst = NonZeroU32::new(per_second.saturating_mul(2)).unwrap_or(rate);
        Some(Self {
            limiter: Arc::new(RateLimiter::keyed(Quota::per_second(rate).allow_burst(burst))),
            metrics,
        })
    }
}

/// The middleware: a request from an address over its rate gets 429 and `Retry-After` (s).
/// Requests without a peer address (in-process calls) pass.
pub async fn limit(State(rate): State<RateLimit>, request: Request, next: Next) -> Response {
    let peer = request.extensions().get::<ConnectInfo<Peer>>().map(|c| c.0 .0.ip());
    if let Some(ip) = peer {
        if rate.limiter.len() > FORGET_ABOVE {
            rate.limiter.retain_recent();
        }
        if let Err(not_until) = rate.limiter.check_key(&ip) {
            rate.metrics.http_requests_limited.inc();
            let wait = not_until.wait_time_from(DefaultClock::default().now());
            let retry_after_s = wait.as_secs() + 1;
            let mut response = ApiError::new(
                StatusCode::TOO_MANY_REQUESTS,
                format!("too many requests from {ip}; retry in {retry_after_s} s"),
            )
            .into_response();
            if let Ok(value) = retry_after_s.to_string().parse() {
                response.headers_mut().insert(header::RETRY_AFTER, value);
            }
            return response;
        }
    }
    next.run(request).await
}
