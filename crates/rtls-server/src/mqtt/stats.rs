//! The embedded broker's counters: the live atomics every connection task adds to, and their
//! public snapshot and handle.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// A snapshot of the embedded broker's counters (totals since it started, except
/// `connections_open`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BrokerStats {
    /// TCP connections accepted.
    pub connections_accepted: u64,
    /// MQTT sessions open now (CONNECT accepted, not yet closed).
    pub connections_open: u64,
    /// Connections refused at CONNECT: wrong token, protocol version, client id, or the
    /// connection limit.
    pub connections_refused: u64,
    /// Connections closed for a protocol violation: malformed or oversize packet, forbidden
    /// PUBLISH (read-only token, topic outside the prefix, QoS 2), unexpected packet.
    pub protocol_violations: u64,
    /// Measurement PUBLISH packets handed to the sink.
    pub publishes_received: u64,
    /// Records the sink stored from them.
    pub records_stored: u64,
    /// PUBACKs sent.
    pub acks_sent: u64,
    /// Payloads the sink refused as invalid (acknowledged and reported on the error topic).
    pub publishes_invalid: u64,
    /// Payloads the sink could not take (not acknowledged; the connection was closed).
    pub publishes_unavailable: u64,
    /// Publications written to subscribers.
    pub messages_delivered: u64,
    /// Publications a lagging subscriber missed.
    pub messages_dropped: u64,
}

/// The live counters behind [`BrokerStats`].
#[derive(Debug, Default)]
pub(crate) struct Counters {
    pub(crate) connections_accepted: AtomicU64,
    pub(crate) connections_open: AtomicU64,
    pub(crate) connections_refused: AtomicU64,
    pub(crate) protocol_violations: AtomicU64,
    pub(crate) publishes_received: AtomicU64,
    pub(crate) records_stored: AtomicU64,
    pub(crate) acks_sent: AtomicU64,
    pub(crate) publishes_invalid: AtomicU64,
    pub(crate) publishes_unavailable: AtomicU64,
    pub(crate) messages_delivered: AtomicU64,
    pub(crate) messages_dropped: AtomicU64,
}

/// Adds `amount` to a counter.
pub(crate) fn add(counter: &AtomicU64, amount: u64) {
    counter.fetch_add(amount, Ordering::Relaxed);
}

/// A cheap, cloneable handle on the embedded broker's counters that outlives
/// [`EmbeddedBroker::run`](super::EmbeddedBroker::run)'s consumption of the broker (e.g. for a
/// metrics endpoint).
#[derive(Debug, Clone)]
pub struct BrokerStatsHandle(pub(super) Arc<Counters>);

impl BrokerStatsHandle {
    /// The counters now.
    #[must_use]
    pub fn snapshot(&self) -> BrokerStats {
        let c = &self.0;
        let get = |counter: &AtomicU64| counter.load(Ordering::Relaxed);
        BrokerStats {
            connections_accepted: get(&c.connections_accepted),
            connections_open: get(&c.connections_open),
            connections_refused: get(&c.connections_refused),
            protocol_violations: get(&c.protocol_violations),
            publishes_received: get(&c.publishes_received),
            records_stored: get(&c.records_stored),
            acks_sent: get(&c.acks_sent),
            publishes_invalid: get(&c.publishes_invalid),
            publishes_unavailable: get(&c.publishes_unavailable),
            messages_delivered: get(&c.messages_delivered),
            messages_dropped: get(&c.messages_dropped),
        }
    }
}
