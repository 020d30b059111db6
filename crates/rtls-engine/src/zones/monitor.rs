//! Zone events: enter / exit with anti-flap hysteresis, dwell, head counts.

use std::collections::BTreeMap;

use super::{Shape, Zone};
use crate::error::{EngineError, Result};

/// Anti-flap settings: a tag must be inside (outside) a zone by more than `tolerance_m`,
/// continuously for `delay_s`, before it enters (exits). A tag wobbling across a border by less
/// than the tolerance produces no events.
///
/// # Examples
/// ```
/// use rtls_engine::zones::AntiFlap;
/// let anti_flap = AntiFlap { tolerance_m: 1.0, delay_s: 2.0 };
/// anti_flap.validate().unwrap();
/// assert!(AntiFlap { tolerance_m: -1.0, delay_s: 0.0 }.validate().is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AntiFlap {
    /// Hysteresis half-width around the border, m (≥ 0): enter at signed distance
    /// `≤ −tolerance_m`, exit at `≥ +tolerance_m`.
    pub tolerance_m: f64,
    /// How long the condition must hold before the event fires, s (≥ 0).
    pub delay_s: f64,
}

impl AntiFlap {
    /// Checks that both values are finite and non-negative.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] naming the bad value.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::zones::AntiFlap;
    /// assert!(AntiFlap { tolerance_m: 0.5, delay_s: f64::NAN }.validate().is_err());
    /// ```
    pub fn validate(&self) -> Result<()> {
        for (name, value) in [("tolerance_m", self.tolerance_m), ("delay_s", self.delay_s)] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(EngineError::InvalidParameter {
                    name,
                    reason: "must be a finite number ≥ 0",
                });
            }
        }
        Ok(())
    }
}

/// What happened to a tag with respect to a zone.
#[derive(Debug, Clone, PartialEq)]
pub enum ZoneEvent {
    /// The tag entered the zone (confirmed after the anti-flap delay).
    Enter {
        /// Tag id.
        tag: String,
        /// Zone id.
        zone: String,
        /// Time the entry was confirmed, s.
        time_s: f64,
    },
    /// The tag left the zone (confirmed after the anti-flap delay, or its track was removed).
    Exit {
        /// Tag id.
        tag: String,
        /// Zone id.
        zone: String,
        /// Time the exit was confirmed, s.
        time_s: f64,
    },
    /// The tag is still inside, reported once per dwell interval.
    Dwell {
        /// Tag id.
        tag: String,
        /// Zone id.
        zone: String,
        /// Time of the report, s.
        time_s: f64,
        /// Time since the confirmed entry, s.
        dwell_s: f64,
    },
}

impl ZoneEvent {
    /// The tag id.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::zones::ZoneEvent;
    /// let e = ZoneEvent::Enter { tag: "t1".into(), zone: "z".into(), time_s: 3.0 };
    /// assert_eq!((e.tag(), e.zone(), e.time_s()), ("t1", "z", 3.0));
    /// ```
    #[must_use]
    pub fn tag(&self) -> &str {
        match self {
            Self::Enter { tag, .. } | Self::Exit { tag, .. } | Self::Dwell { tag, .. } => tag,
        }
    }

    /// The zone id.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::zones::ZoneEvent;
    /// assert_eq!(ZoneEvent::Exit { tag: "t".into(), zone: "z".into(), time_s: 0.0 }.zone(), "z");
    /// ```
    #[must_use]
    pub fn zone(&self) -> &str {
        match self {
            Self::Enter { zone, .. } | Self::Exit { zone, .. } | Self::Dwell { zone, .. } => zone,
        }
    }

    /// The event time, s.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::zones::ZoneEvent;
    /// let e = ZoneEvent::Dwell { tag: "t".into(), zone: "z".into(), time_s: 9.0, dwell_s: 5.0 };
    /// assert_eq!(e.time_s(), 9.0);
    /// ```
    #[must_use]
    pub fn time_s(&self) -> f64 {
        match self {
            Self::Enter { time_s, .. } | Self::Exit { time_s, .. } | Self::Dwell { time_s, .. } => *time_s,
        }
    }
}

