//! The outputs between nodes: this node's on `rtls.out.<node>` (JSON arrays of
//! [`PeerMessage`]s, as many as are waiting), the other nodes' applied here.

use futures_util::StreamExt;
use tokio::sync::{mpsc, watch};

use super::{Cluster, OUTPUT_SUBJECT};
use crate::pipeline::{PeerMessage, Pipeline};

/// Messages sent in one NATS message at most.
const BATCH_MESSAGES: usize = 512;

/// Sends this node's outputs until the queue closes or `shutdown`.
pub async fn send(cluster: Cluster, mut queue: mpsc::Receiver<PeerMessage>, mut shutdown: watch::Receiver<bool>) {
    let subject = format!("{OUTPUT_SUBJECT}.{}", cluster.node);
    let mut batch = Vec::with_capacity(BATCH_MESSAGES);
    loop {
        tokio::select! {
            received = queue.recv_many(&mut batch, BATCH_MESSAGES) => if received == 0 { break },
            _ = shutdown.changed() => break,
        }
        match serde_json::to_vec(&batch) {
            Ok(payload) => {
                if let Err(e) = cluster.client.publish(subject.clone(), payload.into()).await {
                    tracing::warn!(error = %e, messages = batch.len(), "sending outputs to the other nodes failed");
                }
            }
            Err(e) => tracing::error!(error = %e, "outputs not serialisable"),
        }
        batch.clear();
    }
}

/// Applies the other nodes' outputs to this node until `shutdown`.
///
/// # Errors
/// The subscription's failure, as text.
pub async fn receive(cluster: Cluster, pipeline: Pipeline, mut shutdown: watch::Receiver<bool>) -> Result<(), String> {
    let own = format!("{OUTPUT_SUBJECT}.{}", cluster.node);
    let mut subscription = cluster
        .client
        .subscribe(format!("{OUTPUT_SUBJECT}.*"))
        .await
        .map_err(|e| format!("subscribing to the other nodes' outputs: {e}"))?;
    loop {
        let message = tokio::select! {
            message = subscription.next() => match message { Some(m) => m, None => break },
            _ = shutdown.changed() => break,
        };
        if message.subject.as_str() == own {
            continue;
        }
        match serde_json::from_slice::<Vec<PeerMessage>>(&message.payload) {
            Ok(messages) => {
                for peer_message in messages {
                    pipeline.apply_peer(peer_message);
                }
            }
            Err(e) => tracing::error!(subject = %message.subject, error = %e, "a peer's outputs do not parse; skipped"),
        }
    }
    Ok(())
}
