//! One webhook's HTTP deliveries: the request, the answer's verdict, the back-off.

use std::time::Duration;

use hmac::{KeyInit, Mac};
use reqwest::header::{HeaderValue, CONTENT_TYPE, RETRY_AFTER};
use reqwest::StatusCode;

use super::{Counters, Delivery, Webhook};

/// What an attempt's answer means.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Verdict {
    /// 2xx.
    Delivered,
    /// Not worth repeating (4xx but 408 and 429, 3xx, a request that cannot be built).
    Failed(String),
    /// Worth another attempt (408, 429, 5xx, timeout, connection error), after `after` if the
    /// answer said (`Retry-After`).
    Retry {
        /// Why.
        reason: String,
        /// `Retry-After`, if given in seconds.
        after: Option<Duration>,
    },
}

/// The verdict on an HTTP answer (`detail`: the start of its body, for the log).
pub(super) fn classify(status: StatusCode, retry_after: Option<&HeaderValue>, detail: &str) -> Verdict {
    let reason = if detail.is_empty() {
        format!("HTTP {status}")
    } else {
        format!("HTTP {status}: {detail}")
    };
    if status.is_success() {
        Verdict::Delivered
    } else if status.is_server_error()
        || status == StatusCode::REQUEST_TIMEOUT
        || status == StatusCode::TOO_MANY_REQUESTS
    {
        Verdict::Retry {
            reason,
            after: retry_after.and_then(parse_retry_after),
        }
    } else if status.is_redirection() {
        Verdict::Failed(format!(
            "{reason} (redirects are not followed: set url to the final address)"
        ))
    } else {
        Verdict::Failed(reason)
    }
}

/// `Retry-After` in delay-seconds; an HTTP date is ignored (the back-off applies).
pub(super) fn parse_retry_after(value: &HeaderValue) -> Option<Duration> {
    value.to_str().ok()?.trim().parse::<u64>().ok().map(Duration::from_secs)
}

/// The wait after the `retry`-th failed attempt (1 for the first): `Retry-After` if the answer
/// gave one, else `initial · 2^(retry − 1)`; either capped at `max`; the back-off (not
/// `Retry-After`) scaled by `0.75 + 0.25 · jitter` (`jitter` in [0, 1]) so that many clients
/// do not retry in step.
#[must_use]
pub fn backoff(retry: u32, initial: Duration, max: Duration, retry_after: Option<Duration>, jitter: f64) -> Duration {
    if let Some(after) = retry_after {
        return after.min(max);
    }
    let doublings = retry.saturating_sub(1).min(60);
    let base_s = (initial.as_secs_f64() * 2_f64.powi(doublings as i32)).min(max.as_secs_f64());
    Duration::from_secs_f64(base_s * (0.75 + 0.25 * jitter.clamp(0.0, 1.0)))
}

/// A uniform number in [0, 1) from the OS's randomness (a v4 UUID's random bits: no generator
/// of our own).
pub(super) fn jitter() -> f64 {
    let bits = uuid::Uuid::new_v4().as_u128() as u64 >> 11;
    bits as f64 / (1_u64 << 53) as f64
}

/// `X-Rtls-Signature`'s value: `sha256=` and the lower-case hex HMAC-SHA256 of `body` keyed
/// with `secret`.
///
/// # Examples
/// ```
/// // RFC 4231 test case 2
/// let signature = rtls_server::webhooks::signature(b"Jefe", b"what do ya want for nothing?");
/// assert_eq!(signature, "sha256=5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843");
/// ```
#[must_use]
pub fn signature(secret: &[u8], body: &[u8]) -> String {
    let mut mac = hmac::Hmac::<sha2::Sha256>::new_from_slice(secret).expect("HMAC takes a key of any length");
    mac.update(body);
    let digest = mac.finalize().into_bytes();
    let mut text = String::with_capacity(7 + 2 * digest.len());
    text.push_str("sha256=");
    for byte in digest.iter() {
        text.push_str(&format!("{byte:02x}"));
    }
    text
}

/// One webhook's HTTP client and counters.
pub(super) struct Sender {
    pub webhook: Webhook,
    pub counters: Counters,
    client: reqwest::Client,
}

