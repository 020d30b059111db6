//! Trackable-level fence events (omlox `FenceEvent` with `trackable_id`, `provider_id` absent):
//! a trackable is inside a fence while at least one of its providers is. Its entry is the first
//! provider's entry, its exit the last provider's exit; the providers' own events stay as they
//! are. Derived from the providers' fence events as they reach the hub (each names the
//! trackables its provider is assigned to), so every node of a cluster derives the same ones
//! from the same events, as it judges collisions.

use std::collections::{BTreeSet, HashMap};

use crate::convert::uuid_for;
use crate::omlox::{FenceEvent, FenceEventType};

/// Which providers of each trackable are inside each fence, and since when.
#[derive(Debug, Default)]
pub(crate) struct TrackableFences {
    /// (trackable id, fence id) → the providers inside and the trackable's entry time.
    inside: HashMap<(String, String), (BTreeSet<String>, Option<String>)>,
}

impl TrackableFences {
    /// The trackable-level events a provider's fence event causes: an entry for each of its
    /// trackables that had no provider inside, an exit for each whose last provider left.
    /// Events without a provider (a trackable's own) cause none.
    pub(crate) fn on_provider_event(&mut self, event: &FenceEvent) -> Vec<FenceEvent> {
        let Some(provider) = event.provider_id.as_deref() else {
            return Vec::new();
        };
        let mut derived = Vec::new();
        for trackable in event.trackables.iter().flatten() {
            let key = (trackable.clone(), event.fence_id.clone());
            let (providers, entered) = self.inside.entry(key.clone()).or_default();
            let transition = match event.event_type {
                FenceEventType::RegionEntry => {
                    let first = providers.is_empty();
                    providers.insert(provider.to_string());
                    if first {
                        *entered = event.entry_time.clone();
                    }
                    first
                }
                FenceEventType::RegionExit => providers.remove(provider) && providers.is_empty(),
            };
            if !transition {
                continue;
            }
            let entry_time = entered.clone();
            if event.event_type == FenceEventType::RegionExit {
                self.inside.remove(&key);
            }
            let time = event.exit_time.as_deref().or(event.entry_time.as_deref()).unwrap_or("");
            derived.push(FenceEvent {
                id: uuid_for(
                    "fence-event",
                    &format!("{trackable}\0{}\0{:?}\0{time}", event.fence_id, event.event_type),
                ),
                fence_id: event.fence_id.clone(),
                event_type: event.event_type,
                provider_id: None,
                trackable_id: Some(trackable.clone()),
                trackables: None,
                foreign_id: event.foreign_id.clone(),
                entry_time,
                exit_time: event.exit_time.clone(),
                properties: event.properties.clone(),
            });
        }
        derived
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn provider_event(provider: &str, kind: FenceEventType, time: &str, trackables: &[&str]) -> FenceEvent {
        let entry = kind == FenceEventType::RegionEntry;
        FenceEvent {
            id: format!("{provider}-{time}"),
            fence_id: "f".into(),
            event_type: kind,
            provider_id: Some(provider.into()),
            trackable_id: None,
            trackables: Some(trackables.iter().map(|t| (*t).to_string()).collect()),
            foreign_id: None,
            entry_time: entry.then(|| time.to_string()),
            exit_time: (!entry).then(|| time.to_string()),
            properties: None,
        }
    }

    #[test]
    fn a_trackable_is_inside_while_one_of_its_providers_is() {
        use FenceEventType::{RegionEntry as In, RegionExit as Out};
        let mut fences = TrackableFences::default();
        // a forklift with two tags, a pallet with the second tag only
        let first_in = fences.on_provider_event(&provider_event("tag-1", In, "t1", &["forklift"]));
        assert_eq!(first_in.len(), 1);
        assert_eq!(first_in[0].trackable_id.as_deref(), Some("forklift"));
        assert_eq!(first_in[0].provider_id, None);
        assert_eq!(first_in[0].entry_time.as_deref(), Some("t1"));
        let second_in = fences.on_provider_event(&provider_event("tag-2", In, "t2", &["forklift", "pallet"]));
        let ids: Vec<_> = second_in.iter().map(|e| e.trackable_id.clone().unwrap()).collect();
        assert_eq!(ids, ["pallet"], "the forklift was in already");
        let first_out = fences.on_provider_event(&provider_event("tag-1", Out, "t3", &["forklift"]));
        assert!(first_out.is_empty(), "tag-2 keeps the forklift inside");
        let last_out = fences.on_provider_event(&provider_event("tag-2", Out, "t4", &["forklift", "pallet"]));
        assert_eq!(last_out.len(), 2);
        for exit in &last_out {
            assert_eq!(exit.event_type, Out);
            assert_eq!(exit.exit_time.as_deref(), Some("t4"));
        }
        // the exit carries the trackable's own entry time
        let forklift = last_out
            .iter()
            .find(|e| e.trackable_id.as_deref() == Some("forklift"))
            .unwrap();
        assert_eq!(forklift.entry_time.as_deref(), Some("t1"));
        // a provider without trackables, or a trackable's own event, derives nothing
        assert!(fences
            .on_provider_event(&provider_event("tag-9", In, "t5", &[]))
            .is_empty());
        let own = FenceEvent {
            provider_id: None,
            trackable_id: Some("forklift".into()),
            ..provider_event("x", In, "t6", &["forklift"])
        };
        assert!(fences.on_provider_event(&own).is_empty());
    }
}
