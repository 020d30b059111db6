//! Where a partition's outputs go: this node's live state and broadcasts, and — in a cluster —
//! the other nodes, which apply the same messages to theirs ([`PeerMessage`]).
//!
//! Every node serves the APIs, the WebSocket and MQTT subscribers and the dashboard for every
//! tag, but only the node that owns a tag's partition tracks it: what its partition threads
//! produce is applied here and sent to the peers (`rtls.out.<node>` on NATS, by
//! `crate::cluster`), whose [`Fanout::apply`] writes it to their live state and broadcasts.
//!
//! Collision events are not sent on: every node judges them itself from the same track
//! updates (`super::collisions`), with the same name-based event ids. Proximities pushed to
//! one node are.

use std::collections::HashMap;
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use serde_json::Value;
use tokio::sync::{broadcast, mpsc};

use super::live::{HubMessage, LiveState, TagState};
use crate::metrics::Metrics;
use crate::omlox::ws::Topic;
use crate::omlox::{Location, Proximity};
use crate::sink::Publication;
use rtls_engine::tracker::AnchorOffsetSummary;

/// One output of a partition, as it travels to the other nodes of a cluster (JSON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum PeerMessage {
    /// A track update: the tag's live state and the `location_updates` message.
    Location {
        /// The tag.
        tag: String,
        /// The update's time (s).
        time_s: f64,
        /// Its position (m).
        position_m: [f64; 3],
        /// Its lifecycle status name.
        status: String,
        /// The omlox `Location`.
        location: Box<Location>,
    },
    /// A track deleted: the tag leaves the live state.
    Removed {
        /// The tag.
        tag: String,
    },
    /// A hub message without live state (a fence event, an extension event).
    Hub {
        /// The tag of a fence event; `None` for an extension event.
        tag: Option<String>,
        /// The topic of an extension event; `None` for a fence event.
        topic: Option<Topic>,
        /// The event.
        event: Value,
    },
    /// An alarm for the recent-alarm list (acknowledgements look it up).
    Alarm {
        /// The alarm's event JSON with its `alarm_id`.
        event: Value,
    },
    /// A partition's zone occupants.
    Occupants {
        /// The partition.
        partition: usize,
        /// Zone id → tags inside.
        occupants: HashMap<String, Vec<String>>,
    },
    /// An MQTT publication (tracks and events topics).
    Publication {
        /// The MQTT topic.
        topic: String,
        /// The payload (JSON text).
        payload: String,
    },
    /// A proximity a provider pushed to the node that sends it (`proximity_updates`).
    Proximity {
        /// The `Proximity`, as pushed.
        proximity: Box<Proximity>,
    },
    /// A location a provider pushed to the node that sends it (its track's outputs keep what
    /// the provider said, on whichever node tracks it).
    Pushed {
        /// As pushed.
        location: Box<Location>,
        /// Its time (s).
        time_s: f64,
    },
    /// Readers named by records another node received: `(reader, records)` at `at_ms`.
    ReadersHeard {
        /// Each reader and how many records named it.
        counts: Vec<(String, u64)>,
        /// When they were received (ms since the Unix epoch).
        at_ms: i64,
    },
    /// What a partition's tracks learnt of the readers' range offsets (reader health).
    Offsets {
        /// The partition.
        partition: usize,
        /// Per reader: `(reader, tags, mean_m, min_m, max_m, mean_std_m)`.
        summaries: Vec<(String, usize, f64, f64, f64, f64)>,
    },
    /// The zone set was edited through the API (on the node that stored the edit).
    Zones {
        /// The whole set.
        zones: Vec<rtls_engine::zones::Zone>,
    },
}

/// The live state and broadcasts of this node, and the way to the peers (cluster mode).
#[derive(Clone)]
pub struct Fanout {
    pub(super) live: Arc<LiveState>,
    pub(super) hub: broadcast::Sender<Arc<HubMessage>>,
    pub(super) publications: broadcast::Sender<Publication>,
    /// The cluster's outbound queue (bounded: a full queue drops and counts the message).
    pub(super) peers: Option<mpsc::Sender<PeerMessage>>,
    /// In a cluster: this node's own hub messages and publications only, for what must leave
    /// the cluster once (webhooks, an external MQTT broker), not once per node.
    pub(super) local: Option<(broadcast::Sender<Arc<HubMessage>>, broadcast::Sender<Publication>)>,
    pub(super) metrics: Arc<Metrics>,
    /// Reader health (records heard, learnt range offsets).
    pub(super) readers: Arc<super::ReaderMonitor>,
}

