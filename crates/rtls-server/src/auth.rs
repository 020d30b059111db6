//! Credentials and roles.
//!
//! Every credential is a bearer token (HTTP `Authorization: Bearer …`, the WebSocket's
//! `?token=`, the MQTT password) with a [`Role`]:
//!
//! | role | may |
//! |---|---|
//! | `viewer` | read: REST GET, WebSocket, MQTT subscribe |
//! | `operator` | read; acknowledge alarms; create, edit and delete zones (fences) |
//! | `integrator` | read; write measurement records (HTTP, MQTT publish, omlox locations); create, edit and delete providers and trackables |
//! | `admin` | everything, and issue and revoke tokens |
//!
//! The configured write token (`RTLS_WRITE_TOKEN`) is an admin, the read token
//! (`RTLS_READ_TOKEN`) a viewer. More tokens are issued at run time (`POST /api/v1/tokens`):
//! only their SHA-256 is kept (in memory and in the store), and a revoked one stops working at
//! once, without a restart. Without a read token reads need none only when the configuration
//! says so (`[auth] open_reads`); a wrong token is refused, never taken as no token.

use std::sync::{Arc, RwLock};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

/// What a request needs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Access {
    /// Nothing (a refused credential).
    None,
    /// Reading (REST GET, WebSocket, MQTT subscribe).
    Read,
    /// Operating the control room: acknowledging alarms, editing zones.
    Operate,
    /// Writing records and the integration's objects (providers, trackables).
    Write,
    /// Managing credentials.
    Admin,
}

/// A credential's role.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Reads.
    Viewer,
    /// Reads, acknowledges alarms, edits zones.
    Operator,
    /// Reads, writes records, providers and trackables.
    Integrator,
    /// Everything.
    Admin,
}

impl Role {
    /// Whether this role may do what needs `needed`.
    ///
    /// # Examples
    /// ```
    /// use rtls_server::auth::{Access, Role};
    ///
    /// assert!(Role::Operator.allows(Access::Operate));
    /// assert!(!Role::Operator.allows(Access::Write));
    /// assert!(Role::Integrator.allows(Access::Write));
    /// assert!(!Role::Integrator.allows(Access::Operate));
    /// assert!(Role::Admin.allows(Access::Admin));
    /// ```
    #[must_use]
    pub fn allows(self, needed: Access) -> bool {
        match needed {
            Access::None | Access::Read => true,
            Access::Operate => matches!(self, Self::Operator | Self::Admin),
            Access::Write => matches!(self, Self::Integrator | Self::Admin),
            Access::Admin => self == Self::Admin,
        }
    }

    /// What this role allows at most in one level: [`Access::Write`] when it may write
    /// records (it publishes over MQTT), else [`Access::Read`].
    #[must_use]
    pub fn publish_level(self) -> Access {
        if self.allows(Access::Write) {
            Access::Write
        } else {
            Access::Read
        }
    }

    /// The role's name as the API spells it (`viewer`, …).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Viewer => "viewer",
            Self::Operator => "operator",
            Self::Integrator => "integrator",
            Self::Admin => "admin",
        }
    }
}

/// Who presented a credential: its name (`write-token`, `read-token`, an issued token's name,
/// `anonymous` for open reads) and role.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Principal {
    /// The credential's name (for the audit log).
    pub name: String,
    /// What it may do.
    pub role: Role,
}

/// A token issued at run time: its id, name, role and the SHA-256 of its secret.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct IssuedToken {
    /// Its id (a UUID), to list and revoke it.
    pub id: String,
    /// A name for people and the audit log (`dispatcher-3`, `gateway-north`).
    pub name: String,
    /// What it may do.
    pub role: Role,
    /// SHA-256 of the secret, lowercase hex.
    pub sha256: String,
    /// When it was issued (ms since the Unix epoch).
    pub issued_ms: i64,
}

/// The credentials: the configured tokens and the issued ones (shared by every clone, so a
/// token issued or revoked through the API counts at once everywhere — HTTP and MQTT).
#[derive(Debug, Clone)]
pub struct Tokens {
    /// The configured write token: an admin.
    pub write: String,
    /// The configured read token: a viewer; `None`: see `open_reads`.
    pub read: Option<String>,
    /// Without a read token, whether presenting no token reads.
    pub open_reads: bool,
    issued: Arc<RwLock<Vec<IssuedToken>>>,
}

impl PartialEq for Tokens {
    fn eq(&self, other: &Self) -> bool {
        self.write == other.write
            && self.read == other.read
            && self.open_reads == other.open_reads
            && Arc::ptr_eq(&self.issued, &other.issued)
    }
}

impl Eq for Tokens {}

impl Tokens {
    /// The configured tokens; with no read token, reads are open (`open_reads`) — a server
    /// that must not have open reads configures a read token.
    #[must_use]
    pub fn new(write: impl Into<String>, read: Option<String>) -> Self {
        Self {
            write: write.into(),
            open_reads: read.is_none(),
            read,
            issued: Arc::default(),
        }
    }

    /// With no read token, whether presenting none reads (`[auth] open_reads`).
    #[must_use]
    pub fn with_open_reads(mut self, open_reads: bool) -> Self {
        self.open_reads = open_reads;
        self
    }

