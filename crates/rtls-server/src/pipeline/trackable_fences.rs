//! Trackable-level fence events (omlox `FenceEvent` with `trackable_id`, `provider_id` absent):
//! a trackable is inside a fence while at least one of the providers whose locations it takes
//! is ([`super::trackable_location`]: any of its providers without `locating_rules`, the one
//! they select with them). Its entry is the first such provider's entry, its exit the last
//! one's exit — or the moment its rules switch to a provider inside (an entry) or away from
//! the last one inside (an exit); the providers' own events stay as they are. Derived from the
//! providers' fence events and track updates as they reach the hub (each fence event names the
//! trackables its provider is assigned to), so every node of a cluster derives the same ones
//! from the same messages, as it judges collisions.

use std::collections::{BTreeSet, HashMap};

use super::trackable_location::Taking;
use crate::convert::uuid_for;
use crate::omlox::time::format_timestamp;
use crate::omlox::{FenceEvent, FenceEventType, Properties};

/// Which providers of each trackable are inside each fence, and whether the trackable is.
#[derive(Debug, Default)]
pub(crate) struct TrackableFences {
    /// (trackable id, fence id) → its occupancy.
    inside: HashMap<(String, String), Occupancy>,
    /// Which providers' locations each trackable takes; absent: all of them.
    taking: HashMap<String, Taking>,
}

/// A trackable's providers inside one fence.
#[derive(Debug, Default)]
struct Occupancy {
    /// The providers inside, taken or not.
    providers: BTreeSet<String>,
    /// Whether the trackable is inside, and since when (its entry's `entry_time`).
    entered: Option<Option<String>>,
    /// The fence's `foreign_id` and the `properties` of the last provider event (copied onto
    /// the trackable's).
    foreign_id: Option<String>,
    properties: Option<Properties>,
}

impl TrackableFences {
    /// The trackable-level events a provider's fence event causes: an entry for each of its
    /// trackables that had no taken provider inside, an exit for each whose last taken
    /// provider left. Events without a provider (a trackable's own) cause none.
    pub(crate) fn on_provider_event(&mut self, event: &FenceEvent) -> Vec<FenceEvent> {
        let Some(provider) = event.provider_id.as_deref() else {
            return Vec::new();
        };
        let time = event.exit_time.as_deref().or(event.entry_time.as_deref()).unwrap_or("");
        let mut derived = Vec::new();
        for trackable in event.trackables.iter().flatten() {
            let key = (trackable.clone(), event.fence_id.clone());
            let occupancy = self.inside.entry(key.clone()).or_default();
            match event.event_type {
                FenceEventType::RegionEntry => occupancy.providers.insert(provider.to_string()),
                FenceEventType::RegionExit => occupancy.providers.remove(provider),
            };
            occupancy.foreign_id.clone_from(&event.foreign_id);
            occupancy.properties.clone_from(&event.properties);
            derived.extend(self.settle(&key, time));
        }
        derived
    }

    /// The trackable-level events of `trackable` now taking `taking` (at `time_s`, the
    /// records' clock): an entry into each fence where it now takes a provider inside and did
    /// not, an exit from each where it no longer does. None when `taking` did not change.
    pub(crate) fn on_taking(&mut self, trackable: &str, taking: Taking, time_s: f64) -> Vec<FenceEvent> {
        let before = self.taking.get(trackable).unwrap_or(&Taking::All);
        if *before == taking {
            return Vec::new();
        }
        if taking == Taking::All {
            self.taking.remove(trackable);
        } else {
            self.taking.insert(trackable.to_string(), taking);
        }
        let time = format_timestamp(time_s, "time").unwrap_or_default();
        let keys: Vec<(String, String)> = self.inside.keys().filter(|(t, _)| t == trackable).cloned().collect();
        keys.iter().filter_map(|key| self.settle(key, &time)).collect()
    }

    /// The event, if any, that brings the trackable of `key` in line with its taken providers
    /// inside the fence (an entry or exit at `time`); forgets an occupancy left empty.
    fn settle(&mut self, key: &(String, String), time: &str) -> Option<FenceEvent> {
        let (trackable, fence_id) = key;
        let taking = self.taking.get(trackable).unwrap_or(&Taking::All);
        let occupancy = self.inside.get_mut(key)?;
        let inside = occupancy.providers.iter().any(|p| taking.takes(p));
        let event = if inside == occupancy.entered.is_some() {
            None
        } else {
            let event_type = if inside {
                occupancy.entered = Some(Some(time.to_string()).filter(|t| !t.is_empty()));
                FenceEventType::RegionEntry
            } else {
                FenceEventType::RegionExit
            };
            let entry_time = occupancy.entered.clone().flatten();
            if !inside {
                occupancy.entered = None;
            }
            Some(FenceEvent {
                id: uuid_for(
                    "fence-event",
                    &format!("{trackable}\0{fence_id}\0{event_type:?}\0{time}"),
                ),
                fence_id: fence_id.clone(),
                event_type,
                provider_id: None,
                trackable_id: Some(trackable.clone()),
                trackables: None,
                foreign_id: occupancy.foreign_id.clone(),
                entry_time,
                exit_time: (!inside).then(|| time.to_string()),
                properties: occupancy.properties.clone(),
            })
        };
        if occupancy.providers.is_empty() && occupancy.entered.is_none() {
            self.inside.remove(key);
        }
        event
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

    #[test]
    fn rules_switching_the_taken_provider_move_the_trackable_in_and_out() {
        use FenceEventType::{RegionEntry as In, RegionExit as Out};
        let mut fences = TrackableFences::default();
        let kinds = |events: &[FenceEvent]| events.iter().map(|e| e.event_type).collect::<Vec<_>>();
        // without rules (taking all) tag-1 takes the forklift in
        assert_eq!(
            kinds(&fences.on_provider_event(&provider_event("tag-1", In, "t1", &["forklift"]))),
            [In]
        );
        // its rules now take tag-2, which is outside: the forklift leaves, at the switch
        let out = fences.on_taking("forklift", Taking::One("tag-2".into()), 10.0);
        assert_eq!(kinds(&out), [Out]);
        assert_eq!(out[0].exit_time.as_deref(), Some("1970-01-01T00:00:10.000Z"));
        assert_eq!(out[0].entry_time.as_deref(), Some("t1"));
        assert!(fences
            .on_taking("forklift", Taking::One("tag-2".into()), 11.0)
            .is_empty());
        // tag-1 leaving changes nothing; tag-2 entering takes it in
        assert!(fences
            .on_provider_event(&provider_event("tag-1", Out, "t2", &["forklift"]))
            .is_empty());
        assert_eq!(
            kinds(&fences.on_provider_event(&provider_event("tag-2", In, "t3", &["forklift"]))),
            [In]
        );
        // no provider matches a rule: out; back to no rules: in again (tag-2 is inside)
        assert_eq!(kinds(&fences.on_taking("forklift", Taking::Nothing, 12.0)), [Out]);
        assert_eq!(kinds(&fences.on_taking("forklift", Taking::All, 13.0)), [In]);
        // another trackable is not concerned
        assert!(fences.on_taking("pallet", Taking::Nothing, 14.0).is_empty());
    }
}
