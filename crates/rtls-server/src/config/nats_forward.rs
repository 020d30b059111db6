//! `[[nats_forward]]`: the NATS servers positions and events are forwarded to
//! ([`crate::nats_forward`]), their keys, defaults and checks.

use serde::Deserialize;

use super::ConfigError;

/// What a forward sends, by the hub's topic ([`crate::omlox::ws::Topic`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ForwardTopic {
    /// Every track update as an omlox `Location` (`location_updates`), on
    /// `{subject_prefix}.positions.{tag}`.
    Positions,
    /// The `rtls:alarms` messages (alarms, acknowledgements, lost / recovered, model switches),
    /// on `{subject_prefix}.events.{type}`.
    Alarms,
    /// The `rtls:events` messages (every other engine event, audit entries), on
    /// `{subject_prefix}.events.{type}`.
    Events,
}

/// `[[nats_forward]]`: one NATS server (or cluster) the server publishes to.
#[derive(Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NatsForwardSection {
    /// `nats://host:4222` (or `tls://…`; several separated by commas: one cluster's servers);
    /// `nats://user:password@host:4222` for a user and password.
    pub url: String,
    /// The forward's name in metrics (`forward` label) and logs; default: the first URL's
    /// `host[:port]` (never its credentials).
    pub name: Option<String>,
    /// The first tokens of every subject (default `rtls`).
    pub subject_prefix: String,
    /// What is sent; default every topic.
    pub topics: Vec<ForwardTopic>,
    /// The environment variable holding the NATS server's authentication token, if it wants one.
    pub token_env: Option<String>,
}

impl Default for NatsForwardSection {
    fn default() -> Self {
        Self {
            url: String::new(),
            name: None,
            subject_prefix: "rtls".into(),
            topics: vec![ForwardTopic::Positions, ForwardTopic::Alarms, ForwardTopic::Events],
            token_env: None,
        }
    }
}

/// The URL's credentials are not shown.
impl std::fmt::Debug for NatsForwardSection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NatsForwardSection")
            .field("url", &super::redact_password(&self.url))
            .field("name", &self.name)
            .field("subject_prefix", &self.subject_prefix)
            .field("topics", &self.topics)
            .field("token_env", &self.token_env)
            .finish()
    }
}

impl NatsForwardSection {
    /// The servers of `url`, each parsed.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`] for `nats_forward[index].url` when it is empty or a server is
    /// not a `nats://` or `tls://` URL with a host (the message does not repeat the URL, which
    /// may hold a password).
    pub fn servers(&self, index: usize) -> Result<Vec<url::Url>, ConfigError> {
        let invalid = |reason: String| ConfigError::Invalid {
            field: format!("nats_forward[{index}].url"),
            reason,
        };
        if self.url.trim().is_empty() {
            return Err(invalid("required: nats://host:4222".into()));
        }
        self.url
            .split(',')
            .map(|server| {
                let url = url::Url::parse(server.trim()).map_err(|e| invalid(format!("not a URL ({e})")))?;
                if !matches!(url.scheme(), "nats" | "tls") {
                    return Err(invalid(format!("scheme `{}` is not nats or tls", url.scheme())));
                }
                if url.host_str().is_none_or(str::is_empty) {
                    return Err(invalid("has no host".into()));
                }
                Ok(url)
            })
            .collect()
    }

    /// `name`, else the first server's `host[:port]`.
    ///
    /// # Errors
    /// As [`NatsForwardSection::servers`].
    pub fn resolved_name(&self, index: usize) -> Result<String, ConfigError> {
        if let Some(name) = &self.name {
            return Ok(name.clone());
        }
        let servers = self.servers(index)?;
        let url = &servers[0];
        let host = url.host_str().unwrap_or_default();
        Ok(match url.port() {
            Some(port) => format!("{host}:{port}"),
            None => host.to_string(),
        })
    }

    /// The token: the value of the variable `token_env` names; `None` without one.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`] for `nats_forward[index].token_env` when the variable is not
    /// set or empty.
    pub fn resolved_token(&self, index: usize) -> Result<Option<String>, ConfigError> {
        let Some(variable) = &self.token_env else {
            return Ok(None);
        };
        match std::env::var(variable) {
            Ok(value) if !value.is_empty() => Ok(Some(value)),
            _ => Err(ConfigError::Invalid {
                field: format!("nats_forward[{index}].token_env"),
                reason: format!("the environment variable {variable} is not set or empty"),
            }),
        }
    }

