//! One accepted connection of the embedded broker up to its session: reading the CONNECT,
//! refusing it (protocol version, client id, token, connection limit) or handing the
//! connection to a [`Session`].

use std::net::SocketAddr;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use bytes::BytesMut;
use rumqttc::mqttbytes::v4::{ConnAck, Connect, ConnectReturnCode, Packet};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::sync::{watch, OwnedSemaphorePermit};
use tokio::time::timeout;

use crate::auth::{Access, Principal, Tokens};

use super::frame::{self, FrameError, Next};
use super::session::{packet_name, Session, CLOSE_WRITE_TIMEOUT};
use super::shared::Shared;
use super::stats::add;
use super::stream::{Reader, Writer};
use super::CONNECT_TIMEOUT;

/// Serves one accepted connection until it closes: the handshake, then the session.
pub(crate) async fn serve(
    (mut reader, mut writer): (Reader, Writer),
    peer: SocketAddr,
    connection_no: u64,
    shared: Arc<Shared>,
    mut stop: watch::Receiver<bool>,
    handshake: OwnedSemaphorePermit,
) {
    let mut inbox = BytesMut::with_capacity(4096);
    let max_packet_bytes = shared.config.max_packet_bytes;
    let first = tokio::select! {
        read = timeout(CONNECT_TIMEOUT, read_packet(&mut reader, &mut inbox, max_packet_bytes)) => read,
        _ = stop.changed() => return,
    };
    let connect = match first {
        Ok(Ok(Packet::Connect(connect))) => connect,
        Ok(Ok(other)) => {
            add(&shared.counters.protocol_violations, 1);
            tracing::warn!(%peer, packet = packet_name(&other), "mqtt: closing a connection whose first packet is not CONNECT");
            return;
        }
        Ok(Err(HandshakeError::Frame(error @ FrameError::UnsupportedProtocol { .. }))) => {
            add(&shared.counters.connections_refused, 1);
            tracing::warn!(%peer, %error, "mqtt: refusing CONNECT");
            send_connack(&mut writer, ConnectReturnCode::RefusedProtocolVersion).await;
            return;
        }
        Ok(Err(HandshakeError::Frame(error))) => {
            add(&shared.counters.protocol_violations, 1);
            tracing::warn!(%peer, %error, "mqtt: closing a connection before CONNECT");
            return;
        }
        Ok(Err(error)) => {
            tracing::debug!(%peer, %error, "mqtt: connection ended before CONNECT");
            return;
        }
        Err(_elapsed) => {
            tracing::warn!(%peer, timeout_s = CONNECT_TIMEOUT.as_secs(), "mqtt: no CONNECT in time, closing");
            return;
        }
    };
    let (access, credential) = match admit(&connect, &shared.config.tokens) {
        Ok(who) => (who.role.publish_level(), who.name),
        Err(code) => {
            add(&shared.counters.connections_refused, 1);
            tracing::warn!(%peer, client_id = %connect.client_id, ?code, "mqtt: refusing CONNECT");
            send_connack(&mut writer, code).await;
            return;
        }
    };
    drop(handshake);
    // a session slot, and for a read-only one a read slot: subscribers cannot fill the broker
    let limits = &shared.limits;
    let session_slot = Arc::clone(&limits.sessions).try_acquire_owned().ok();
    let read_slot = match access {
        Access::Read => Arc::clone(&limits.read_sessions).try_acquire_owned().ok().map(Some),
        _ => Some(None),
    };
    let (Some(_session_slot), Some(_read_slot)) = (session_slot, read_slot) else {
        add(&shared.counters.connections_refused, 1);
        tracing::warn!(%peer, client_id = %connect.client_id, ?access, "mqtt: session limit reached, refusing");
        send_connack(&mut writer, ConnectReturnCode::ServiceUnavailable).await;
        return;
    };
    let client_id = if connect.client_id.is_empty() {
        format!("rtls-anonymous-{connection_no}")
    } else {
        connect.client_id
    };
    let user = connect
        .login
        .as_ref()
        .map(|login| login.username.clone())
        .unwrap_or_default();
    let Some(taken_over) = shared.clients.register(&client_id, connection_no, &credential) else {
        add(&shared.counters.connections_refused, 1);
        tracing::warn!(%peer, %client_id, %credential, "mqtt: refusing CONNECT: the client id is held by a session of another credential");
        send_connack(&mut writer, ConnectReturnCode::BadClientId).await;
        return;
    };
    let _open = OpenConnection::new(&shared);
    tracing::info!(%peer, %client_id, %user, ?access, keep_alive_s = connect.keep_alive, "mqtt: client connected");

    let session = Session::accept(
        Arc::clone(&shared),
        client_id.clone(),
        access,
        connect.keep_alive,
        (reader, writer),
        inbox,
    );
    let reason = session.run(stop, &taken_over).await;
    shared.clients.unregister(&client_id, connection_no);
    if reason.is_orderly() {
        tracing::info!(%peer, %client_id, %reason, "mqtt: connection closed");
    } else {
        tracing::warn!(%peer, %client_id, %reason, "mqtt: connection closed");
    }
}

/// Answers a connection over the connection limit: waits (at most `wait`) for its CONNECT,
/// answers CONNACK "server unavailable" and closes.
pub(crate) async fn refuse_unavailable(
    (mut reader, mut writer): (Reader, Writer),
    peer: SocketAddr,
    shared: Arc<Shared>,
    wait: Duration,
) {
    let mut inbox = BytesMut::new();
    let first = timeout(
        wait,
        read_packet(&mut reader, &mut inbox, shared.config.max_packet_bytes),
    )
    .await;
    if let Ok(Ok(Packet::Connect(_))) = first {
        send_connack(&mut writer, ConnectReturnCode::ServiceUnavailable).await;
    }
    tracing::debug!(%peer, "mqtt: refused connection closed");
}

