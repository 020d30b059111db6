//! The live state the APIs read: each tag's latest location and each zone's head count.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, RwLock};

use rtls_engine::site::Site;
use rtls_engine::zones::Zone;
use serde_json::Value;

use super::collision_news::CollisionNews;
use super::trackables::TrackableIndex;
use crate::omlox::ws::Topic;
use crate::omlox::{Location, Proximity, Trackable};

/// A message for WebSocket subscribers, already in omlox JSON.
#[derive(Debug, Clone, PartialEq)]
pub enum HubMessage {
    /// A track update as an omlox `Location` (`location_updates`).
    Location {
        /// The tag.
        tag: String,
        /// The update's time (s, the records' clock: Unix seconds when live).
        time_s: f64,
        /// The `Location` object (shared with [`TagState`]: built once per update, written by
        /// each reader from the struct — no JSON value tree is built per update).
        location: Arc<Location>,
    },
    /// A zone entry or exit as an omlox `FenceEvent` (`fence_events`).
    FenceEvent {
        /// The tag.
        tag: String,
        /// The `FenceEvent` object.
        event: Value,
    },
    /// Two trackables started or stopped colliding, or still collide (`collision_events`);
    /// the omlox `CollisionEvent` is built when a subscriber first asks for it.
    Collision(Arc<CollisionNews>),
    /// A proximity a provider pushed (`PUT /v2/providers/proximities`), as received
    /// (`proximity_updates`).
    Proximity(Arc<Proximity>),
    /// A predictive alarm, lost tag, model switch, … on an extension topic.
    Extension {
        /// `rtls:alarms` or `rtls:events`.
        topic: Topic,
        /// The event (the engine's event JSON).
        event: Value,
    },
}

/// A tag's latest reported state.
#[derive(Debug, Clone, PartialEq)]
pub struct TagState {
    /// Its time (s).
    pub time_s: f64,
    /// Its position (m); the third coordinate is 0 for 2-D tracks.
    pub position_m: [f64; 3],
    /// Its lifecycle status (`tentative`, `confirmed`, `coasting`, `lost`).
    pub status: &'static str,
    /// The omlox `Location` (shared with the hub message that published it).
    pub location: Arc<Location>,
}

/// Latest locations and head counts, written by the partition threads.
pub struct LiveState {
    /// The zones now: the site's, or the zone editor's set (`set_zones`).
    zones: RwLock<Arc<Vec<Zone>>>,
    /// Incremented by every `set_zones`, so the partitions see an edit.
    zones_version: AtomicU64,
    latest: RwLock<HashMap<String, TagState>>,
    /// Per partition: the tags inside each zone.
    occupants: Vec<RwLock<HashMap<String, Vec<String>>>>,
    /// The latest alarms (their event JSON with `alarm_id`), oldest first.
    recent_alarms: RwLock<VecDeque<Value>>,
    /// Every tag's last known position, kept after its track is deleted: the muster board
    /// counts a tag that went silent on site as missing, not as gone.
    last_seen: RwLock<HashMap<String, LastSeen>>,
    /// Told every zone set [`LiveState::set_zones`] takes (a cluster sends it to the peers).
    zone_edits: std::sync::OnceLock<ZoneEditListener>,
    /// The latest locations each provider pushed (`PUT /v2/providers/locations`), oldest
    /// first, [`PUSHED_KEPT`] at most: a track's update comes after its fix's push, later ones
    /// may be pushed meanwhile.
    pushed: RwLock<HashMap<String, VecDeque<Arc<crate::pushed::PushedLocation>>>>,
    /// The stored omlox trackables by provider, for the topics about trackables.
    trackables: RwLock<Arc<TrackableIndex>>,
    /// How many `collision_events` subscriptions are open ([`CollisionListener`]).
    collision_listeners: Arc<AtomicUsize>,
}

/// An open `collision_events` subscription: while one is held, the collision thread publishes
/// what it finds on the hub ([`LiveState::collisions_listened`]); dropping it closes it.
#[derive(Debug)]
pub struct CollisionListener(Arc<AtomicUsize>);

impl Drop for CollisionListener {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::AcqRel);
    }
}

impl std::fmt::Debug for LiveState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LiveState")
            .field("zones_version", &self.zones_version)
            .finish_non_exhaustive()
    }
}

/// Pushed locations kept per provider.
const PUSHED_KEPT: usize = 32;

/// What is told of a zone edit.
pub(super) type ZoneEditListener = Box<dyn Fn(&[Zone]) + Send + Sync>;