impl Fanout {
    /// To the peers, if there are any; a full queue costs the message (counted).
    pub(super) fn to_peers(&self, message: impl FnOnce() -> PeerMessage) {
        if let Some(peers) = &self.peers {
            if peers.try_send(message()).is_err() {
                self.metrics.cluster_peer_messages_dropped.inc();
            }
        }
    }

    pub(super) fn set_tag(&self, tag: &str, state: TagState) {
        self.to_peers(|| PeerMessage::Location {
            tag: tag.to_string(),
            time_s: state.time_s,
            position_m: state.position_m,
            status: state.status.to_string(),
            location: Box::new((*state.location).clone()),
        });
        self.live.set_tag(tag, state);
    }

    pub(super) fn remove_tag(&self, tag: &str) {
        self.to_peers(|| PeerMessage::Removed { tag: tag.to_string() });
        self.live.remove_tag(tag);
    }

    /// A hub message; a location's is sent to the peers with its live state by `set_tag`.
    pub(super) fn hub(&self, message: HubMessage) {
        match &message {
            HubMessage::Location { .. } => {}
            HubMessage::FenceEvent { tag, event } => self.to_peers(|| PeerMessage::Hub {
                tag: Some(tag.clone()),
                topic: None,
                event: event.clone(),
            }),
            HubMessage::Extension { topic, event } => self.to_peers(|| PeerMessage::Hub {
                tag: None,
                topic: Some(*topic),
                event: event.clone(),
            }),
            HubMessage::Proximity(proximity) => self.to_peers(|| PeerMessage::Proximity {
                proximity: Box::new(Proximity::clone(proximity)),
            }),
            // every node judges collisions from the track updates it applies
            HubMessage::Collision(_) => {}
        }
        let message = Arc::new(message);
        if let Some((local_hub, _)) = &self.local {
            let _ = local_hub.send(Arc::clone(&message));
        }
        // no subscriber is not an error
        let _ = self.hub.send(message);
    }

    pub(super) fn publish(&self, publication: Publication) {
        self.to_peers(|| PeerMessage::Publication {
            topic: publication.topic.clone(),
            payload: String::from_utf8_lossy(&publication.payload).into_owned(),
        });
        if let Some((_, local_publications)) = &self.local {
            let _ = local_publications.send(publication.clone());
        }
        let _ = self.publications.send(publication);
    }

    pub(super) fn note_alarm(&self, alarm: &Value) {
        self.to_peers(|| PeerMessage::Alarm { event: alarm.clone() });
        self.live.note_alarm(alarm);
    }

    pub(super) fn set_occupants(&self, partition: usize, occupants: HashMap<String, Vec<String>>) {
        self.to_peers(|| PeerMessage::Occupants {
            partition,
            occupants: occupants.clone(),
        });
        self.live.set_occupants(partition, occupants);
    }

    /// Posts what a partition's tracks learnt of the readers' range offsets, here and to the
    /// peers.
    pub(super) fn post_offsets(&self, partition: usize, summaries: Vec<AnchorOffsetSummary>) {
        self.to_peers(|| PeerMessage::Offsets {
            partition,
            summaries: summaries
                .iter()
                .map(|s| (s.anchor.clone(), s.tags, s.mean_m, s.min_m, s.max_m, s.mean_std_m))
                .collect(),
        });
        self.readers.learnt_offsets(partition, summaries);
    }

    /// This node's own hub messages (all of them without a cluster).
    pub(super) fn subscribe_local(&self) -> broadcast::Receiver<Arc<HubMessage>> {
        self.local
            .as_ref()
            .map_or_else(|| self.hub.subscribe(), |(hub, _)| hub.subscribe())
    }

