//! `[[webhooks]]`: the endpoints alarms are POSTed to ([`crate::webhooks`]), their keys,
//! defaults and checks.

use serde::Deserialize;

use super::ConfigError;

/// The longest webhook timeout or back-off accepted, s (a day).
const MAX_WEBHOOK_SECONDS: f64 = 86_400.0;

/// `[[webhooks]]`: one endpoint alarms are POSTed to ([`crate::webhooks`]).
#[derive(Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WebhookSection {
    /// `http://` or `https://` URL the events are POSTed to.
    pub url: String,
    /// The webhook's name in metrics (`webhook` label) and logs; default: the URL's
    /// `host[:port]` (never its path or query, which may hold a token).
    pub name: Option<String>,
    /// The event types sent ([`crate::webhooks::EVENT_TYPES`]); default
    /// [`crate::webhooks::DEFAULT_EVENT_TYPES`]: every alarm and every acknowledgement.
    pub events: Option<Vec<String>>,
    /// The HMAC-SHA256 key signing each body (`X-Rtls-Signature`).
    pub secret: Option<String>,
    /// The environment variable holding the key instead (not both).
    pub secret_env: Option<String>,
    /// Time allowed for one attempt (connect, send, answer), s.
    pub timeout_s: f64,
    /// Attempts per event before it is given up.
    pub max_attempts: u32,
    /// Wait before the first retry, s; doubled for each further retry.
    pub initial_backoff_s: f64,
    /// The longest wait between attempts, s (also caps `Retry-After`).
    pub max_backoff_s: f64,
}

impl Default for WebhookSection {
    fn default() -> Self {
        Self {
            url: String::new(),
            name: None,
            events: None,
            secret: None,
            secret_env: None,
            timeout_s: 5.0,
            max_attempts: 8,
            initial_backoff_s: 1.0,
            max_backoff_s: 60.0,
        }
    }
}

/// The secret is not shown.
impl std::fmt::Debug for WebhookSection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WebhookSection")
            .field("url", &self.url)
            .field("name", &self.name)
            .field("events", &self.events)
            .field("secret", &self.secret.as_ref().map(|_| "***"))
            .field("secret_env", &self.secret_env)
            .field("timeout_s", &self.timeout_s)
            .field("max_attempts", &self.max_attempts)
            .field("initial_backoff_s", &self.initial_backoff_s)
            .field("max_backoff_s", &self.max_backoff_s)
            .finish()
    }
}

impl WebhookSection {
    /// The parsed `url`.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`] for `webhooks[index].url` when it is not an `http://` or
    /// `https://` URL with a host.
    pub fn parsed_url(&self, index: usize) -> Result<reqwest::Url, ConfigError> {
        let invalid = |reason: String| ConfigError::Invalid {
            field: format!("webhooks[{index}].url"),
            reason,
        };
        if self.url.is_empty() {
            return Err(invalid(
                "required: the http:// or https:// address alarms are POSTed to".into(),
            ));
        }
        // the URL may hold a token (in its path or query): errors do not repeat it
        let url = reqwest::Url::parse(&self.url).map_err(|e| invalid(format!("not a URL ({e})")))?;
        if !matches!(url.scheme(), "http" | "https") {
            return Err(invalid(format!("scheme `{}` is not http or https", url.scheme())));
        }
        if url.host_str().is_none_or(str::is_empty) {
            return Err(invalid("has no host".into()));
        }
        Ok(url)
    }

    /// `name`, else the URL's `host[:port]`.
    ///
    /// # Errors
    /// As [`WebhookSection::parsed_url`].
    pub fn resolved_name(&self, index: usize) -> Result<String, ConfigError> {
        if let Some(name) = &self.name {
            return Ok(name.clone());
        }
        let url = self.parsed_url(index)?;
        let host = url.host_str().unwrap_or_default();
        Ok(match url.port() {
            Some(port) => format!("{host}:{port}"),
            None => host.to_string(),
        })
    }

    /// The event types sent: `events`, else the default set.
    #[must_use]
    pub fn resolved_events(&self) -> Vec<String> {
        match &self.events {
            Some(events) => events.clone(),
            None => crate::webhooks::DEFAULT_EVENT_TYPES
                .iter()
                .map(|e| (*e).to_string())
                .collect(),
        }
    }