/// A tag's last known position for the muster board.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LastSeen {
    /// When (s, the records' clock).
    pub time_s: f64,
    /// Where (m).
    pub position_m: [f64; 3],
    /// Whether its track is lost or deleted since.
    pub lost: bool,
}

/// How many recent alarms the live state keeps (older ones are in the store).
pub const RECENT_ALARMS: usize = 10_000;

impl LiveState {
    pub(super) fn new(site: &Site, partitions: usize) -> Self {
        Self {
            zones: RwLock::new(Arc::new(site.zones.clone())),
            zones_version: AtomicU64::new(0),
            latest: RwLock::new(HashMap::new()),
            occupants: (0..partitions.max(1)).map(|_| RwLock::new(HashMap::new())).collect(),
            recent_alarms: RwLock::new(VecDeque::new()),
            last_seen: RwLock::new(HashMap::new()),
            zone_edits: std::sync::OnceLock::new(),
            trackables: RwLock::default(),
            pushed: RwLock::default(),
            collision_listeners: Arc::default(),
        }
    }

    /// Opens a `collision_events` subscription (held by the WebSocket's subscription).
    #[must_use]
    pub fn listen_for_collisions(&self) -> CollisionListener {
        self.collision_listeners.fetch_add(1, Ordering::AcqRel);
        CollisionListener(Arc::clone(&self.collision_listeners))
    }

    /// Whether a `collision_events` subscription is open. The collision thread judges every
    /// update either way (its pairs' starts and ends stay right), but publishes only then: a
    /// trackable colliding with n others is n messages per update, which nobody else reads.
    #[must_use]
    pub fn collisions_listened(&self) -> bool {
        self.collision_listeners.load(Ordering::Acquire) > 0
    }

    /// Notes a location a provider pushed (its track's outputs keep what it said).
    pub fn note_pushed(&self, pushed: crate::pushed::PushedLocation) {
        if let Ok(mut all) = self.pushed.write() {
            let kept = all.entry(pushed.location.provider_id.clone()).or_default();
            if kept.len() == PUSHED_KEPT {
                kept.pop_front();
            }
            kept.push_back(Arc::new(pushed));
        }
    }

    /// The location `tag`'s provider pushed for the fix of `time_s`, else its newest; `None`
    /// when it pushes none.
    #[must_use]
    pub fn pushed(&self, tag: &str, time_s: f64) -> Option<Arc<crate::pushed::PushedLocation>> {
        let all = self.pushed.read().ok()?;
        let kept = all.get(tag)?;
        kept.iter()
            .rev()
            .find(|p| crate::pushed::same_time(p.time_s, time_s))
            .or_else(|| kept.back())
            .cloned()
    }

    /// The stored trackables by provider ([`TrackableIndex`]).
    #[must_use]
    pub fn trackables(&self) -> Arc<TrackableIndex> {
        self.trackables.read().map(|t| Arc::clone(&t)).unwrap_or_default()
    }

    /// Replaces the stored trackables (after a change to them through the API, or at start).
    pub fn set_trackables(&self, trackables: Vec<Trackable>) {
        if let Ok(mut slot) = self.trackables.write() {
            *slot = Arc::new(TrackableIndex::new(trackables));
        }
    }

    /// The site's zones.
    #[must_use]
    pub fn zones(&self) -> Arc<Vec<Zone>> {
        self.zones.read().map(|z| Arc::clone(&z)).unwrap_or_default()
    }

    /// The zone set's version: 0 for the site's, one more for every edit.
    #[must_use]
    pub fn zones_version(&self) -> u64 {
        self.zones_version.load(Ordering::Acquire)
    }

    /// Replaces the zones (validated by the caller): head counts list them at once, the
    /// partitions hand them to their trackers within a clock tick.
    pub fn set_zones(&self, zones: Vec<Zone>) {
        if let Some(listener) = self.zone_edits.get() {
            listener(&zones);
        }
        self.adopt_zones(zones);
    }

    /// Replaces the zones without telling the edit listener (a cluster peer's edit).
    pub(super) fn adopt_zones(&self, zones: Vec<Zone>) {
        if let Ok(mut slot) = self.zones.write() {
            *slot = Arc::new(zones);
            self.zones_version.fetch_add(1, Ordering::AcqRel);
        }
    }

    /// Sets the listener told of every zone edit (once; a second is ignored).
    pub(super) fn on_zone_edit(&self, listener: ZoneEditListener) {
        let _ = self.zone_edits.set(listener);
    }

    /// A tag's latest state.
    #[must_use]
    pub fn tag(&self, tag: &str) -> Option<TagState> {
        self.latest.read().ok()?.get(tag).cloned()
    }