    /// This node's own publications (all of them without a cluster).
    pub(super) fn local_publications(&self) -> broadcast::Sender<Publication> {
        self.local
            .as_ref()
            .map_or_else(|| self.publications.clone(), |(_, publications)| publications.clone())
    }

    /// Applies a peer's message to this node's live state and broadcasts (not sent on).
    pub(super) fn apply(&self, message: PeerMessage) {
        match message {
            PeerMessage::Location {
                tag,
                time_s,
                position_m,
                status,
                location,
            } => {
                let location = Arc::new(*location);
                self.live.set_tag(
                    &tag,
                    TagState {
                        time_s,
                        position_m,
                        status: status_of(&status),
                        location: Arc::clone(&location),
                    },
                );
                let _ = self.hub.send(Arc::new(HubMessage::Location { tag, time_s, location }));
            }
            PeerMessage::Removed { tag } => self.live.remove_tag(&tag),
            PeerMessage::Hub { tag, topic, event } => {
                let message = match (tag, topic) {
                    (_, Some(topic)) => HubMessage::Extension { topic, event },
                    (Some(tag), None) => HubMessage::FenceEvent { tag, event },
                    (None, None) => return,
                };
                let _ = self.hub.send(Arc::new(message));
            }
            PeerMessage::Alarm { event } => self.live.note_alarm(&event),
            PeerMessage::Occupants { partition, occupants } => self.live.set_occupants(partition, occupants),
            PeerMessage::Publication { topic, payload } => {
                let _ = self.publications.send(Publication {
                    topic,
                    payload: payload.into(),
                });
            }
            PeerMessage::Proximity { proximity } => {
                let _ = self.hub.send(Arc::new(HubMessage::Proximity(Arc::new(*proximity))));
            }
            PeerMessage::Zones { zones } => self.live.adopt_zones(zones),
            PeerMessage::Pushed { location, time_s } => self.live.note_pushed(crate::pushed::PushedLocation {
                location: *location,
                time_s,
            }),
            PeerMessage::ReadersHeard { counts, at_ms } => self.readers.heard_counts(&counts, at_ms),
            PeerMessage::Offsets { partition, summaries } => self.readers.learnt_offsets(
                partition,
                summaries
                    .into_iter()
                    .map(|(anchor, tags, mean_m, min_m, max_m, mean_std_m)| AnchorOffsetSummary {
                        anchor,
                        tags,
                        mean_m,
                        min_m,
                        max_m,
                        mean_std_m,
                    })
                    .collect(),
            ),
        }
    }
}