    /// The signing key: `secret`, or the value of the variable `secret_env` names; `None`:
    /// requests are not signed.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`] for `webhooks[index].secret_env` when the variable is not set
    /// or empty, or for `webhooks[index].secret` when both are given or it is empty.
    pub fn resolved_secret(&self, index: usize) -> Result<Option<String>, ConfigError> {
        let invalid = |key: &str, reason: String| ConfigError::Invalid {
            field: format!("webhooks[{index}].{key}"),
            reason,
        };
        match (&self.secret, &self.secret_env) {
            (Some(_), Some(_)) => Err(invalid("secret", "give secret or secret_env, not both".into())),
            (Some(secret), None) if secret.is_empty() => Err(invalid("secret", "must not be empty".into())),
            (Some(secret), None) => Ok(Some(secret.clone())),
            (None, Some(variable)) => match std::env::var(variable) {
                Ok(value) if !value.is_empty() => Ok(Some(value)),
                Ok(_) => Err(invalid(
                    "secret_env",
                    format!("the environment variable {variable} is empty"),
                )),
                Err(_) => Err(invalid(
                    "secret_env",
                    format!("the environment variable {variable} is not set"),
                )),
            },
            (None, None) => Ok(None),
        }
    }

    fn validate(&self, index: usize) -> Result<(), ConfigError> {
        let invalid = |key: &str, reason: String| ConfigError::Invalid {
            field: format!("webhooks[{index}].{key}"),
            reason,
        };
        self.parsed_url(index)?;
        if let Some(name) = &self.name {
            if name.trim().is_empty() || name.chars().count() > 100 || name.chars().any(char::is_control) {
                return Err(invalid("name", "1 to 100 characters, no control characters".into()));
            }
        }
        match &self.events {
            Some(events) if events.is_empty() => {
                return Err(invalid(
                    "events",
                    "empty: nothing would be sent (leave it out for every alarm and acknowledgement)".into(),
                ))
            }
            Some(events) => {
                for (k, event) in events.iter().enumerate() {
                    if !crate::webhooks::EVENT_TYPES.contains(&event.as_str()) {
                        return Err(invalid(
                            &format!("events[{k}]"),
                            format!("`{event}` is not one of {}", crate::webhooks::EVENT_TYPES.join(", ")),
                        ));
                    }
                }
            }
            None => {}
        }
        self.resolved_secret(index)?;
        let seconds_ok = |s: f64| s.is_finite() && s > 0.0 && s <= MAX_WEBHOOK_SECONDS;
        if !seconds_ok(self.timeout_s) {
            return Err(invalid(
                "timeout_s",
                format!("must be > 0 and ≤ {MAX_WEBHOOK_SECONDS} s, got {}", self.timeout_s),
            ));
        }
        if self.max_attempts == 0 {
            return Err(invalid("max_attempts", "must be at least 1".into()));
        }
        if !seconds_ok(self.initial_backoff_s) {
            return Err(invalid(
                "initial_backoff_s",
                format!(
                    "must be > 0 and ≤ {MAX_WEBHOOK_SECONDS} s, got {}",
                    self.initial_backoff_s
                ),
            ));
        }
        if !(seconds_ok(self.max_backoff_s) && self.max_backoff_s >= self.initial_backoff_s) {
            return Err(invalid(
                "max_backoff_s",
                format!(
                    "must be ≥ initial_backoff_s ({} s) and ≤ {MAX_WEBHOOK_SECONDS} s, got {}",
                    self.initial_backoff_s, self.max_backoff_s
                ),
            ));
        }
        Ok(())
    }
}

/// Checks each `[[webhooks]]` table and that their names differ.
///
/// # Errors
/// [`ConfigError::Invalid`] naming `webhooks[i].key`.
pub(crate) fn validate_webhooks(webhooks: &[WebhookSection]) -> Result<(), ConfigError> {
    let mut names: Vec<String> = Vec::with_capacity(webhooks.len());
    for (index, webhook) in webhooks.iter().enumerate() {
        webhook.validate(index)?;
        let name = webhook.resolved_name(index)?;
        if let Some(other) = names.iter().position(|n| *n == name) {
            return Err(ConfigError::Invalid {
                field: format!("webhooks[{index}].name"),
                reason: format!("`{name}` is webhooks[{other}]'s name too; give each webhook its own name"),
            });
        }
        names.push(name);
    }
    Ok(())
}
