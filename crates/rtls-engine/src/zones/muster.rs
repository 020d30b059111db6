//! The muster board's check-in/check-out rule: who is on site now.
//!
//! A mine (or a plant with a gate) counts people in and out at its entry — the portal, the
//! lamp room, the turnstile. The rule here, per tag, from its last known position and whether
//! its track is still alive:
//!
//! | last position                    | track alive | track lost or deleted      |
//! |----------------------------------|-------------|----------------------------|
//! | in the entry zone                | at entry    | off site (left by the entry) |
//! | in an outside zone               | off site    | off site                   |
//! | anywhere else (the site)         | on site     | **missing** (on site, unheard) |
//!
//! So a person who enters through the entry zone and walks in is on site; one who walks back
//! into the entry zone and is no longer heard has checked out; one who goes silent anywhere
//! else is still counted on site, as missing — the case a muster exists for (seed 000's
//! miner behind a broken reader). A tag first heard inside the site without passing the entry
//! (switched on underground) is on site too: counting someone who might be there is the safe
//! error.

use serde::{Deserialize, Serialize};

use super::Zone;

/// `[muster]` in the site file.
///
/// ```toml
/// [muster]
/// entry_zone = "portal"          # a zone id: the way in and out
/// outside_zones = ["surface"]    # zones that are off site (optional)
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MusterSettings {
    /// The zone through which people enter and leave the site.
    pub entry_zone: String,
    /// Zones that are off site (a car park, the surface yard): a tag there is not counted.
    #[serde(default)]
    pub outside_zones: Vec<String>,
}

/// Where a tag stands for the muster board.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MusterStatus {
    /// Inside the site and heard.
    OnSite,
    /// Inside the site by its last position, but its track is lost: counted on site.
    Missing,
    /// In the entry zone and heard (checking in or out).
    AtEntry,
    /// Left through the entry zone, or in an outside zone.
    OffSite,
}

impl MusterStatus {
    /// Whether the board counts the tag as on site (on site, missing or at the entry).
    #[must_use]
    pub fn counted(self) -> bool {
        !matches!(self, Self::OffSite)
    }
}

/// A tag's muster status from its last known position and whether its track is lost.
///
/// `zones` are the site's current zones (an edited set, too); a zone named by `settings` that
/// is not among them counts as absent (nothing is inside it) — the caller reports that
/// ([`missing_zones`]).
///
/// # Examples
/// ```
/// use rtls_engine::zones::{muster_status, MusterSettings, MusterStatus, Shape, Zone, ZoneKind};
/// let portal = Zone {
///     id: "portal".into(),
///     name: "Portal".into(),
///     kind: ZoneKind::AreaOfInterest,
///     readers: vec![],
///     shape: Shape::Box { min_m: [0.0, 0.0, -10.0], max_m: [5.0, 5.0, 10.0] },
/// };
/// let settings = MusterSettings { entry_zone: "portal".into(), outside_zones: vec![] };
/// let zones = [portal];
/// assert_eq!(muster_status(&settings, &zones, [2.0, 2.0, 0.0], false), MusterStatus::AtEntry);
/// assert_eq!(muster_status(&settings, &zones, [2.0, 2.0, 0.0], true), MusterStatus::OffSite);
/// assert_eq!(muster_status(&settings, &zones, [50.0, 2.0, 0.0], false), MusterStatus::OnSite);
/// assert_eq!(muster_status(&settings, &zones, [50.0, 2.0, 0.0], true), MusterStatus::Missing);
/// ```
#[must_use]
pub fn muster_status(settings: &MusterSettings, zones: &[Zone], position_m: [f64; 3], lost: bool) -> MusterStatus {
    let inside = |id: &str| zones.iter().any(|z| z.id == id && z.contains(position_m));
    if settings.outside_zones.iter().any(|id| inside(id)) {
        MusterStatus::OffSite
    } else if inside(&settings.entry_zone) {
        if lost {
            MusterStatus::OffSite
        } else {
            MusterStatus::AtEntry
        }
    } else if lost {
        MusterStatus::Missing
    } else {
        MusterStatus::OnSite
    }
}

/// The zones `settings` names that are not among `zones` (deleted in the zone editor, say):
/// the board cannot apply its rule fully without them.
#[must_use]
pub fn missing_zones(settings: &MusterSettings, zones: &[Zone]) -> Vec<String> {
    std::iter::once(&settings.entry_zone)
        .chain(&settings.outside_zones)
        .filter(|id| !zones.iter().any(|z| &z.id == *id))
        .cloned()
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::zones::{Shape, ZoneKind};

    fn zone(id: &str, x0: f64, x1: f64) -> Zone {
        Zone {
            id: id.into(),
            name: id.into(),
            kind: ZoneKind::AreaOfInterest,
            readers: vec![],
            shape: Shape::Polygon {
                vertices_m: vec![[x0, 0.0], [x1, 0.0], [x1, 10.0], [x0, 10.0]],
                floor: None,
                z_range_m: None,
            },
        }
    }

    #[test]
    fn a_walk_in_and_out_through_the_portal_checks_in_then_out() {
        let zones = [
            zone("surface", -20.0, 0.0),
            zone("portal", 0.0, 5.0),
            zone("stope", 40.0, 60.0),
        ];
        let settings = MusterSettings {
            entry_zone: "portal".into(),
            outside_zones: vec!["surface".into()],
        };
        // (x, lost) along a shift: yard, portal, drift, stope, back out, gone quiet at the portal
        let walk = [
            (-10.0, false, MusterStatus::OffSite),
            (2.0, false, MusterStatus::AtEntry),
            (20.0, false, MusterStatus::OnSite),
            (50.0, false, MusterStatus::OnSite),
            (50.0, true, MusterStatus::Missing),
            (3.0, false, MusterStatus::AtEntry),
            (3.0, true, MusterStatus::OffSite),
            (-5.0, true, MusterStatus::OffSite),
        ];
        for (x, lost, expected) in walk {
            assert_eq!(
                muster_status(&settings, &zones, [x, 5.0, 0.0], lost),
                expected,
                "x = {x}, lost = {lost}"
            );
        }
        assert!(MusterStatus::Missing.counted() && MusterStatus::AtEntry.counted());
        assert!(!MusterStatus::OffSite.counted());
    }

    #[test]
    fn a_deleted_entry_zone_is_reported_and_counts_nobody_at_the_entry() {
        let zones = [zone("stope", 40.0, 60.0)];
        let settings = MusterSettings {
            entry_zone: "portal".into(),
            outside_zones: vec!["surface".into(), "stope".into()],
        };
        assert_eq!(missing_zones(&settings, &zones), ["portal", "surface"]);
        assert_eq!(
            muster_status(&settings, &zones, [2.0, 5.0, 0.0], true),
            MusterStatus::Missing
        );
    }
}
