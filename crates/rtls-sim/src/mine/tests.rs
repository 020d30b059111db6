//! Unit tests of the mine: layout, site file, configuration checks, and the feed's
//! independence from how it is stepped.

use std::collections::HashSet;

use rtls_engine::record::Record;
use rtls_engine::site::Site;
use rtls_engine::zones::ZoneKind;

use super::*;
use crate::SimError;

fn roaming(miners: usize, seed: u64, approach_period_s: f64) -> MineConfig {
    MineConfig {
        miners,
        entering_miners: 2,
        seed,
        start_time_s: 1.75e9,
        walk: WalkModel::Roaming(RoamingSettings {
            collapse_approach_period_s: Some(approach_period_s),
            ..RoamingSettings::default()
        }),
        ..MineConfig::default()
    }
}

/// Steps `config`'s feed to each of `times_s` (s after the start) in turn: all records, and
/// the truth at the end.
fn feed(config: &MineConfig, times_s: &[f64]) -> (Vec<Record>, Vec<[f64; 2]>) {
    let mut mine = MineSimulation::new(MineLayout::seed000(), config.clone()).unwrap();
    let mut records = Vec::new();
    for &t_s in times_s {
        records.extend(mine.step(config.start_time_s + t_s));
    }
    (records, mine.truth().map(|(_, p)| p).collect())
}

#[test]
fn seed000_layout_has_307_uniquely_named_readers_on_the_walls_and_one_broken_in_the_collapse() {
    let mine = MineLayout::seed000();
    mine.validate().unwrap();
    assert_eq!(mine.readers.len(), 307);
    let ids: HashSet<&str> = mine.readers.iter().map(|r| r.id.as_str()).collect();
    assert_eq!(ids.len(), 307);
    let broken: Vec<&MineReader> = mine.readers.iter().filter(|r| !r.working).collect();
    assert_eq!(broken.len(), 1);
    assert_eq!(broken[0].id, mine.collapse.broken_reader);
    assert!(mine.in_collapse(broken[0].position_m));
    for reader in &mine.readers {
        assert!(mine.inside_tunnels(reader.position_m), "{} in the rock", reader.id);
    }
    // the cross-cut joins every drift
    for drift in &mine.drifts {
        assert!(mine.in_cross_cut([mine.cross_cut.x_m, drift.y_m]));
    }
}

#[test]
fn site_file_loads_with_the_collapse_as_a_hazard_and_optional_drift_zones() {
    let mine = MineLayout::seed000();
    let options = SiteOptions {
        name: Some("Paishanlou \"demo\"".into()),
        drift_zones: true,
        without_map: false,
    };
    let site = Site::from_toml_str(&mine.site_toml(&options), "mine.toml").unwrap();
    assert_eq!(site.name.as_deref(), Some("Paishanlou \"demo\""));
    assert_eq!(site.readers.len(), 307);
    let broken = site.readers.iter().find(|r| !r.working).unwrap();
    assert_eq!(broken.id, "D3-28");
    assert_eq!(site.zones, mine.zones(&options));
    assert_eq!(site.zones.len(), 1 + mine.drifts.len());
    assert_eq!(site.zones[0].kind, ZoneKind::Hazard);
    assert_eq!(site.zones[0].readers, vec!["D3-28".to_string()]);
    assert!(site.zones[1..].iter().all(|z| z.kind == ZoneKind::AreaOfInterest));
    // every drift's centreline is in its own zone only
    for (index, drift) in mine.drifts.iter().enumerate() {
        let inside: Vec<&str> = site.zones[1..]
            .iter()
            .filter(|z| z.contains([100.0, drift.y_m, 0.0]))
            .map(|z| z.id.as_str())
            .collect();
        assert_eq!(inside, vec![format!("drift-{index}")]);
    }
    assert_eq!(site.tracker.coast_timeout_s, 10.0);
}

