//! The collision thread: reads every track update from the hub, moves the trackables its tag
//! belongs to ([`super::trackables`]) in one [`CollisionDetector`], and publishes the
//! collisions it finds on the hub as [`CollisionNews`] (each an omlox `CollisionEvent` for
//! `collision_events`, built when a subscriber first asks for it). It also
//! turns the providers' fence events into the trackables' ([`super::trackable_fences`]),
//! published on the hub as `fence_events`.
//!
//! One thread for every partition's tags, since two colliding tags may be tracked on
//! different partitions. It reads the hub as a WebSocket client does: if it falls more than
//! the broadcast capacity behind it misses updates (logged), and the trackables concerned are
//! judged again at their next update. It holds the hub weakly and ends when the pipeline's
//! last sender is gone.
//!
//! Each update is judged against the other trackables' newest updates as they reached the hub.
//! Live, the partitions keep pace with the records' clock and those are a fraction of a
//! second apart; a replayed burst, though, may run one partition's whole stretch of time
//! before another's, and collisions between their tags in that stretch are then not seen.

use std::sync::Arc;

use tokio::sync::broadcast;
use tokio::sync::broadcast::error::RecvError;

use super::collision_news::CollisionNews;
use super::live::{HubMessage, LiveState};
use super::trackable_fences::TrackableFences;
use super::trackable_location::{moved_by, Taking};
use crate::omlox::collision::{Body, CollisionDetector, CollisionSettings};
use crate::omlox::{FenceEvent, Location, Trackable};

pub(super) struct CollisionWorker {
    pub live: Arc<LiveState>,
    pub hub: broadcast::WeakSender<Arc<HubMessage>>,
    pub rx: broadcast::Receiver<Arc<HubMessage>>,
    pub detector: CollisionDetector,
    /// How the detector judges (to start afresh).
    pub settings: CollisionSettings,
    /// Hub messages missed by falling behind (`rtls_collision_updates_missed_total`).
    pub missed: prometheus_client::metrics::counter::Counter,
    /// The trackables inside each fence.
    pub fences: TrackableFences,
}

impl CollisionWorker {
    pub(super) fn new(
        live: Arc<LiveState>,
        hub: &broadcast::Sender<Arc<HubMessage>>,
        settings: CollisionSettings,
        missed: prometheus_client::metrics::counter::Counter,
    ) -> Self {
        Self {
            missed,
            live,
            rx: hub.subscribe(),
            hub: hub.downgrade(),
            detector: CollisionDetector::new(settings),
            settings,
            fences: TrackableFences::default(),
        }
    }

    pub(super) fn run(mut self) {
        loop {
            match self.rx.blocking_recv() {
                Ok(message) => {
                    let going_on = match message.as_ref() {
                        HubMessage::Location { tag, time_s, location } => self.on_location(tag, *time_s, location),
                        HubMessage::FenceEvent { tag, event } => self.on_fence_event(tag, event),
                        _ => true,
                    };
                    if !going_on {
                        return;
                    }
                }
                Err(RecvError::Lagged(missed)) => {
                    self.missed.inc_by(missed);
                    tracing::warn!(missed, "collision detection fell behind the track updates");
                }
                Err(RecvError::Closed) => return,
            }
        }
    }

