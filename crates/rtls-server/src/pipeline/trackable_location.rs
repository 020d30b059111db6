//! Where a trackable is: which of its providers' latest locations it takes. The one place a
//! trackable's location is derived from its providers'; every consumer asks here — the REST
//! reads (`/v2/trackables/{id}/location`, `…/motion`, `trackables/motions`, the fences a
//! trackable is inside and the trackables inside a fence), the WebSocket's `trackable_motions`,
//! the collision judge and the trackable-level fence events.
//!
//! Each tag has its own track (the engine tracks per tag; a trackable's providers are not fused
//! into one track), so a trackable's location is chosen among its providers' latest locations:
//!
//! - **Without `locating_rules`** (absent or empty) it takes every provider's: its location is
//!   the newest of them, every update of any provider moves it, and it is inside a fence while
//!   one of its providers is — the hub's behaviour before rules were evaluated.
//! - **With rules** it takes the one location the rules select
//!   ([`crate::omlox::locating_rules`]: highest priority matched, then newest, then most
//!   accurate) and no other: an update moves it only when the update is that location, and it
//!   is inside a fence while that provider is. When no provider's latest location matches a
//!   rule it has no location (no motion; it leaves its fences and collisions).

use std::sync::Arc;

use super::live::LiveState;
use super::trackables::TrackableIndex;
use crate::omlox::locating_rules::{Candidate, RuleSet};
use crate::omlox::{Location, Trackable};

/// Which of its providers' locations a trackable takes now.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Taking {
    /// Every provider's (a trackable without rules).
    All,
    /// This provider's only.
    One(String),
    /// None: no provider's latest location matches a rule.
    Nothing,
}

impl Taking {
    /// Whether the trackable takes `provider`'s locations.
    #[must_use]
    pub fn takes(&self, provider: &str) -> bool {
        match self {
            Self::All => true,
            Self::One(taken) => taken == provider,
            Self::Nothing => false,
        }
    }
}

/// A provider's latest location, and its time (s, the records' clock).
#[derive(Debug, Clone)]
pub struct Latest {
    /// The provider (tag).
    pub provider: String,
    /// The location's time, s.
    pub time_s: f64,
    /// The location.
    pub location: Arc<Location>,
}

/// What one update of a provider does to one trackable it is a provider of.
#[derive(Debug, Clone)]
pub struct Moved {
    /// The trackable.
    pub trackable: Arc<Trackable>,
    /// Whether the update is the trackable's location now (a motion of it).
    pub moves: bool,
    /// Which providers' locations the trackable takes after the update.
    pub taking: Taking,
}

/// The providers' latest locations `trackable` takes now (module documentation): every one
/// without rules, the selected one (or none) with them; in the order of its
/// `location_providers`.
#[must_use]
pub fn taken(trackable: &Trackable, rules: &RuleSet, live: &LiveState) -> Vec<Latest> {
    let latest = latest_of(trackable, live, None);
    if rules.is_empty() {
        return latest;
    }
    select(rules, &latest)
        .map(|i| vec![latest[i].clone()])
        .unwrap_or_default()
}

/// A stored trackable's location: the newest of the locations it takes ([`taken`]), its rules
/// parsed as stored (a rule that does not parse is left out, logged).
#[must_use]
pub fn trackable_location(trackable: &Trackable, live: &LiveState) -> Option<Arc<Location>> {
    taken(trackable, &RuleSet::of_stored(trackable), live)
        .into_iter()
        .max_by(|a, b| a.time_s.total_cmp(&b.time_s))
        .map(|latest| latest.location)
}

/// What an update of `tag` (at `time_s`) does to each trackable it moves or may move
/// ([`TrackableIndex::of`]): judged with the update as `tag`'s latest location and the other
/// providers' latest locations from `live`.
#[must_use]
pub fn moved_by(
    index: &TrackableIndex,
    live: &LiveState,
    tag: &str,
    time_s: f64,
    location: &Arc<Location>,
) -> Vec<Moved> {
    index
        .of(tag)
        .iter()
        .map(|trackable| {
            let Some(rules) = index.rules(&trackable.id) else {
                return Moved {
                    trackable: Arc::clone(trackable),
                    moves: true,
                    taking: Taking::All,
                };
            };
            let update = Latest {
                provider: tag.to_string(),
                time_s,
                location: Arc::clone(location),
            };
            let latest = latest_of(trackable, live, Some(update));
            let taking = match select(rules, &latest) {
                Some(i) => Taking::One(latest[i].provider.clone()),
                None => Taking::Nothing,
            };
            Moved {
                trackable: Arc::clone(trackable),
                moves: taking.takes(tag),
                taking,
            }
        })
        .collect()
}

/// The latest location of each of `trackable`'s providers that has one (each provider once),
/// `update` standing for its provider's.
fn latest_of(trackable: &Trackable, live: &LiveState, update: Option<Latest>) -> Vec<Latest> {
    let mut latest: Vec<Latest> = Vec::new();
    for provider in trackable.location_providers.iter().flatten() {
        if latest.iter().any(|l| &l.provider == provider) {
            continue;
        }
        match &update {
            Some(update) if &update.provider == provider => latest.push(update.clone()),
            _ => {
                if let Some(state) = live.tag(provider) {
                    latest.push(Latest {
                        provider: provider.clone(),
                        time_s: state.time_s,
                        location: state.location,
                    });
                }
            }
        }
    }
    latest
}