/// The `'static` name of a lifecycle status sent by a peer (an unknown one reads `confirmed`).
fn status_of(name: &str) -> &'static str {
    match name {
        "tentative" => "tentative",
        "coasting" => "coasting",
        "lost" => "lost",
        "deleted" => "deleted",
        _ => "confirmed",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fanout(peers: Option<mpsc::Sender<PeerMessage>>) -> Fanout {
        let site = rtls_engine::site::Site::from_toml_str(
            "[[readers]]\nid = \"R1\"\nposition_m = [0.0, 0.0]\ntechnology = \"uwb\"\n",
            "site.toml",
        )
        .expect("site");
        Fanout {
            live: Arc::new(LiveState::new(&site, 2)),
            hub: broadcast::channel(16).0,
            publications: broadcast::channel(16).0,
            local: peers
                .as_ref()
                .map(|_| (broadcast::channel(16).0, broadcast::channel(16).0)),
            peers,
            metrics: Arc::new(Metrics::new()),
            readers: Arc::new(crate::pipeline::ReaderMonitor::new(&site, 0)),
        }
    }

    #[test]
    fn what_a_partition_produces_reaches_a_peer_as_it_was_applied_here() {
        let (tx, mut rx) = mpsc::channel(16);
        let owner = fanout(Some(tx));
        let peer = fanout(None);
        let mut hub = peer.hub.subscribe();
        let location: Location = serde_json::from_value(serde_json::json!({
            "position": { "type": "Point", "coordinates": [1.0, 2.0] },
            "source": "rtls", "provider_type": "uwb", "provider_id": "t1", "crs": "local"
        }))
        .expect("location");
        owner.set_tag(
            "t1",
            TagState {
                time_s: 10.0,
                position_m: [1.0, 2.0, 0.0],
                status: "coasting",
                location: Arc::new(location),
            },
        );
        owner.set_occupants(1, HashMap::from([("z".to_string(), vec!["t1".to_string()])]));
        owner.remove_tag("gone");
        let mut sent = Vec::new();
        while let Ok(message) = rx.try_recv() {
            // the wire is JSON
            let text = serde_json::to_string(&message).expect("serialise");
            sent.push(serde_json::from_str::<PeerMessage>(&text).expect("parse"));
        }
        assert_eq!(sent.len(), 3);
        for message in sent {
            peer.apply(message);
        }
        assert_eq!(peer.live.tag("t1"), owner.live.tag("t1"));
        assert_eq!(peer.live.occupants(), owner.live.occupants());
        assert!(
            matches!(&*hub.try_recv().expect("a location message"), HubMessage::Location { tag, .. } if tag == "t1")
        );
    }

    #[test]
    fn proximities_reach_the_peers_and_collisions_stay_on_their_node() {
        let (tx, mut rx) = mpsc::channel(16);
        let owner = fanout(Some(tx));
        let peer = fanout(None);
        let mut hub = peer.hub.subscribe();
        let proximity: Proximity = serde_json::from_value(serde_json::json!({
            "source": "gate-3", "provider_type": "rfid", "provider_id": "rfid-77", "accuracy": 0.4
        }))
        .expect("proximity");
        owner.hub(HubMessage::Proximity(Arc::new(proximity.clone())));
        let side = |id: &str| crate::omlox::collision::Side {
            id: id.into(),
            provider_id: id.into(),
            coordinates: vec![0.0, 0.0],
            floor: 0.0,
            extent_m: 1.0,
        };
        owner.hub(HubMessage::Collision(Arc::new(
            crate::pipeline::collision_news::CollisionNews::new(crate::omlox::collision::Transition {
                kind: crate::omlox::CollisionType::CollisionStart,
                trigger: side("a"),
                other: side("b"),
                start_s: 1.0,
                time_s: 1.0,
                distance_m: 0.5,
                area_m: Some([0.25, 0.0]),
            }),
        )));
        let sent: Vec<PeerMessage> = std::iter::from_fn(|| rx.try_recv().ok()).collect();
        assert_eq!(sent.len(), 1, "{sent:?}");
        let text = serde_json::to_string(&sent[0]).expect("serialise");
        peer.apply(serde_json::from_str(&text).expect("parse"));
        assert_eq!(
            *hub.try_recv().expect("the proximity"),
            HubMessage::Proximity(Arc::new(proximity))
        );
    }

    #[test]
    fn reader_health_counts_what_every_node_received_and_learnt() {
        let (tx, mut rx) = mpsc::channel(16);
        let owner = fanout(Some(tx));
        let peer = fanout(None);
        owner.to_peers(|| PeerMessage::ReadersHeard {
            counts: vec![("R1".into(), 3)],
            at_ms: 1_000,
        });
        let summary = AnchorOffsetSummary {
            anchor: "R1".into(),
            tags: 2,
            mean_m: 0.12,
            min_m: 0.1,
            max_m: 0.14,
            mean_std_m: 0.02,
        };
        owner.post_offsets(4, vec![summary.clone()]);
        while let Ok(message) = rx.try_recv() {
            let text = serde_json::to_string(&message).expect("serialise");
            peer.apply(serde_json::from_str(&text).expect("parse"));
        }
        let health = peer.readers.health(1_000);
        let r1 = health.iter().find(|r| r.id == "R1").expect("R1");
        assert_eq!((r1.records, r1.last_heard_ms), (3, Some(1_000)));
        assert_eq!(r1.range_offset.as_ref(), Some(&summary));
    }

    #[test]
    fn a_full_peer_queue_costs_the_message_and_counts_it() {
        let (tx, _rx) = mpsc::channel(1);
        let owner = fanout(Some(tx));
        owner.remove_tag("a");
        owner.remove_tag("b");
        assert_eq!(owner.metrics.cluster_peer_messages_dropped.get(), 1);
    }
}
