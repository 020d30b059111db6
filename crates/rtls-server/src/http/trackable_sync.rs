//! The stored omlox trackables handed to the live state, where the WebSocket topics about
//! trackables (`trackable_motions`, `collision_events`) read them
//! ([`crate::pipeline::trackables`]): at start, after every change through this node's API,
//! and — in a cluster, whose nodes share the database — every [`CLUSTER_PERIOD`], so a change
//! made through another node arrives within that time.

use std::future::Future;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use super::{AppState, QueryStore, TRACKABLE_CONFIG};
use crate::omlox::Trackable;
use crate::pipeline::Pipeline;
use crate::store::{Store, StoreError};

/// How often a cluster node re-reads the stored trackables.
pub const CLUSTER_PERIOD: Duration = Duration::from_secs(5);

/// The stored trackables; a corrupt one is logged and left out.
///
/// # Errors
/// The store's error.
pub fn read_trackables(store: &mut dyn Store) -> Result<Vec<Trackable>, StoreError> {
    Ok(store
        .list_config(TRACKABLE_CONFIG)?
        .into_iter()
        .filter_map(|(id, json)| match serde_json::from_str(&json) {
            Ok(trackable) => Some(trackable),
            Err(e) => {
                tracing::error!(trackable = %id, error = %e, "stored trackable is corrupt; left out of the live topics");
                None
            }
        })
        .collect())
}

/// Hands the stored trackables to the live state after a change through the API. The change
/// is made: a failed read is logged, and the next change (or restart) hands them over.
pub(super) async fn refresh_trackables(state: &AppState) {
    match state.query(read_trackables).await {
        Ok(trackables) => state.pipeline.live().set_trackables(trackables),
        Err(e) => tracing::error!(error = %e.message, "stored trackables not re-read after a change"),
    }
}

/// Re-reads the stored trackables every `period` until `stopped` (a cluster node).
pub async fn refresh_trackables_every(
    queries: Arc<Mutex<QueryStore>>,
    pipeline: Pipeline,
    period: Duration,
    stopped: impl Future<Output = ()>,
) {
    tokio::pin!(stopped);
    loop {
        tokio::select! {
            () = &mut stopped => return,
            () = tokio::time::sleep(period) => {}
        }
        let store = Arc::clone(&queries);
        let read = tokio::task::spawn_blocking(move || match store.lock() {
            Ok(mut store) => store.trackables(),
            Err(_) => Err("the query connection failed".to_string()),
        })
        .await;
        match read {
            Ok(Ok(trackables)) => pipeline.live().set_trackables(trackables),
            Ok(Err(e)) => tracing::warn!(error = %e, "stored trackables not re-read"),
            Err(e) => tracing::warn!(error = %e, "stored trackables not re-read"),
        }
    }
}

impl QueryStore {
    /// The stored trackables ([`read_trackables`]).
    ///
    /// # Errors
    /// The store's error, or a closed connection.
    pub fn trackables(&mut self) -> Result<Vec<Trackable>, String> {
        read_trackables(self.get().map_err(|e| e.message)?).map_err(|e| e.to_string())
    }
}