impl Sender {
    pub fn new(webhook: Webhook, counters: Counters) -> Result<Self, String> {
        let client = reqwest::Client::builder()
            .timeout(webhook.timeout)
            .redirect(reqwest::redirect::Policy::none())
            .user_agent(concat!("rtls-server/", env!("CARGO_PKG_VERSION")))
            .build()
            .map_err(|e| format!("webhook {}: HTTP client: {}", webhook.name, describe(e)))?;
        Ok(Self {
            webhook,
            counters,
            client,
        })
    }

    /// Delivers one event: attempts until it is delivered, refused, or `max_attempts` are
    /// spent, waiting [`backoff`] between attempts. Counts and logs the outcome.
    pub async fn deliver(&self, delivery: &Delivery) {
        let hook = &self.webhook;
        let signature = hook.secret.as_ref().map(|secret| signature(secret, &delivery.body));
        for attempt in 1..=hook.max_attempts {
            let verdict = self.attempt(delivery, attempt, signature.as_deref()).await;
            let log_failure = |reason: &str, what: &str| {
                tracing::warn!(
                    webhook = %hook.name,
                    delivery = %delivery.id,
                    event = %delivery.event_type,
                    alarm_id = delivery.alarm_id.as_deref().unwrap_or(""),
                    attempt,
                    reason,
                    "webhook delivery failed: {what}"
                );
            };
            match verdict {
                Verdict::Delivered => {
                    self.counters.delivered.inc();
                    tracing::debug!(webhook = %hook.name, delivery = %delivery.id, attempt, "webhook delivered");
                    return;
                }
                Verdict::Failed(reason) => {
                    self.counters.failed.inc();
                    log_failure(&reason, "refused, not retried");
                    return;
                }
                Verdict::Retry { reason, .. } if attempt == hook.max_attempts => {
                    self.counters.failed.inc();
                    log_failure(&reason, "given up after the last attempt (max_attempts)");
                    return;
                }
                Verdict::Retry { reason, after } => {
                    self.counters.retried.inc();
                    let wait = backoff(attempt, hook.initial_backoff, hook.max_backoff, after, jitter());
                    tracing::debug!(
                        webhook = %hook.name,
                        delivery = %delivery.id,
                        attempt,
                        reason,
                        wait_s = wait.as_secs_f64(),
                        "webhook attempt failed; retrying"
                    );
                    tokio::time::sleep(wait).await;
                }
            }
        }
    }

    async fn attempt(&self, delivery: &Delivery, attempt: u32, signature: Option<&str>) -> Verdict {
        let mut request = self
            .client
            .post(self.webhook.url.clone())
            .header(CONTENT_TYPE, "application/json")
            .header("X-Rtls-Delivery", &delivery.id)
            .header("X-Rtls-Attempt", attempt.to_string())
            .header("X-Rtls-Event", &delivery.event_type)
            .body(delivery.body.clone());
        if let Some(signature) = signature {
            request = request.header("X-Rtls-Signature", signature);
        }
        match request.send().await {
            Ok(mut response) => {
                let status = response.status();
                let retry_after = response.headers().get(RETRY_AFTER).cloned();
                let detail = if status.is_success() {
                    String::new()
                } else {
                    // the start of the answer, for the log
                    match response.chunk().await {
                        Ok(Some(bytes)) => {
                            let text = String::from_utf8_lossy(&bytes[..bytes.len().min(200)]);
                            text.split_whitespace().collect::<Vec<_>>().join(" ")
                        }
                        _ => String::new(),
                    }
                };
                classify(status, retry_after.as_ref(), &detail)
            }
            Err(e) if e.is_builder() => Verdict::Failed(describe(e)),
            Err(e) => Verdict::Retry {
                reason: if e.is_timeout() {
                    format!("timed out after {:?}", self.webhook.timeout)
                } else {
                    describe(e)
                },
                after: None,
            },
        }
    }
}

/// An HTTP client error and its causes, without the URL (which may hold a token).
fn describe(error: reqwest::Error) -> String {
    let error = error.without_url();
    let mut text = error.to_string();
    let mut source = std::error::Error::source(&error);
    while let Some(cause) = source {
        text.push_str(": ");
        text.push_str(&cause.to_string());
        source = cause.source();
    }
    text
}
