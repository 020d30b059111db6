//! What every connection task of the embedded broker shares: its configuration, the sink, the
//! publication channel, the counters and the registry of client ids.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};

use tokio::sync::{broadcast, Notify, Semaphore};

use crate::limits::IpSlots;
use crate::sink::{MeasurementSink, Publication};

use super::config::BrokerConfig;
use super::stats::Counters;

/// The sessions by client id, so that a new CONNECT with an id in use closes the older session
/// (MQTT 3.1.1 §3.1.4) — when it comes with the same credential: nobody can disconnect a reader
/// by reusing its client id with another token (or none).
#[derive(Debug, Default)]
pub(crate) struct ClientRegistry {
    sessions: Mutex<HashMap<String, Registered>>,
}

/// A registered session: its connection number, its credential's name, and how to tell it to
/// close.
type Registered = (u64, String, Arc<Notify>);

impl ClientRegistry {
    /// Registers session `connection_no` of `credential` (the token's name) as `client_id`,
    /// tells the session it replaces (if any) to close, and returns the signal by which this
    /// session will be told; `None` (nothing registered) when the id is held by a session of
    /// another credential.
    pub(crate) fn register(&self, client_id: &str, connection_no: u64, credential: &str) -> Option<Arc<Notify>> {
        let mut sessions = self.sessions.lock().unwrap_or_else(PoisonError::into_inner);
        if sessions.get(client_id).is_some_and(|(_, held, _)| held != credential) {
            return None;
        }
        let taken_over = Arc::new(Notify::new());
        let registered = (connection_no, credential.to_owned(), Arc::clone(&taken_over));
        if let Some((_, _, previous)) = sessions.insert(client_id.to_owned(), registered) {
            previous.notify_one();
        }
        Some(taken_over)
    }

    /// Removes `client_id` unless a newer session registered it since.
    pub(crate) fn unregister(&self, client_id: &str, connection_no: u64) {
        let mut sessions = self.sessions.lock().unwrap_or_else(PoisonError::into_inner);
        if sessions.get(client_id).is_some_and(|(no, _, _)| *no == connection_no) {
            sessions.remove(client_id);
        }
    }
}

/// The broker's connection limits as semaphores: handshakes waiting for CONNECT, sessions,
/// read-only sessions; and the connections per IP address.
pub(crate) struct Limits {
    pub(crate) pending: Arc<Semaphore>,
    pub(crate) sessions: Arc<Semaphore>,
    pub(crate) read_sessions: Arc<Semaphore>,
    pub(crate) per_ip: Arc<IpSlots>,
}

impl Limits {
    pub(crate) fn new(config: &BrokerConfig) -> Self {
        Self {
            pending: Arc::new(Semaphore::new(config.max_pending_connects)),
            sessions: Arc::new(Semaphore::new(config.max_connections)),
            read_sessions: Arc::new(Semaphore::new(config.max_read_connections.min(config.max_connections))),
            per_ip: Arc::default(),
        }
    }
}

/// What every connection task shares.
pub(crate) struct Shared {
    pub(crate) config: BrokerConfig,
    pub(crate) sink: Arc<dyn MeasurementSink>,
    pub(crate) publications: broadcast::Sender<Publication>,
    pub(crate) counters: Arc<Counters>,
    pub(crate) clients: ClientRegistry,
    pub(crate) limits: Limits,
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;

    #[test]
    fn a_second_session_with_the_same_client_id_takes_over() {
        let registry = ClientRegistry::default();
        let first = registry.register("reader-1", 1, "gateway-north").expect("free id");
        let other = registry.register("reader-2", 2, "gateway-north").expect("free id");
        // another credential cannot take the id
        assert!(registry.register("reader-1", 5, "anonymous").is_none());
        assert!(registry.register("reader-1", 6, "gateway-south").is_none());
        let second = registry
            .register("reader-1", 3, "gateway-north")
            .expect("same credential");
        // The first session was told; a notified() future now completes at once.
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_time()
            .build()
            .expect("runtime");
        runtime.block_on(async {
            tokio::time::timeout(Duration::from_millis(100), first.notified())
                .await
                .expect("the first session is told to close");
            assert!(tokio::time::timeout(Duration::from_millis(20), other.notified())
                .await
                .is_err());
            assert!(tokio::time::timeout(Duration::from_millis(20), second.notified())
                .await
                .is_err());
        });
        // The first session's unregister must not remove the second one's entry.
        registry.unregister("reader-1", 1);
        let third = registry.register("reader-1", 4, "gateway-north");
        runtime.block_on(async {
            tokio::time::timeout(Duration::from_millis(100), second.notified())
                .await
                .expect("the second session is still registered and is told");
        });
        drop(third);
    }
}