    /// Judges one update; `false` when the hub is gone.
    fn on_location(&mut self, tag: &str, time_s: f64, location: &Arc<Location>) -> bool {
        let lost = location
            .properties
            .as_ref()
            .and_then(|p| p.get("rtls:status"))
            .and_then(|s| s.as_str())
            == Some("lost");
        let index = self.live.trackables();
        // collisions are judged only while a collision_events subscription is open: otherwise
        // nobody reads them, and the detector forgets what it knew, so a subscriber who comes
        // later is told of each collision as it starts (at the pair's next update)
        let listened = self.live.collisions_listened();
        if !listened && !self.detector.is_empty() {
            self.detector = CollisionDetector::new(self.settings);
        }
        let mut transitions = Vec::new();
        let mut fence_events = Vec::new();
        // one judgement of which trackables this update moves (locating_rules)
        for moved in moved_by(&index, &self.live, tag, time_s, location) {
            let trackable = &moved.trackable;
            fence_events.extend(self.fences.on_taking(&trackable.id, moved.taking.clone(), time_s));
            if !listened {
                continue;
            }
            if moved.moves && !lost {
                transitions.extend(self.detector.update(body(trackable, tag, time_s, location)));
            } else if moved.moves || moved.taking == Taking::Nothing {
                // lost, or no provider's location matches its rules: it is nowhere to judge
                transitions.extend(self.detector.remove(&trackable.id, time_s));
            }
        }
        if transitions.is_empty() && fence_events.is_empty() {
            return true;
        }
        if !self.publish_fence_events(tag, fence_events) {
            return false;
        }
        let Some(hub) = self.hub.upgrade() else {
            return false;
        };
        for transition in transitions {
            // the omlox event is built only if a subscriber wants it (CollisionNews::event)
            // no subscriber is not an error
            let _ = hub.send(Arc::new(HubMessage::Collision(Arc::new(CollisionNews::new(
                transition,
            )))));
        }
        true
    }
}

impl CollisionWorker {
    /// Publishes the trackable-level events of a provider's fence event; `false` when the hub
    /// is gone.
    fn on_fence_event(&mut self, tag: &str, event: &serde_json::Value) -> bool {
        // a trackable's own event (derived here) names no provider: nothing to derive
        if event.get("provider_id").is_none() {
            return true;
        }
        let Ok(event) = serde_json::from_value::<FenceEvent>(event.clone()) else {
            return true;
        };
        // which providers each trackable takes is known from the track updates, which a
        // partition publishes before the fence events of the same step
        let derived = self.fences.on_provider_event(&event);
        self.publish_fence_events(tag, derived)
    }

    /// Publishes trackable-level fence events on the hub; `false` when the hub is gone.
    fn publish_fence_events(&self, tag: &str, events: Vec<FenceEvent>) -> bool {
        if events.is_empty() {
            return true;
        }
        let Some(hub) = self.hub.upgrade() else {
            return false;
        };
        for trackable_event in events {
            if let Ok(event) = serde_json::to_value(trackable_event) {
                // no subscriber is not an error
                let _ = hub.send(Arc::new(HubMessage::FenceEvent {
                    tag: tag.to_string(),
                    event,
                }));
            }
        }
        true
    }
}