/// One tag's state with respect to one zone.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
struct Membership {
    /// Confirmed inside.
    inside: bool,
    /// Since when the opposite condition (clearly inside when outside, clearly outside when
    /// inside) has held without interruption.
    pending_since_s: Option<f64>,
    /// Time of the confirmed entry.
    entered_s: f64,
    /// Time of the next dwell report.
    next_dwell_s: f64,
}

#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct TagState {
    last_time_s: f64,
    zones: Vec<Membership>,
}

/// Every tag's zone memberships, with the zone ids they are indexed by.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct Memberships {
    zone_ids: Vec<String>,
    tags: BTreeMap<String, TagState>,
}

/// Turns tag positions into zone events and keeps per-zone head counts.
///
/// Per tag and zone it is a two-state machine with hysteresis ([`AntiFlap`]). Events of one
/// update come in zone-id order; tags are independent, so a stream of updates gives events in
/// a deterministic order.
///
/// # Examples
/// ```
/// use rtls_engine::zones::{AntiFlap, Shape, Zone, ZoneEvent, ZoneKind, ZoneMonitor};
/// let zone = Zone {
///     id: "z".into(),
///     name: "box".into(),
///     kind: ZoneKind::Hazard,
///     readers: vec![],
///     shape: Shape::Box { min_m: [0.0, 0.0, 0.0], max_m: [10.0, 10.0, 3.0] },
/// };
/// let mut monitor = ZoneMonitor::new(vec![zone], AntiFlap { tolerance_m: 0.5, delay_s: 1.0 }).unwrap();
/// assert!(monitor.update("t1", 0.0, [5.0, 5.0, 1.0]).unwrap().is_empty()); // not yet confirmed
/// let events = monitor.update("t1", 1.0, [5.0, 5.0, 1.0]).unwrap();
/// assert_eq!(events, vec![ZoneEvent::Enter { tag: "t1".into(), zone: "z".into(), time_s: 1.0 }]);
/// assert_eq!(monitor.head_count("z"), 1);
/// ```
#[derive(Debug, Clone)]
pub struct ZoneMonitor {
    zones: Vec<Zone>,
    anti_flap: AntiFlap,
    dwell_interval_s: Option<f64>,
    tags: BTreeMap<String, TagState>,
    counts: Vec<usize>,
}

impl ZoneMonitor {
    /// A monitor of `zones` (any order; events come in zone-id order), without dwell reports.
    ///
    /// # Errors
    /// [`EngineError::Parse`] (file `-`, field `zones[i]…`) for invalid geometry, a duplicate
    /// zone id or a polygon whose `floor` was not resolved into `z_range_m` (load zones through
    /// [`crate::site::Site`] or give the height range); [`EngineError::InvalidParameter`] for
    /// bad anti-flap settings.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::zones::{AntiFlap, ZoneMonitor};
    /// let monitor = ZoneMonitor::new(vec![], AntiFlap { tolerance_m: 0.0, delay_s: 0.0 }).unwrap();
    /// assert_eq!(monitor.head_count("nowhere"), 0);
    /// ```
    pub fn new(mut zones: Vec<Zone>, anti_flap: AntiFlap) -> Result<Self> {
        anti_flap.validate()?;
        for (i, zone) in zones.iter().enumerate() {
            let located = |field: String, reason: String| EngineError::Parse {
                file: "-".into(),
                line: 0,
                field: format!("zones[{i}].{field}"),
                reason,
            };
            if let Err(EngineError::Parse { field, reason, .. }) = zone.validate() {
                return Err(located(field, reason));
            }
            if let Shape::Polygon {
                floor: Some(floor),
                z_range_m: None,
                ..
            } = &zone.shape
            {
                return Err(located(
                    "shape.floor".into(),
                    format!("floor `{floor}` is not resolved: load the zone through a site or give z_range_m"),
                ));
            }
            if zones[..i].iter().any(|z| z.id == zone.id) {
                return Err(located("id".into(), format!("duplicate zone id `{}`", zone.id)));
            }
        }
        zones.sort_by(|a, b| a.id.cmp(&b.id));
        let counts = vec![0; zones.len()];
        Ok(Self {
            zones,
            anti_flap,
            dwell_interval_s: None,
            tags: BTreeMap::new(),
            counts,
        })
    }

