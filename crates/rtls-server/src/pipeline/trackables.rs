//! Which omlox trackable a tag's updates move: the stored trackables by location provider,
//! for the WebSocket topics that speak of trackables (`trackable_motions`,
//! `collision_events`).
//!
//! A tag listed in a stored trackable's `location_providers` moves that trackable (the spec
//! assigns a provider to one trackable at a time; if several list it, it moves each). A tag no
//! stored trackable lists is a trackable of its own — its *implicit trackable*: id and name the
//! tag's, type `omlox`, no radius — so a site whose tags were never registered as trackables
//! still has motions and collisions, as it has implicit providers (`GET /v2/providers`).
//! The REST trackable operations list stored trackables only.

use std::borrow::Cow;
use std::collections::HashMap;
use std::sync::Arc;

use crate::omlox::locating_rules::RuleSet;
use crate::omlox::{Trackable, TrackableType};

/// The stored trackables by provider id, and their parsed `locating_rules`; built whenever the
/// stored trackables change.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TrackableIndex {
    by_provider: HashMap<String, Vec<Arc<Trackable>>>,
    /// The rules of the trackables that have some, by trackable id.
    rules: HashMap<String, Arc<RuleSet>>,
}

impl TrackableIndex {
    /// Indexes `trackables` by their `location_providers`.
    #[must_use]
    pub fn new(trackables: Vec<Trackable>) -> Self {
        let mut by_provider: HashMap<String, Vec<Arc<Trackable>>> = HashMap::new();
        let mut rules = HashMap::new();
        for trackable in trackables {
            let parsed = RuleSet::of_stored(&trackable);
            if !parsed.is_empty() {
                rules.insert(trackable.id.clone(), Arc::new(parsed));
            }
            let trackable = Arc::new(trackable);
            for provider in trackable.location_providers.iter().flatten() {
                by_provider
                    .entry(provider.clone())
                    .or_default()
                    .push(Arc::clone(&trackable));
            }
        }
        for list in by_provider.values_mut() {
            list.sort_by(|a, b| a.id.cmp(&b.id));
            list.dedup_by(|a, b| a.id == b.id);
        }
        Self { by_provider, rules }
    }

    /// The parsed rules of the stored trackable `trackable_id`; `None` when it has none (or
    /// is not stored: an implicit trackable has none).
    #[must_use]
    pub fn rules(&self, trackable_id: &str) -> Option<&RuleSet> {
        self.rules.get(trackable_id).map(Arc::as_ref)
    }

    /// The trackables `provider_id`'s updates move: the stored ones listing it, in id order,
    /// else its implicit trackable.
    #[must_use]
    pub fn of(&self, provider_id: &str) -> Cow<'_, [Arc<Trackable>]> {
        match self.by_provider.get(provider_id) {
            Some(list) => Cow::Borrowed(list),
            None => Cow::Owned(vec![Arc::new(implicit_trackable(provider_id))]),
        }
    }

    /// The ids of the stored trackables `provider_id` is assigned to, in id order (a fence
    /// event's `trackables`); empty when none lists it.
    #[must_use]
    pub fn assigned(&self, provider_id: &str) -> Vec<String> {
        self.by_provider
            .get(provider_id)
            .map(|list| list.iter().map(|t| t.id.clone()).collect())
            .unwrap_or_default()
    }
}

/// The trackable of a tag no stored trackable lists (see the module documentation).
#[must_use]
pub fn implicit_trackable(tag: &str) -> Trackable {
    Trackable {
        id: tag.to_string(),
        kind: TrackableType::Omlox,
        name: Some(tag.to_string()),
        geometry: None,
        extrusion: None,
        location_providers: Some(vec![tag.to_string()]),
        fence_timeout: None,
        exit_tolerance: None,
        tolerance_timeout: None,
        exit_delay: None,
        radius: None,
        properties: None,
        locating_rules: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stored(id: &str, providers: &[&str]) -> Trackable {
        Trackable {
            id: id.into(),
            kind: TrackableType::Virtual,
            location_providers: Some(providers.iter().map(|p| (*p).to_string()).collect()),
            ..implicit_trackable(id)
        }
    }

    #[test]
    fn a_listed_tag_moves_its_trackables_and_another_its_implicit_one() {
        let index = TrackableIndex::new(vec![
            stored("forklift", &["tag-1", "tag-2"]),
            stored("crate", &["tag-2"]),
        ]);
        let ids = |tag: &str| index.of(tag).iter().map(|t| t.id.clone()).collect::<Vec<_>>();
        assert_eq!(ids("tag-1"), ["forklift"]);
        assert_eq!(ids("tag-2"), ["crate", "forklift"]);
        assert_eq!(ids("tag-3"), ["tag-3"]);
        assert_eq!(index.of("tag-3")[0].kind, TrackableType::Omlox);
        assert_eq!(index.assigned("tag-2"), ["crate", "forklift"]);
        assert!(
            index.assigned("tag-3").is_empty(),
            "an implicit trackable is no assignment"
        );
    }
}