/// The index of the location `rules` select among `latest`.
fn select(rules: &RuleSet, latest: &[Latest]) -> Option<usize> {
    let candidates: Vec<Candidate<'_>> = latest
        .iter()
        .map(|l| Candidate {
            time_s: l.time_s,
            location: &l.location,
        })
        .collect();
    rules.select(&candidates)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::omlox::LocatingRule;
    use crate::pipeline::live::TagState;
    use crate::pipeline::trackables::implicit_trackable;

    fn location(tag: &str, kind: &str, x: f64, accuracy: f64) -> Arc<Location> {
        Arc::new(
            serde_json::from_value(serde_json::json!({
                "position": {"type": "Point", "coordinates": [x, 0.0]}, "source": "s",
                "provider_type": kind, "provider_id": tag, "accuracy": accuracy
            }))
            .expect("a location"),
        )
    }

    fn live_with(latest: &[(&str, f64, &Arc<Location>)]) -> LiveState {
        let site = rtls_engine::site::Site::from_toml_str(
            "[[readers]]\nid = \"R1\"\nposition_m = [0.0, 0.0]\ntechnology = \"uwb\"\n",
            "site.toml",
        )
        .expect("site");
        let live = LiveState::new(&site, 1);
        for (tag, time_s, location) in latest {
            live.set_tag(
                tag,
                TagState {
                    time_s: *time_s,
                    position_m: [location.position.coordinates[0], 0.0, 0.0],
                    status: "confirmed",
                    location: Arc::clone(location),
                },
            );
        }
        live
    }

    fn cart(rules: &[(&str, f64)]) -> Trackable {
        Trackable {
            location_providers: Some(vec!["uwb-1".into(), "ble-1".into()]),
            locating_rules: Some(
                rules
                    .iter()
                    .map(|(expression, priority)| LocatingRule {
                        expression: (*expression).into(),
                        priority: *priority,
                    })
                    .collect(),
            ),
            ..implicit_trackable("cart")
        }
    }

    const RULES: [(&str, f64); 2] = [("type = 'uwb' AND accuracy < 1", 10.0), ("type = 'ibeacon'", 1.0)];

    #[test]
    fn with_rules_the_selected_provider_moves_the_trackable_and_no_other() {
        let (good, poor, ble) = (
            location("uwb-1", "uwb", 1.0, 0.3),
            location("uwb-1", "uwb", 1.5, 5.0),
            location("ble-1", "ibeacon", 9.0, 3.0),
        );
        let index = TrackableIndex::new(vec![cart(&RULES)]);
        // the uwb fix is taken though the beacon's is newer
        let live = live_with(&[("uwb-1", 10.0, &good), ("ble-1", 11.0, &ble)]);
        let moved = moved_by(&index, &live, "ble-1", 11.0, &ble);
        assert_eq!(moved.len(), 1);
        assert!(!moved[0].moves, "the beacon does not move the cart");
        assert_eq!(moved[0].taking, Taking::One("uwb-1".into()));
        let at = trackable_location(&cart(&RULES), &live).expect("a location");
        assert_eq!(at.position.coordinates[0], 1.0);
        // a poor uwb fix matches no rule: it does not move the cart, which now takes the beacon
        let moved = moved_by(&index, &live, "uwb-1", 12.0, &poor);
        assert!(!moved[0].moves);
        assert_eq!(moved[0].taking, Taking::One("ble-1".into()));
        let live = live_with(&[("uwb-1", 12.0, &poor), ("ble-1", 11.0, &ble)]);
        assert_eq!(
            trackable_location(&cart(&RULES), &live)
                .expect("a location")
                .position
                .coordinates[0],
            9.0
        );
        assert!(moved_by(&index, &live, "ble-1", 13.0, &ble)[0].moves);
        // nothing matches: no location at all
        let only_poor = live_with(&[("uwb-1", 12.0, &poor)]);
        assert_eq!(trackable_location(&cart(&RULES), &only_poor), None);
        assert_eq!(
            moved_by(&index, &only_poor, "uwb-1", 12.0, &poor)[0].taking,
            Taking::Nothing
        );
    }

    #[test]
    fn without_rules_every_update_moves_it_and_its_location_is_the_newest() {
        let (good, ble) = (
            location("uwb-1", "uwb", 1.0, 0.3),
            location("ble-1", "ibeacon", 9.0, 3.0),
        );
        let index = TrackableIndex::new(vec![cart(&[])]);
        let live = live_with(&[("uwb-1", 10.0, &good), ("ble-1", 11.0, &ble)]);
        for (tag, location) in [("uwb-1", &good), ("ble-1", &ble)] {
            let moved = moved_by(&index, &live, tag, 11.0, location);
            assert!(moved[0].moves, "{tag}");
            assert_eq!(moved[0].taking, Taking::All);
        }
        assert_eq!(
            trackable_location(&cart(&[]), &live)
                .expect("a location")
                .position
                .coordinates[0],
            9.0
        );
        assert_eq!(taken(&cart(&[]), &RuleSet::default(), &live).len(), 2);
    }
}