    fn validate(&self, index: usize) -> Result<(), ConfigError> {
        let invalid = |key: &str, reason: String| ConfigError::Invalid {
            field: format!("nats_forward[{index}].{key}"),
            reason,
        };
        self.servers(index)?;
        if let Some(name) = &self.name {
            if name.trim().is_empty() || name.chars().count() > 100 || name.chars().any(char::is_control) {
                return Err(invalid("name", "1 to 100 characters, no control characters".into()));
            }
        }
        let token_ok = |t: &str| !t.is_empty() && !t.chars().any(|c| c.is_whitespace() || matches!(c, '*' | '>'));
        if !self.subject_prefix.split('.').all(token_ok) {
            return Err(invalid(
                "subject_prefix",
                format!(
                    "`{}` is not a NATS subject: tokens separated by dots, none empty, without spaces, `*` or `>`",
                    self.subject_prefix
                ),
            ));
        }
        if self.topics.is_empty() {
            return Err(invalid(
                "topics",
                "empty: nothing would be sent (leave it out for every topic)".into(),
            ));
        }
        self.resolved_token(index)?;
        Ok(())
    }
}

/// Checks each `[[nats_forward]]` table and that their names differ.
///
/// # Errors
/// [`ConfigError::Invalid`] naming `nats_forward[i].key`.
pub(crate) fn validate_nats_forwards(forwards: &[NatsForwardSection]) -> Result<(), ConfigError> {
    let mut names: Vec<String> = Vec::with_capacity(forwards.len());
    for (index, forward) in forwards.iter().enumerate() {
        forward.validate(index)?;
        let name = forward.resolved_name(index)?;
        if let Some(other) = names.iter().position(|n| *n == name) {
            return Err(ConfigError::Invalid {
                field: format!("nats_forward[{index}].name"),
                reason: format!("`{name}` is nats_forward[{other}]'s name too; give each its own name"),
            });
        }
        names.push(name);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parsed(toml: &str) -> Result<Vec<NatsForwardSection>, String> {
        #[derive(Deserialize)]
        struct File {
            nats_forward: Vec<NatsForwardSection>,
        }
        let file: File = toml::from_str(toml).map_err(|e| e.to_string())?;
        validate_nats_forwards(&file.nats_forward).map_err(|e| e.to_string())?;
        Ok(file.nats_forward)
    }

    #[test]
    fn defaults_names_and_checks() {
        let forwards = parsed("[[nats_forward]]\nurl = \"nats://rtls:s3cret@bus.example:4222\"\n").unwrap();
        let forward = &forwards[0];
        assert_eq!(forward.subject_prefix, "rtls");
        assert_eq!(forward.topics.len(), 3);
        assert_eq!(forward.resolved_name(0).unwrap(), "bus.example:4222");
        assert!(!format!("{forward:?}").contains("s3cret"), "{forward:?}");

        let error = parsed("[[nats_forward]]\nurl = \"http://rtls:s3cret@bus\"\n").unwrap_err();
        assert!(
            error.contains("nats_forward[0].url") && !error.contains("s3cret"),
            "{error}"
        );
        let error = parsed("[[nats_forward]]\nurl = \"nats://a\"\nsubject_prefix = \"rtls.>\"\n").unwrap_err();
        assert!(error.contains("subject_prefix"), "{error}");
        let error = parsed("[[nats_forward]]\nurl = \"nats://a\"\ntopics = []\n").unwrap_err();
        assert!(error.contains("topics"), "{error}");
        let error = parsed("[[nats_forward]]\nurl = \"nats://a\"\ntopics = [\"tracks\"]\n").unwrap_err();
        assert!(error.contains("tracks"), "{error}");
        let error = parsed("[[nats_forward]]\nurl = \"nats://a\"\n[[nats_forward]]\nurl = \"nats://a\"\n").unwrap_err();
        assert!(error.contains("nats_forward[1].name"), "{error}");
        let error =
            parsed("[[nats_forward]]\nurl = \"nats://a\"\ntoken_env = \"RTLS_TEST_UNSET_NATS_TOKEN\"\n").unwrap_err();
        assert!(error.contains("RTLS_TEST_UNSET_NATS_TOKEN"), "{error}");
    }
}