/// Decides a CONNECT: who its password names, or the CONNACK code refusing it.
fn admit(connect: &Connect, tokens: &Tokens) -> Result<Principal, ConnectReturnCode> {
    let id = &connect.client_id;
    // Wildcards or NUL would make the error topic `rtls/v1/errors/{client_id}` invalid; an
    // empty id needs a clean session (MQTT 3.1.1 §3.1.3-8).
    if id.contains(['+', '#', '\0']) || (id.is_empty() && !connect.clean_session) {
        return Err(ConnectReturnCode::BadClientId);
    }
    let password = connect
        .login
        .as_ref()
        .map(|login| login.password.as_str())
        .filter(|password| !password.is_empty());
    match tokens.principal(password) {
        Some(who) => Ok(who),
        None if password.is_some() => Err(ConnectReturnCode::BadUserNamePassword),
        None => Err(ConnectReturnCode::NotAuthorized),
    }
}

/// Why no packet could be read during the handshake.
#[derive(Debug, thiserror::Error)]
enum HandshakeError {
    #[error("{0}")]
    Frame(#[from] FrameError),
    #[error("i/o: {0}")]
    Io(#[from] std::io::Error),
    #[error("the client closed the connection")]
    Closed,
}

/// Reads until one whole packet has arrived and decodes it.
async fn read_packet(
    reader: &mut Reader,
    inbox: &mut BytesMut,
    max_packet_bytes: usize,
) -> Result<Packet, HandshakeError> {
    loop {
        match frame::next_packet(inbox, max_packet_bytes)? {
            Next::Packet(packet) => return Ok(packet),
            Next::Incomplete { needed_bytes } => {
                inbox.reserve(needed_bytes);
                if reader.read_buf(inbox).await? == 0 {
                    return Err(HandshakeError::Closed);
                }
            }
        }
    }
}

/// Writes a CONNACK (best effort: the connection closes next anyway).
async fn send_connack(writer: &mut Writer, code: ConnectReturnCode) {
    let mut out = BytesMut::new();
    if frame::encode(&Packet::ConnAck(ConnAck::new(code, false)), &mut out).is_ok() {
        let _ = timeout(CLOSE_WRITE_TIMEOUT, async {
            let _ = writer.write_all(&out).await;
            let _ = writer.shutdown().await;
        })
        .await;
    }
}

/// Counts an open session for as long as it lives.
struct OpenConnection(Arc<Shared>);

impl OpenConnection {
    fn new(shared: &Arc<Shared>) -> Self {
        add(&shared.counters.connections_open, 1);
        Self(Arc::clone(shared))
    }
}

impl Drop for OpenConnection {
    fn drop(&mut self) {
        self.0.counters.connections_open.fetch_sub(1, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What [`admit`] grants, in one level.
    fn admit_access(connect: &Connect, tokens: &Tokens) -> Result<Access, ConnectReturnCode> {
        admit(connect, tokens).map(|who| who.role.publish_level())
    }
    use rumqttc::mqttbytes::v4::Login;

    fn connect(client_id: &str, clean_session: bool, password: Option<&str>) -> Connect {
        let mut connect = Connect::new(client_id);
        connect.clean_session = clean_session;
        connect.login = password.map(|password| Login::new("reader", password));
        connect
    }

    #[test]
    fn admission_follows_the_token_and_names_the_refusal() {
        let tokens = Tokens::new("w-token", Some("r-token".into()));
        assert_eq!(
            admit_access(&connect("r1", true, Some("w-token")), &tokens),
            Ok(Access::Write)
        );
        assert_eq!(
            admit_access(&connect("r1", true, Some("r-token")), &tokens),
            Ok(Access::Read)
        );
        assert_eq!(
            admit_access(&connect("r1", true, Some("nope")), &tokens),
            Err(ConnectReturnCode::BadUserNamePassword)
        );
        assert_eq!(
            admit_access(&connect("r1", true, None), &tokens),
            Err(ConnectReturnCode::NotAuthorized)
        );
        // Without a read token, no password reads.
        let open_reads = Tokens::new("w-token", None);
        assert_eq!(admit_access(&connect("r1", true, None), &open_reads), Ok(Access::Read));
        // … but a wrong password is refused, not admitted as a reader
        assert_eq!(
            admit_access(&connect("r1", true, Some("guess")), &open_reads),
            Err(ConnectReturnCode::BadUserNamePassword)
        );
    }

    #[test]
    fn client_ids_that_break_the_error_topic_are_refused() {
        let tokens = Tokens::new("w", None);
        for id in ["a+b", "site/#", "nul\0"] {
            assert_eq!(
                admit_access(&connect(id, true, Some("w")), &tokens),
                Err(ConnectReturnCode::BadClientId),
                "{id:?}"
            );
        }
        assert_eq!(
            admit_access(&connect("", false, Some("w")), &tokens),
            Err(ConnectReturnCode::BadClientId)
        );
        assert_eq!(admit_access(&connect("", true, Some("w")), &tokens), Ok(Access::Write));
        assert_eq!(
            admit_access(&connect("site/reader-7", true, Some("w")), &tokens),
            Ok(Access::Write)
        );
    }
}