/// `trackable` at `location`, an update of its provider `tag` (module documentation of
/// [`crate::omlox::collision`] for what is judged).
fn body(trackable: &Trackable, tag: &str, time_s: f64, location: &Location) -> Body {
    Body {
        id: trackable.id.clone(),
        provider_id: tag.to_string(),
        time_s,
        coordinates: location.position.coordinates.clone(),
        floor: location.floor.unwrap_or(0.0),
        radius_m: trackable.radius.unwrap_or(0.0).max(0.0),
        sigma_m: location.accuracy.unwrap_or(0.0),
        exit_tolerance_m: trackable.exit_tolerance.unwrap_or(0.0).max(0.0),
        // ms; absent or negative (−1 in the spec) is no timeout
        tolerance_timeout_s: trackable
            .tolerance_timeout
            .filter(|ms| *ms >= 0.0)
            .map(|ms| ms / 1000.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn falling_behind_the_hub_is_counted() {
        let site = rtls_engine::site::Site::from_toml_str(
            "[[readers]]\nid = \"R1\"\nposition_m = [0.0, 0.0]\ntechnology = \"uwb\"\n",
            "site.toml",
        )
        .expect("site");
        let (hub, _) = broadcast::channel(2);
        let missed = prometheus_client::metrics::counter::Counter::default();
        let worker = CollisionWorker::new(
            Arc::new(LiveState::new(&site, 1)),
            &hub,
            CollisionSettings::default(),
            missed.clone(),
        );
        for k in 0..5 {
            hub.send(Arc::new(HubMessage::Extension {
                topic: crate::omlox::ws::Topic::RtlsEvents,
                event: serde_json::json!({ "k": k }),
            }))
            .expect("a subscriber");
        }
        drop(hub);
        // five messages into a ring of two: three missed, then the hub is gone and it ends
        worker.run();
        assert_eq!(missed.get(), 3);
    }

    type Hub = broadcast::Sender<Arc<HubMessage>>;

    /// A worker on a fresh hub: the live state, the hub, a receiver of what it publishes.
    fn worker() -> (
        Arc<LiveState>,
        Hub,
        broadcast::Receiver<Arc<HubMessage>>,
        CollisionWorker,
    ) {
        let site = rtls_engine::site::Site::from_toml_str(
            "[[readers]]\nid = \"R1\"\nposition_m = [0.0, 0.0]\ntechnology = \"uwb\"\n",
            "site.toml",
        )
        .expect("site");
        let live = Arc::new(LiveState::new(&site, 1));
        let (hub, published) = broadcast::channel(64);
        let worker = CollisionWorker::new(
            Arc::clone(&live),
            &hub,
            CollisionSettings::default(),
            prometheus_client::metrics::counter::Counter::default(),
        );
        (live, hub, published, worker)
    }

    /// `tag`'s location at (x, 0) m, σ 0.1 m.
    fn location(tag: &str, x: f64) -> Arc<Location> {
        Arc::new(
            serde_json::from_value(serde_json::json!({
                "position": {"type": "Point", "coordinates": [x, 0.0]},
                "source": "test", "provider_type": "uwb", "provider_id": tag, "accuracy": 0.1
            }))
            .expect("location"),
        )
    }

    /// Two tags 0.3 m apart, each updated twice, judged by a worker; the collisions it published.
    fn collisions_published(listening: bool) -> usize {
        let (live, _hub, mut published, mut worker) = worker();
        let listener = listening.then(|| live.listen_for_collisions());
        assert_eq!(live.collisions_listened(), listening);
        for (k, (tag, x)) in [("a", 0.0), ("b", 0.3), ("a", 0.0), ("b", 0.3)].into_iter().enumerate() {
            assert!(
                worker.on_location(tag, k as f64 * 0.1, &location(tag, x)),
                "the hub is there"
            );
        }
        drop(listener);
        assert!(!live.collisions_listened(), "the subscription closed with its listener");
        std::iter::from_fn(|| published.try_recv().ok())
            .filter(|m| matches!(m.as_ref(), HubMessage::Collision(_)))
            .count()
    }

    #[test]
    fn a_listener_who_comes_later_is_told_of_the_collision_as_it_starts() {
        let (live, hub, mut published, mut worker) = worker();
        // judged while nobody listens: nothing kept, nothing published
        assert!(worker.on_location("a", 0.0, &location("a", 0.0)));
        assert!(worker.on_location("b", 0.1, &location("b", 0.3)));
        assert!(worker.detector.is_empty());
        let _listener = live.listen_for_collisions();
        assert!(worker.on_location("a", 0.2, &location("a", 0.0)));
        assert!(worker.on_location("b", 0.3, &location("b", 0.3)));
        drop(hub);
        let kinds: Vec<_> = std::iter::from_fn(|| published.try_recv().ok())
            .filter_map(|m| match m.as_ref() {
                HubMessage::Collision(news) => Some(news.transition.kind),
                _ => None,
            })
            .collect();
        assert_eq!(kinds, [crate::omlox::CollisionType::CollisionStart]);
    }

    #[test]
    fn collisions_are_published_only_while_someone_listens() {
        // a start at b's first update, colliding at each of the next two
        assert_eq!(collisions_published(true), 3);
        assert_eq!(collisions_published(false), 0);
    }
}
