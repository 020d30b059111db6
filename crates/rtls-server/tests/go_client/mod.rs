//! The harness of the Go omlox client (`omlox_go_client.rs`): what it writes and how it reads
//! (`wire`), its REST half (`rest`) and its WebSocket half (`socket`).

pub mod rest;
pub mod socket;
pub mod wire;

use std::time::Duration;

/// The client commit this harness mirrors.
pub const CLIENT_COMMIT: &str = "34053748938b64888636554bd45c281597f88cde";
/// The id a zero-valued `uuid.UUID` is written as: what the client sends for a new trackable.
pub const NIL_UUID: &str = "00000000-0000-0000-0000-000000000000";
/// nhooyr.io/websocket's default read limit per message (`defaultReadLimit`).
pub const GO_READ_LIMIT: usize = 32_768;
/// What Go's `net/http` sends as `User-Agent` when the caller sets none.
pub const GO_USER_AGENT: &str = "Go-http-client/1.1";
/// Every wait of the session.
pub const WAIT: Duration = Duration::from_secs(20);
/// Locations pushed per provider.
pub const FIXES: usize = 20;