#[test]
fn the_feed_is_the_same_however_it_is_stepped_and_changes_with_the_seed() {
    // 10 minutes, a miner sent into the collapse every minute (interrupting walks and rests)
    let config = roaming(20, 11, 60.0);
    let every_second: Vec<f64> = (1..=600).map(f64::from).collect();
    let mut irregular = Vec::new();
    let mut t_s: f64 = 0.0;
    while t_s < 600.0 {
        t_s = (t_s + if irregular.len() % 5 == 0 { 7.3 } else { 0.37 }).min(600.0);
        irregular.push(t_s);
        // steps not after the last one do nothing
        irregular.push(t_s - 0.2);
        irregular.push(f64::NAN);
    }
    let (records, truth) = feed(&config, &every_second);
    let (records_irregular, truth_irregular) = feed(&config, &irregular);
    let (records_at_once, truth_at_once) = feed(&config, &[600.0]);
    assert!(records.len() > 20 * 600);
    assert_eq!(records, records_irregular);
    assert_eq!(records, records_at_once);
    assert_eq!(truth, truth_irregular);
    assert_eq!(truth, truth_at_once);
    let (other_seed, _) = feed(&roaming(20, 12, 60.0), &every_second);
    assert_ne!(records, other_seed);
}

#[test]
fn a_step_not_after_the_last_one_returns_nothing_and_changes_nothing() {
    let config = roaming(5, 3, 120.0);
    let mut mine = MineSimulation::new(MineLayout::seed000(), config.clone()).unwrap();
    assert_eq!(mine.time_s(), config.start_time_s);
    assert!(mine.step(config.start_time_s).is_empty());
    assert!(!mine.step(config.start_time_s + 2.0).is_empty());
    let truth: Vec<[f64; 2]> = mine.truth().map(|(_, p)| p).collect();
    for t_s in [
        config.start_time_s + 1.0,
        config.start_time_s + 2.0,
        f64::NAN,
        f64::INFINITY,
    ] {
        assert!(mine.step(t_s).is_empty(), "{t_s}");
    }
    assert_eq!(mine.time_s(), config.start_time_s + 2.0);
    assert_eq!(mine.truth().map(|(_, p)| p).collect::<Vec<_>>(), truth);
    // and the feed goes on where it was
    let next = mine.step(config.start_time_s + 3.0);
    assert!(!next.is_empty());
    assert!(next.iter().all(|r| r.time_s > config.start_time_s + 2.0));
}

#[test]
fn bad_configurations_and_layouts_are_refused_with_the_field_named() {
    let refused = |layout: MineLayout, config: MineConfig| match MineSimulation::new(layout, config) {
        Err(SimError::InvalidParameter { name, .. }) => name,
        other => panic!("expected an invalid parameter, got {other:?}"),
    };
    let layout = MineLayout::seed000();
    let config = MineConfig::default();
    assert_eq!(
        refused(
            layout.clone(),
            MineConfig {
                miners: 0,
                ..config.clone()
            }
        ),
        "miners"
    );
    let too_many = MineConfig {
        miners: 3,
        entering_miners: 4,
        ..config.clone()
    };
    assert_eq!(refused(layout.clone(), too_many), "entering_miners");
    let backwards = MineConfig {
        speed_range_mps: [1.5, 0.8],
        ..config.clone()
    };
    assert_eq!(refused(layout.clone(), backwards), "speed_range_mps");
    let restless = MineConfig {
        walk: WalkModel::Roaming(RoamingSettings {
            rest_probability: 1.5,
            ..RoamingSettings::default()
        }),
        ..config.clone()
    };
    assert_eq!(refused(layout.clone(), restless), "rest_probability");
    let never = MineConfig {
        walk: WalkModel::Roaming(RoamingSettings {
            collapse_approach_period_s: Some(0.0),
            ..RoamingSettings::default()
        }),
        ..config.clone()
    };
    assert_eq!(refused(layout.clone(), never), "collapse_approach_period_s");
    let mut nowhere = layout.clone();
    nowhere.collapse.drift = 7;
    assert_eq!(refused(nowhere, config.clone()), "collapse.drift");
    let mut walled_off = layout.clone();
    walled_off.drifts[0].walkable_x_m = [10.0, 200.0]; // short of the cross-cut at 300 m
    assert_eq!(refused(walled_off, config.clone()), "cross_cut");
    let mut empty = layout;
    empty.drifts.clear();
    assert!(matches!(
        MineSimulation::new(empty, config),
        Err(SimError::EmptyInput { .. })
    ));
}

#[test]
fn the_simulation_can_move_to_another_thread() {
    // the server steps it from a task of its runtime
    fn assert_send<T: Send + 'static>() {}
    assert_send::<MineSimulation>();
}
