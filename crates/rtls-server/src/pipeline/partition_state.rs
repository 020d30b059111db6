//! A partition's checkpoint (cluster): its tracker's state ([`TrackerState`]) with what the
//! partition thread keeps beside it, encoded as CBOR (which keeps the non-finite floats the
//! state holds), and its restore on the partition's next owner.

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};

use rtls_engine::site::Site;
use rtls_engine::tracker::{Output, TrackerState};
use serde::{Deserialize, Serialize};

use super::partition::PartitionWorker;

/// The layout of [`PartitionCheckpoint`]; a checkpoint of another layout is not restored.
const FORMAT: u32 = 1;

/// What a partition's next owner needs to continue where the checkpoint was taken.
#[derive(Serialize, Deserialize)]
struct PartitionCheckpoint {
    format: u32,
    /// The site (and build) the state belongs to ([`site_fingerprint`]).
    site: u64,
    tracker: TrackerState,
    /// Entry time (s) of each (tag, zone) a tag is in.
    zone_entries: Vec<(String, String, f64)>,
    /// Tags whose lost state has been published once.
    reported_lost: Vec<String>,
}

/// A fingerprint of the site and of this build's version: a checkpoint taken under another
/// site file or release is not restored (the partition warms up from its records instead).
#[must_use]
pub fn site_fingerprint(site: &Site) -> u64 {
    let mut hasher = DefaultHasher::new();
    env!("CARGO_PKG_VERSION").hash(&mut hasher);
    format!("{site:?}").hash(&mut hasher);
    hasher.finish()
}

impl PartitionWorker {
    /// The partition's state, encoded.
    pub(super) fn checkpoint(&self) -> Result<Vec<u8>, String> {
        let checkpoint = PartitionCheckpoint {
            format: FORMAT,
            site: self.site_fingerprint,
            tracker: self.tracker.state(),
            zone_entries: self
                .zone_entries
                .iter()
                .map(|((tag, zone), entered_s)| (tag.clone(), zone.clone(), *entered_s))
                .collect(),
            reported_lost: self.reported_lost.iter().cloned().collect(),
        };
        let mut bytes = Vec::new();
        ciborium::into_writer(&checkpoint, &mut bytes).map_err(|e| format!("encoding the checkpoint: {e}"))?;
        Ok(bytes)
    }

    /// Continues from an encoded checkpoint: the tracks, zone entries and lost tags replace
    /// this partition's; the live zone set is handed to the tracker again and the occupants
    /// published. Returns the number of tracks.
    ///
    /// # Errors
    /// Why the checkpoint was not taken (another format, site or build; it does not decode;
    /// the tracker refused it); the partition is unchanged then.
    pub(super) fn restore(&mut self, bytes: &[u8], out: &mut Output) -> Result<usize, String> {
        let checkpoint: PartitionCheckpoint =
            ciborium::from_reader(bytes).map_err(|e| format!("the checkpoint does not decode: {e}"))?;
        if checkpoint.format != FORMAT {
            return Err(format!(
                "checkpoint format {} (this build reads {FORMAT})",
                checkpoint.format
            ));
        }
        if checkpoint.site != self.site_fingerprint {
            return Err("the checkpoint was taken under another site file or release".into());
        }
        // a fresh tracker with the live zone set first: alarm flags and memberships then
        // follow their zone's id into the zones this node has now
        let zones_version = self.fanout.live.zones_version();
        let mut tracker = rtls_engine::tracker::Tracker::new(&self.site).map_err(|e| e.to_string())?;
        tracker
            .replace_zones(self.fanout.live.zones().to_vec())
            .map_err(|e| format!("the live zones: {e}"))?;
        tracker.restore(checkpoint.tracker).map_err(|e| e.to_string())?;
        self.tracker = tracker;
        self.zones_version = zones_version;
        out.clear();
        self.pending_events.clear();
        self.zone_entries = checkpoint
            .zone_entries
            .into_iter()
            .map(|(tag, zone, entered_s)| ((tag, zone), entered_s))
            .collect();
        self.reported_lost = checkpoint.reported_lost.into_iter().collect();
        self.publish_occupants();
        Ok(self.tracker.track_count())
    }
}
