//! Access tokens: writes (HTTP ingest and configuration, MQTT publish) need the write token;
//! reads need the read token or the write token, unless no read token is configured.

/// What a presented token allows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Access {
    /// Nothing.
    None,
    /// Reading (REST GET, WebSocket, MQTT subscribe).
    Read,
    /// Reading and writing.
    Write,
}

/// The configured tokens.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Tokens {
    /// The token that allows writing (and reading).
    pub write: String,
    /// The token that allows reading; `None`: reading needs no token.
    pub read: Option<String>,
}

impl Tokens {
    /// What `presented` (e.g. a bearer token or an MQTT password) allows. Tokens are compared
    /// in constant time. Without a read token, presenting none reads; presenting a wrong one
    /// allows nothing (a mistyped or guessed credential is refused, never downgraded).
    #[must_use]
    pub fn access(&self, presented: Option<&str>) -> Access {
        let matches = |expected: &str| presented.is_some_and(|p| constant_time_eq(p, expected));
        if matches(&self.write) {
            Access::Write
        } else if self.read.as_deref().map_or(presented.is_none(), matches) {
            Access::Read
        } else {
            Access::None
        }
    }
}

/// A random token: 128 bits from the operating system's generator (a v4 UUID without dashes).
#[must_use]
pub fn random_token() -> String {
    uuid::Uuid::new_v4().simple().to_string()
}

/// Compares two strings without an early exit on the first difference.
fn constant_time_eq(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_write_token_writes_the_read_token_reads_and_others_get_nothing() {
        let tokens = Tokens {
            write: "w-secret".into(),
            read: Some("r-secret".into()),
        };
        assert_eq!(tokens.access(Some("w-secret")), Access::Write);
        assert_eq!(tokens.access(Some("r-secret")), Access::Read);
        assert_eq!(tokens.access(Some("w-secreT")), Access::None);
        assert_eq!(tokens.access(None), Access::None);
        let open_reads = Tokens {
            write: "w".into(),
            read: None,
        };
        assert_eq!(open_reads.access(None), Access::Read);
        assert_eq!(open_reads.access(Some("w")), Access::Write);
        assert_eq!(
            open_reads.access(Some("guess")),
            Access::None,
            "a wrong token is refused"
        );
    }
}