    /// Who presents `presented` (e.g. a bearer token or an MQTT password), or `None` for a
    /// credential that is refused. Secrets are compared in constant time.
    #[must_use]
    pub fn principal(&self, presented: Option<&str>) -> Option<Principal> {
        let who = |name: &str, role| {
            Some(Principal {
                name: name.into(),
                role,
            })
        };
        let Some(presented) = presented else {
            return (self.read.is_none() && self.open_reads)
                .then(|| who("anonymous", Role::Viewer))
                .flatten();
        };
        if constant_time_eq(presented.as_bytes(), self.write.as_bytes()) {
            return who("write-token", Role::Admin);
        }
        if self
            .read
            .as_deref()
            .is_some_and(|read| constant_time_eq(presented.as_bytes(), read.as_bytes()))
        {
            return who("read-token", Role::Viewer);
        }
        let digest = hex(&Sha256::digest(presented.as_bytes()));
        let issued = self.issued.read().ok()?;
        issued
            .iter()
            .find(|token| constant_time_eq(token.sha256.as_bytes(), digest.as_bytes()))
            .and_then(|token| who(&token.name, token.role))
    }

    /// Issues a token named `name` with `role`: the secret (shown once) and its record (to
    /// store; only its hash is kept).
    #[must_use]
    pub fn issue(&self, name: &str, role: Role, issued_ms: i64) -> (String, IssuedToken) {
        let secret = random_token();
        let record = IssuedToken {
            id: uuid::Uuid::new_v4().to_string(),
            name: name.to_string(),
            role,
            sha256: hex(&Sha256::digest(secret.as_bytes())),
            issued_ms,
        };
        self.remember(record.clone());
        (secret, record)
    }

    /// Takes an issued token (loaded from the store at start).
    pub fn remember(&self, token: IssuedToken) {
        if let Ok(mut issued) = self.issued.write() {
            issued.retain(|t| t.id != token.id);
            issued.push(token);
        }
    }

    /// Revokes the issued token `id`; `false` when there is none.
    pub fn revoke(&self, id: &str) -> bool {
        self.issued.write().is_ok_and(|mut issued| {
            let before = issued.len();
            issued.retain(|t| t.id != id);
            issued.len() < before
        })
    }

    /// The issued tokens (their hashes, never secrets).
    #[must_use]
    pub fn issued(&self) -> Vec<IssuedToken> {
        self.issued.read().map(|issued| issued.clone()).unwrap_or_default()
    }
}

/// A random token: 128 bits from the operating system's generator (a v4 UUID without dashes).
#[must_use]
pub fn random_token() -> String {
    uuid::Uuid::new_v4().simple().to_string()
}

/// Lowercase hex of `bytes`.
fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Compares two byte strings without an early exit on the first difference.
fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What `presented` allows at most, in one level ([`Access::None`] when refused).
    fn access(tokens: &Tokens, presented: Option<&str>) -> Access {
        tokens
            .principal(presented)
            .map_or(Access::None, |who| who.role.publish_level())
    }

    #[test]
    fn the_write_token_is_an_admin_the_read_token_a_viewer_and_others_nobody() {
        let tokens = Tokens::new("w-secret", Some("r-secret".into()));
        assert_eq!(tokens.principal(Some("w-secret")).unwrap().role, Role::Admin);
        assert_eq!(tokens.principal(Some("r-secret")).unwrap().role, Role::Viewer);
        assert_eq!(access(&tokens, Some("w-secret")), Access::Write);
        assert_eq!(access(&tokens, Some("r-secret")), Access::Read);
        assert_eq!(access(&tokens, Some("w-secreT")), Access::None);
        assert_eq!(access(&tokens, None), Access::None);
        let open_reads = Tokens::new("w", None);
        assert_eq!(access(&open_reads, None), Access::Read);
        assert_eq!(open_reads.principal(None).unwrap().name, "anonymous");
        assert_eq!(access(&open_reads, Some("w")), Access::Write);
        assert_eq!(
            access(&open_reads, Some("guess")),
            Access::None,
            "a wrong token is refused"
        );
        let closed = Tokens::new("w", None).with_open_reads(false);
        assert_eq!(access(&closed, None), Access::None, "reads need a credential");
    }

    #[test]
    fn an_issued_token_works_everywhere_at_once_and_stops_when_revoked() {
        let tokens = Tokens::new("w", Some("r".into()));
        let shared = tokens.clone();
        let (secret, record) = tokens.issue("dispatcher-3", Role::Operator, 1);
        assert_ne!(record.sha256, secret, "only the hash is kept");
        assert_eq!(record.sha256.len(), 64);
        let who = shared.principal(Some(&secret)).expect("known in every clone");
        assert_eq!((who.name.as_str(), who.role), ("dispatcher-3", Role::Operator));
        assert_eq!(
            access(&shared, Some(&secret)),
            Access::Read,
            "an operator does not publish"
        );
        assert!(tokens.revoke(&record.id));
        assert!(shared.principal(Some(&secret)).is_none(), "revoked everywhere");
        assert!(!tokens.revoke(&record.id));
    }

    #[test]
    fn each_role_allows_its_own_work() {
        use Access::*;
        let table = [
            (Role::Viewer, [true, false, false, false]),
            (Role::Operator, [true, true, false, false]),
            (Role::Integrator, [true, false, true, false]),
            (Role::Admin, [true, true, true, true]),
        ];
        for (role, allowed) in table {
            for (needed, expected) in [Read, Operate, Write, Admin].into_iter().zip(allowed) {
                assert_eq!(role.allows(needed), expected, "{role:?} {needed:?}");
            }
        }
    }
}