    /// Whether `tag` has a latest state (without copying it).
    #[must_use]
    pub fn has_tag(&self, tag: &str) -> bool {
        self.latest.read().is_ok_and(|latest| latest.contains_key(tag))
    }

    /// Every tag's latest state, ordered by tag.
    #[must_use]
    pub fn tags(&self) -> BTreeMap<String, TagState> {
        self.latest
            .read()
            .map(|latest| latest.iter().map(|(k, v)| (k.clone(), v.clone())).collect())
            .unwrap_or_default()
    }

    /// Calls `f` with every tag's latest state, under the read lock (no copies).
    pub fn for_each_tag(&self, mut f: impl FnMut(&str, &TagState)) {
        if let Ok(latest) = self.latest.read() {
            for (tag, state) in latest.iter() {
                f(tag, state);
            }
        }
    }

    /// Number of tags with a state.
    #[must_use]
    pub fn tag_count(&self) -> usize {
        self.latest.read().map_or(0, |latest| latest.len())
    }

    /// Tags inside each zone (confirmed entries), for every zone of the site.
    #[must_use]
    pub fn head_counts(&self) -> BTreeMap<String, usize> {
        self.occupants()
            .into_iter()
            .map(|(zone, tags)| (zone, tags.len()))
            .collect()
    }

    /// The tags inside each zone (confirmed entries), sorted, for every zone of the site.
    #[must_use]
    pub fn occupants(&self) -> BTreeMap<String, Vec<String>> {
        let mut inside: BTreeMap<String, Vec<String>> =
            self.zones().iter().map(|z| (z.id.clone(), Vec::new())).collect();
        for partition in &self.occupants {
            if let Ok(partition) = partition.read() {
                for (zone, tags) in partition.iter() {
                    // a partition may not have seen a zone edit yet: deleted zones are not listed
                    if let Some(inside) = inside.get_mut(zone) {
                        inside.extend(tags.iter().cloned());
                    }
                }
            }
        }
        for tags in inside.values_mut() {
            tags.sort_unstable();
        }
        inside
    }

    /// The recent alarm with this id (its event JSON), if it is among the last `RECENT_ALARMS` (10 000).
    #[must_use]
    pub fn recent_alarm(&self, alarm_id: &str) -> Option<Value> {
        self.recent_alarms
            .read()
            .ok()?
            .iter()
            .rev()
            .find(|alarm| alarm["alarm_id"].as_str() == Some(alarm_id))
            .cloned()
    }

    pub(super) fn note_alarm(&self, alarm: &Value) {
        if let Ok(mut recent) = self.recent_alarms.write() {
            if recent.len() == RECENT_ALARMS {
                recent.pop_front();
            }
            recent.push_back(alarm.clone());
        }
    }

    /// Every tag ever tracked since the start, with its last known position (tags whose
    /// track was deleted included, marked lost), ordered by tag.
    #[must_use]
    pub fn last_seen(&self) -> BTreeMap<String, LastSeen> {
        self.last_seen
            .read()
            .map(|seen| seen.iter().map(|(k, v)| (k.clone(), *v)).collect())
            .unwrap_or_default()
    }

    pub(super) fn set_tag(&self, tag: &str, state: TagState) {
        if let Ok(mut seen) = self.last_seen.write() {
            let last = LastSeen {
                time_s: state.time_s,
                position_m: state.position_m,
                lost: state.status == "lost",
            };
            match seen.get_mut(tag) {
                Some(slot) => *slot = last,
                None => {
                    seen.insert(tag.to_string(), last);
                }
            }
        }
        if let Ok(mut latest) = self.latest.write() {
            // the key is allocated once per tag, not per update
            match latest.get_mut(tag) {
                Some(slot) => *slot = state,
                None => {
                    latest.insert(tag.to_string(), state);
                }
            }
        }
    }

    /// Forgets a tag's latest state (its track was deleted, or a client deleted its omlox
    /// location): it is listed again at its track's next update. Its last known position
    /// stays for the muster board, marked lost.
    pub fn remove_tag(&self, tag: &str) {
        if let Ok(mut seen) = self.last_seen.write() {
            if let Some(last) = seen.get_mut(tag) {
                last.lost = true;
            }
        }
        if let Ok(mut latest) = self.latest.write() {
            latest.remove(tag);
        }
    }

    pub(super) fn set_occupants(&self, partition: usize, occupants: HashMap<String, Vec<String>>) {
        if let Some(Ok(mut slot)) = self.occupants.get(partition).map(|p| p.write()) {
            *slot = occupants;
        }
    }
}