    /// Reports a [`ZoneEvent::Dwell`] every `interval_s` while a tag stays inside a zone (at
    /// the first update at or after each multiple of the interval since the entry).
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] unless `interval_s` is finite and > 0.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::zones::{AntiFlap, ZoneMonitor};
    /// let monitor = ZoneMonitor::new(vec![], AntiFlap { tolerance_m: 0.0, delay_s: 0.0 }).unwrap();
    /// assert!(monitor.clone().with_dwell_interval_s(60.0).is_ok());
    /// assert!(monitor.with_dwell_interval_s(0.0).is_err());
    /// ```
    pub fn with_dwell_interval_s(mut self, interval_s: f64) -> Result<Self> {
        if !(interval_s.is_finite() && interval_s > 0.0) {
            return Err(EngineError::InvalidParameter {
                name: "dwell_interval_s",
                reason: "must be a finite number > 0",
            });
        }
        self.dwell_interval_s = Some(interval_s);
        Ok(self)
    }

    /// Replaces the monitored zones while tags are being tracked (a zone drawn, edited or deleted
    /// in the control room). A tag's state in a zone that keeps its id carries over (inside
    /// stays inside, so no spurious entry; a moved border is judged at its next update with the
    /// usual anti-flap), a new zone starts with every tag outside, and a removed zone's
    /// occupants leave it without an exit event (the zone no longer exists).
    ///
    /// # Errors
    /// As [`ZoneMonitor::new`]; the monitor is unchanged on error.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::zones::{AntiFlap, Shape, Zone, ZoneKind, ZoneMonitor};
    /// let zone = |id: &str, x0: f64| Zone {
    ///     id: id.into(),
    ///     name: id.into(),
    ///     kind: ZoneKind::AreaOfInterest,
    ///     readers: vec![],
    ///     shape: Shape::Box { min_m: [x0, 0.0, 0.0], max_m: [x0 + 10.0, 10.0, 3.0] },
    /// };
    /// let mut monitor = ZoneMonitor::new(vec![zone("a", 0.0)], AntiFlap { tolerance_m: 0.0, delay_s: 0.0 }).unwrap();
    /// monitor.update("t", 0.0, [5.0, 5.0, 1.0]).unwrap();
    /// assert_eq!(monitor.head_count("a"), 1);
    /// monitor.replace_zones(vec![zone("a", 0.0), zone("b", 2.0)]).unwrap();
    /// assert_eq!((monitor.head_count("a"), monitor.head_count("b")), (1, 0));
    /// let events = monitor.update("t", 1.0, [5.0, 5.0, 1.0]).unwrap();
    /// assert_eq!(events.len(), 1); // entered b only
    /// assert_eq!(monitor.head_count("b"), 1);
    /// ```
    pub fn replace_zones(&mut self, zones: Vec<Zone>) -> Result<()> {
        let fresh = ZoneMonitor::new(zones, self.anti_flap)?;
        // new index j ← old index of the zone with the same id, if any
        let old_index: Vec<Option<usize>> = fresh
            .zones
            .iter()
            .map(|zone| self.zones.iter().position(|old| old.id == zone.id))
            .collect();
        for state in self.tags.values_mut() {
            state.zones = old_index
                .iter()
                .map(|old| old.map_or_else(Membership::default, |i| state.zones[i]))
                .collect();
        }
        self.counts = (0..fresh.zones.len())
            .map(|j| self.tags.values().filter(|s| s.zones[j].inside).count())
            .collect();
        self.zones = fresh.zones;
        Ok(())
    }

    /// Every tag's memberships, with the ids of the zones they refer to (a tracker's
    /// checkpoint, [`crate::tracker::TrackerState`]).
    pub(crate) fn memberships(&self) -> Memberships {
        Memberships {
            zone_ids: self.zones.iter().map(|zone| zone.id.clone()).collect(),
            tags: self.tags.clone(),
        }
    }

    /// Takes the memberships of a checkpoint: each zone's by its id; a zone the checkpoint did
    /// not know starts empty for every tag, one it knew and this monitor does not is dropped.
    ///
    /// # Errors
    /// [`EngineError::Checkpoint`] when a tag's entry does not have one membership per zone of
    /// the checkpoint.
    pub(crate) fn restore_memberships(&mut self, memberships: Memberships) -> Result<()> {
        let old_index: Vec<Option<usize>> = self
            .zones
            .iter()
            .map(|zone| memberships.zone_ids.iter().position(|id| *id == zone.id))
            .collect();
        let mut tags = memberships.tags;
        for state in tags.values_mut() {
            if state.zones.len() != memberships.zone_ids.len() {
                return Err(EngineError::Checkpoint(format!(
                    "a tag has {} zone memberships for {} zones",
                    state.zones.len(),
                    memberships.zone_ids.len()
                )));
            }
            state.zones = old_index
                .iter()
                .map(|old| old.map_or_else(Membership::default, |i| state.zones[i]))
                .collect();
        }
        self.counts = (0..self.zones.len())
            .map(|j| tags.values().filter(|s| s.zones[j].inside).count())
            .collect();
        self.tags = tags;
        Ok(())
    }

    /// The monitored zones, sorted by id.
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::zones::{AntiFlap, ZoneMonitor};
    /// let monitor = ZoneMonitor::new(vec![], AntiFlap { tolerance_m: 0.0, delay_s: 0.0 }).unwrap();
    /// assert!(monitor.zones().is_empty());
    /// ```
    #[must_use]
    pub fn zones(&self) -> &[Zone] {
        &self.zones
    }

    /// The time of `tag`'s latest position, s; `None` for a tag the monitor has not seen (or
    /// when there are no zones).
    #[must_use]
    pub fn last_time_s(&self, tag: &str) -> Option<f64> {
        self.tags.get(tag).map(|state| state.last_time_s)
    }

    /// Feeds one position of a tag and returns the events it causes, in zone-id order.
    ///
    /// # Units
    /// `time_s` in s (any epoch, non-decreasing per tag); `position_m` is `[x, y, z]`, m.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] when the time or a coordinate is not finite, or the
    /// time is earlier than this tag's previous update (feed positions in time order). The
    /// monitor is unchanged on error.
    ///
    /// # Examples
    /// See [`ZoneMonitor`].
    pub fn update(&mut self, tag: &str, time_s: f64, position_m: [f64; 3]) -> Result<Vec<ZoneEvent>> {
        if !time_s.is_finite() {
            return Err(EngineError::InvalidParameter {
                name: "time_s",
                reason: "must be finite",
            });
        }
        if position_m.iter().any(|c| !c.is_finite()) {
            return Err(EngineError::InvalidParameter {
                name: "position_m",
                reason: "coordinates must be finite",
            });
        }
        if self.zones.is_empty() {
            return Ok(Vec::new());
        }
        // look up before inserting: no key allocation for a known tag (the per-update path)
        if !self.tags.contains_key(tag) {
            let state = TagState {
                last_time_s: time_s,
                zones: vec![Membership::default(); self.zones.len()],
            };
            self.tags.insert(tag.to_string(), state);
        }
        let Some(state) = self.tags.get_mut(tag) else {
            return Ok(Vec::new());
        };
        if time_s < state.last_time_s {
            return Err(EngineError::InvalidParameter {
                name: "time_s",
                reason: "went backwards for this tag: feed positions in time order",
            });
        }
        state.last_time_s = time_s;
        let AntiFlap { tolerance_m, delay_s } = self.anti_flap;
        let mut events = Vec::new();
        for (k, (zone, m)) in self.zones.iter().zip(state.zones.iter_mut()).enumerate() {
            let distance_m = zone.signed_distance_m(position_m);
            // the condition that would change the state: clearly inside, or clearly outside
            let opposite = if m.inside {
                distance_m >= tolerance_m
            } else {
                distance_m <= -tolerance_m
            };
            if !opposite {
                m.pending_since_s = None;
            } else {
                let since = *m.pending_since_s.get_or_insert(time_s);
                if time_s - since >= delay_s {
                    m.pending_since_s = None;
                    let (tag, zone) = (tag.to_string(), zone.id.clone());
                    if m.inside {
                        m.inside = false;
                        self.counts[k] -= 1;
                        events.push(ZoneEvent::Exit { tag, zone, time_s });
                    } else {
                        m.inside = true;
                        m.entered_s = time_s;
                        m.next_dwell_s = self.dwell_interval_s.map_or(f64::INFINITY, |i| time_s + i);
                        self.counts[k] += 1;
                        events.push(ZoneEvent::Enter { tag, zone, time_s });
                    }
                    continue;
                }
            }
            if m.inside && time_s >= m.next_dwell_s {
                if let Some(interval_s) = self.dwell_interval_s {
                    // next multiple of the interval strictly after now
                    let steps = ((time_s - m.next_dwell_s) / interval_s).floor() + 1.0;
                    m.next_dwell_s += steps * interval_s;
                }
                events.push(ZoneEvent::Dwell {
                    tag: tag.to_string(),
                    zone: zone.id.clone(),
                    time_s,
                    dwell_s: time_s - m.entered_s,
                });
            }
        }
        Ok(events)
    }

    /// Forgets a tag (its track was deleted) and returns an [`ZoneEvent::Exit`] at `time_s` for
    /// every zone it was inside, in zone-id order. Unknown tags give no events.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] when `time_s` is not finite (the tag is kept).
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::zones::{AntiFlap, Shape, Zone, ZoneKind, ZoneMonitor};
    /// let zone = Zone {
    ///     id: "z".into(),
    ///     name: "box".into(),
    ///     kind: ZoneKind::AreaOfInterest,
    ///     readers: vec![],
    ///     shape: Shape::Box { min_m: [0.0; 3], max_m: [1.0; 3] },
    /// };
    /// let mut monitor = ZoneMonitor::new(vec![zone], AntiFlap { tolerance_m: 0.0, delay_s: 0.0 }).unwrap();
    /// monitor.update("t", 0.0, [0.5; 3]).unwrap();
    /// assert_eq!(monitor.remove_tag("t", 5.0).unwrap().len(), 1);
    /// assert_eq!(monitor.head_count("z"), 0);
    /// ```
    pub fn remove_tag(&mut self, tag: &str, time_s: f64) -> Result<Vec<ZoneEvent>> {
        if !time_s.is_finite() {
            return Err(EngineError::InvalidParameter {
                name: "time_s",
                reason: "must be finite",
            });
        }
        let Some(state) = self.tags.remove(tag) else {
            return Ok(Vec::new());
        };
        let mut events = Vec::new();
        for (k, (zone, m)) in self.zones.iter().zip(&state.zones).enumerate() {
            if m.inside {
                self.counts[k] -= 1;
                events.push(ZoneEvent::Exit {
                    tag: tag.to_string(),
                    zone: zone.id.clone(),
                    time_s,
                });
            }
        }
        Ok(events)
    }

    /// How many tags are confirmed inside the zone `zone_id` (0 for an unknown zone).
    ///
    /// # Examples
    /// See [`ZoneMonitor`].
    #[must_use]
    pub fn head_count(&self, zone_id: &str) -> usize {
        self.zone_index(zone_id).map_or(0, |k| self.counts[k])
    }

    /// The tags confirmed inside the zone `zone_id`, sorted (empty for an unknown zone).
    ///
    /// # Examples
    /// ```
    /// use rtls_engine::zones::{AntiFlap, ZoneMonitor};
    /// let monitor = ZoneMonitor::new(vec![], AntiFlap { tolerance_m: 0.0, delay_s: 0.0 }).unwrap();
    /// assert!(monitor.occupants("z").is_empty());
    /// ```
    #[must_use]
    pub fn occupants(&self, zone_id: &str) -> Vec<&str> {
        let Some(k) = self.zone_index(zone_id) else {
            return Vec::new();
        };
        self.tags
            .iter()
            .filter(|(_, s)| s.zones[k].inside)
            .map(|(tag, _)| tag.as_str())
            .collect()
    }

    fn zone_index(&self, zone_id: &str) -> Option<usize> {
        self.zones.binary_search_by(|z| z.id.as_str().cmp(zone_id)).ok()
    }
}

#[cfg(test)]
#[path = "monitor_tests.rs"]
mod tests;
