//! Seed 000 at its scale: the simulated coal mine of `rtls_sim::mine` (307 RSSI readers, 600
//! miners, a roof fall on drift 3 whose reader is broken and whose section is shielded),
//! tracked by the tightly coupled EKF; and the endless feed `rtls serve --demo` streams.
//!
//! Checks (seed 000's claims, on the engine): predictive alarms fire before every miner who
//! walks into the collapse reaches it, with a lead time; a position is output for every miner
//! in every second (PEL = 0, gap filling); the engine loses no miner while he is in coverage.
//! The endless feed keeps scanning every miner every second he is in coverage, keeps them
//! moving inside the tunnels, and sends them into the collapse again and again, each time with
//! a predictive alarm first.

use rtls_engine::lifecycle::{LifecycleEvent, TrackStatus};
use rtls_engine::record::{Measurement, Record};
use rtls_engine::site::Site;
use rtls_engine::tracker::{Event, Output, Tracker};
use rtls_engine::EngineError;
use rtls_sim::mine::{MineConfig, MineLayout, MineSimulation, RoamingSettings, SiteOptions, WalkModel};

/// The scenario's length, s.
const DURATION_S: f64 = 180.0;

fn tag_index(tag: &str) -> usize {
    tag["miner-".len()..].parse::<usize>().unwrap()
}

/// The tracker's output on `records`, and the pushes it refused (the record and the error).
fn track(site: &Site, records: &[Record]) -> (Tracker, Output, Vec<(Record, EngineError)>) {
    let mut tracker = Tracker::new(site).unwrap();
    let mut out = Output::default();
    let mut refused = Vec::new();
    for record in records {
        if let Err(error) = tracker.push(record.clone(), &mut out) {
            refused.push((record.clone(), error));
        }
    }
    tracker.finish(&mut out).unwrap();
    (tracker, out, refused)
}

/// The true positions of miners at times after the start (`(t_s, miner)`, any order): a fresh
/// simulation of `config` stepped through the sorted times (the feed does not depend on the
/// steps).
fn truth_at(layout: &MineLayout, config: &MineConfig, queries: &[(f64, usize)]) -> Vec<[f64; 2]> {
    let mut order: Vec<usize> = (0..queries.len()).collect();
    order.sort_by(|&a, &b| queries[a].0.total_cmp(&queries[b].0));
    let mut simulation = MineSimulation::new(layout.clone(), config.clone()).unwrap();
    let mut positions = vec![[f64::NAN; 2]; queries.len()];
    for q in order {
        let (t_s, miner) = queries[q];
        simulation.step(config.start_time_s + t_s);
        positions[q] = simulation.truth().nth(miner).unwrap().1;
    }
    positions
}

#[test]
fn a_mine_of_600_miners_and_307_readers_alarms_before_the_collapse_with_no_position_loss() {
    let layout = MineLayout::seed000();
    assert_eq!(layout.readers.len(), 307);
    let site = Site::from_toml_str(&layout.site_toml(&SiteOptions::default()), "mine.toml").unwrap();
    let coast_timeout_s = site.tracker.coast_timeout_s;
    let config = MineConfig::seed000_scenario();
    let (tags, entering_tags) = (config.miners, config.entering_miners);
    let mut simulation = MineSimulation::new(layout.clone(), config.clone()).unwrap();
    // patrolling miners keep their drift
    let drifts: Vec<usize> = simulation.truth().map(|(_, p)| layout.drift_at(p).unwrap()).collect();

    // the scans, stepping on a 0.01 s grid to find each entering miner's first time in the
    // collapse (truth entry, 0.01 s resolution)
    let mut records = Vec::new();
    let mut entries_s: Vec<Option<f64>> = vec![None; entering_tags];
    for k in 0..(DURATION_S * 100.0) as usize {
        let t_s = k as f64 / 100.0;
        records.extend(simulation.step(t_s));
        for ((_, position), entry_s) in simulation.truth().zip(entries_s.iter_mut()) {
            if entry_s.is_none() && layout.in_collapse(position) {
                *entry_s = Some(t_s);
            }
        }
    }
    records.extend(simulation.step(DURATION_S));
    let (tracker, out, refused) = track(&site, &records);
    assert!(refused.is_empty(), "the tracker refused {refused:?}");

    // every miner is tracked
    assert_eq!(tracker.track_count(), tags);

    // PEL = 0 (seed 000): from each miner's first confirmed update, every 1-s positioning
    // cycle of his scanner has an output — measured, predicted while coasting, or the kept
    // position while lost
    let mut times: Vec<Vec<(f64, bool)>> = vec![Vec::new(); tags];
    for update in &out.updates {
        let confirmed = update.status != TrackStatus::Tentative;
        times[tag_index(&update.tag)].push((update.time_s, confirmed));
    }
    let (mut missing, mut cycles) = (0, 0);
    for (i, outputs) in times.iter().enumerate() {
        let first = outputs
            .iter()
            .find(|(_, c)| *c)
            .map(|(t, _)| *t)
            .unwrap_or(f64::INFINITY);
        assert!(first < 10.0, "miner {i} confirmed only at {first}");
        let mut start = first - 1e-6;
        while start + 1.0 <= DURATION_S - 1.0 {
            cycles += 1;
            if !outputs.iter().any(|(t, _)| *t >= start && *t < start + 1.0) {
                missing += 1;
            }
            start += 1.0;
        }
    }
    let predicted = out.updates.iter().filter(|u| u.predicted).count();
    assert_eq!(missing, 0, "PEL = {missing}/{cycles}");
    assert!(predicted > 0);

    // no miner is lost while in coverage: lost only in the collapse, after the coast timeout —
    // silent for the coast timeout, most of it (all but the last scans before the border,
    // which may go unheard) inside the collapse
    let lost: Vec<(&str, f64)> = out
        .events
        .iter()
        .filter_map(|event| match event {
            Event::Lifecycle {
                tag,
                time_s,
                event: LifecycleEvent::Lost,
                ..
            } => Some((&**tag, *time_s)),
            _ => None,
        })
        .collect();
    let queries: Vec<(f64, usize)> = lost
        .iter()
        .flat_map(|&(tag, time_s)| {
            let silent_since = time_s - coast_timeout_s;
            [(silent_since + 3.0, tag_index(tag)), (time_s - 0.5, tag_index(tag))]
        })
        .collect();
    let positions = truth_at(&layout, &config, &queries);
    for (k, (tag, time_s)) in lost.iter().enumerate() {
        assert!(
            layout.in_collapse(positions[2 * k]) && layout.in_collapse(positions[2 * k + 1]),
            "{tag} lost at {time_s} s outside the collapse"
        );
    }

    // predictive alarms: every miner who walks in is warned first, with a lead time
    let mut leads = Vec::new();
    for (i, entry_s) in entries_s.iter().enumerate() {
        let entry_s = entry_s.expect("an entering miner enters");
        let tag = format!("miner-{i:03}");
        let alarm_s = out
            .events
            .iter()
            .find_map(|e| match e {
                Event::HazardPredicted {
                    tag: t, zone, time_s, ..
                } if **t == *tag && zone == "collapse" => Some(*time_s),
                _ => None,
            })
            .unwrap_or_else(|| panic!("{tag}: no alarm before entering at {entry_s} s"));
        assert!(
            alarm_s < entry_s - 2.0,
            "{tag}: alarm at {alarm_s} s, entry at {entry_s} s"
        );
        leads.push(entry_s - alarm_s);
        assert!(
            out.events
                .iter()
                .any(|e| matches!(e, Event::NoCoverage { tag: t, zone, .. } if **t == *tag && zone == "collapse")),
            "{tag}: no no-coverage event"
        );
    }
    leads.sort_by(f64::total_cmp);
    let median = leads[leads.len() / 2];
    eprintln!(
        "mine: {} records, {} updates, alarm lead min {:.1} s median {median:.1} s",
        records.len(),
        out.updates.len(),
        leads[0]
    );
    assert!(median > 5.0, "median lead {median}");

    // drift-3 miners who turn back 20 m short of the collapse may be warned (they were heading
    // into danger within the horizon); miners of other drifts only through a cross-track error
    // of ~20 m, which readers along one line allow without a tunnel map (issue 7's map
    // constraint): count both, and bound the second
    let (mut near_misses, mut other_drifts) = (0, 0);
    for event in &out.events {
        if let Event::HazardPredicted { tag, .. } = event {
            let i = tag_index(tag);
            if i >= entering_tags {
                if drifts[i] == layout.collapse.drift {
                    near_misses += 1;
                } else {
                    other_drifts += 1;
                }
            }
        }
    }
    eprintln!("mine: alarms for {near_misses} drift-3 miners who turned back short, {other_drifts} on other drifts");
    assert!(other_drifts <= 6, "{other_drifts} miners of other drifts warned (1 %)");
}

/// The demo feed with few miners and an approach every 5 minutes, on a Unix-time clock.
fn few_roaming_miners() -> MineConfig {
    MineConfig {
        miners: 12,
        entering_miners: 1,
        seed: 7,
        start_time_s: 1.75e9,
        walk: WalkModel::Roaming(RoamingSettings {
            collapse_approach_period_s: Some(300.0),
            ..RoamingSettings::default()
        }),
        ..MineConfig::default()
    }
}

/// 30 simulated minutes, stepped every second as the server does.
const FEED_S: usize = 1800;

/// Steps the feed every second for [`FEED_S`]: the records, and every miner's true position at
/// each whole second (index 0 the start).
fn run_feed(layout: &MineLayout, config: &MineConfig) -> (Vec<Vec<Record>>, Vec<Vec<[f64; 2]>>) {
    let mut simulation = MineSimulation::new(layout.clone(), config.clone()).unwrap();
    let mut truth: Vec<Vec<[f64; 2]>> = simulation.truth().map(|(_, p)| vec![p]).collect();
    let mut steps = Vec::with_capacity(FEED_S);
    for second in 1..=FEED_S {
        steps.push(simulation.step(config.start_time_s + second as f64));
        for (track, (_, position)) in truth.iter_mut().zip(simulation.truth()) {
            track.push(position);
        }
    }
    (steps, truth)
}

/// Seconds `k` at which a miner went from outside the collapse (at `k − 1`) to inside (at `k`).
fn collapse_entries(layout: &MineLayout, truth: &[Vec<[f64; 2]>]) -> Vec<(usize, usize)> {
    let mut entries = Vec::new();
    for (miner, track) in truth.iter().enumerate() {
        for (k, pair) in track.windows(2).enumerate() {
            if !layout.in_collapse(pair[0]) && layout.in_collapse(pair[1]) {
                entries.push((k + 1, miner));
            }
        }
    }
    entries.sort_unstable();
    entries
}

#[test]
fn the_endless_feed_scans_every_miner_every_second_and_keeps_them_moving_inside_the_tunnels() {
    let layout = MineLayout::seed000();
    let config = few_roaming_miners();
    let WalkModel::Roaming(settings) = &config.walk else {
        unreachable!()
    };
    let (steps, truth) = run_feed(&layout, &config);
    let working: std::collections::HashSet<&str> = layout
        .readers
        .iter()
        .filter(|r| r.working)
        .map(|r| r.id.as_str())
        .collect();

    for (k, records) in steps.iter().enumerate() {
        let until_s = config.start_time_s + (k + 1) as f64;
        // the scans of this second, in time order, from working readers only
        assert!(
            records.windows(2).all(|w| w[0].time_s <= w[1].time_s),
            "second {k}: out of order"
        );
        let mut scan_times: Vec<Option<f64>> = vec![None; config.miners];
        for record in records {
            assert!(
                record.time_s > until_s - 1.0 && record.time_s <= until_s,
                "second {k}: {record:?}"
            );
            let Measurement::Rssi { anchor, .. } = &record.measurement else {
                panic!("not an RSSI reading: {record:?}")
            };
            assert!(working.contains(anchor.as_str()), "heard by {anchor}");
            // one scan per miner per second: all his readings share its time
            let scan = &mut scan_times[tag_index(&record.tag)];
            assert_eq!(
                *scan.get_or_insert(record.time_s),
                record.time_s,
                "{}: two scans",
                record.tag
            );
        }
        for (miner, scan) in scan_times.iter().enumerate() {
            let (before, after) = (truth[miner][k], truth[miner][k + 1]);
            match (layout.in_collapse(before), layout.in_collapse(after)) {
                (false, false) => assert!(scan.is_some(), "miner {miner} in coverage not heard in second {k}"),
                (true, true) => assert!(scan.is_none(), "miner {miner} heard inside the collapse"),
                _ => {}
            }
        }
    }

    let longest_rest_s = settings.rest_duration_s[1].max(settings.collapse_linger_s[1]);
    let [_, collapse_east_m] = layout.collapse.x_range_m;
    for (miner, track) in truth.iter().enumerate() {
        for (k, &position) in track.iter().enumerate() {
            // inside the tunnels, and never beyond the roof fall
            assert!(
                layout.inside_tunnels(position),
                "miner {miner} at {position:?} at {k} s"
            );
            if layout.drift_at(position) == Some(layout.collapse.drift) {
                assert!(
                    position[0] <= collapse_east_m,
                    "miner {miner} east of the collapse at {k} s"
                );
            }
        }
        // nobody stuck: no standstill longer than the longest rest, and a real walk in every
        // 5 minutes
        let steps_m: Vec<f64> = track
            .windows(2)
            .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
            .collect();
        let (mut still_s, mut longest_still_s) = (0, 0);
        for &step_m in &steps_m {
            still_s = if step_m < 1e-9 { still_s + 1 } else { 0 };
            longest_still_s = longest_still_s.max(still_s);
        }
        assert!(
            longest_still_s as f64 <= longest_rest_s + 1.0,
            "miner {miner} still for {longest_still_s} s"
        );
        for window in steps_m.chunks(300) {
            let walked_m: f64 = window.iter().sum();
            assert!(walked_m > 30.0, "miner {miner} walked only {walked_m:.1} m in 5 min");
        }
        // and walking speeds stay human
        assert!(steps_m.iter().all(|&m| m <= config.speed_range_mps[1] + 1e-9));
    }

    // repeated approaches to the collapse, not only the first minutes' entering miner
    let entries = collapse_entries(&layout, &truth);
    eprintln!("mine feed: collapse entries (s, miner) {entries:?}");
    assert!(entries.len() >= 3, "{entries:?}");
    assert!(
        entries.iter().any(|&(k, _)| k > 600),
        "no approach after 10 minutes: {entries:?}"
    );
}

#[test]
fn the_tracker_on_the_endless_feed_warns_before_every_approach_to_the_collapse() {
    let layout = MineLayout::seed000();
    let config = few_roaming_miners();
    let site = Site::from_toml_str(&layout.site_toml(&SiteOptions::default()), "mine.toml").unwrap();
    let (steps, truth) = run_feed(&layout, &config);
    let records: Vec<Record> = steps.into_iter().flatten().collect();
    let (_, out, refused) = track(&site, &records);
    assert!(refused.is_empty(), "the tracker refused {refused:?}");

    let entries = collapse_entries(&layout, &truth);
    assert!(entries.len() >= 3, "{entries:?}");
    let mut leads_s = Vec::new();
    for &(k, miner) in &entries {
        // truth entry within the second before k
        let entry_s = config.start_time_s + k as f64;
        let tag = format!("miner-{miner:03}");
        // the last alarm of this approach: within the minute before the entry
        let alarm_s = out
            .events
            .iter()
            .filter_map(|e| match e {
                Event::HazardPredicted {
                    tag: t, zone, time_s, ..
                } if **t == *tag && zone == "collapse" && (entry_s - 60.0..entry_s).contains(time_s) => Some(*time_s),
                _ => None,
            })
            .reduce(f64::max)
            .unwrap_or_else(|| panic!("{tag}: no alarm before entering at {k} s"));
        leads_s.push(entry_s - alarm_s);
    }
    eprintln!("mine feed: alarm leads {leads_s:.1?} s");
    assert!(leads_s.iter().all(|&lead| lead > 2.0), "{leads_s:?}");
}

/// RMSE of every output (updates and coasting predictions) against the truth, linearly
/// interpolated between the whole seconds [`run_feed`] records.
fn rmse_m(out: &Output, truth: &[Vec<[f64; 2]>], start_time_s: f64) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for u in &out.updates {
        let t = u.time_s - start_time_s;
        let k = t.floor() as usize;
        let track = &truth[tag_index(&u.tag)];
        let (Some(a), Some(b)) = (track.get(k), track.get(k + 1)) else {
            continue;
        };
        let w = t - k as f64;
        let p = [a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1])];
        sum += (u.position_m[0] - p[0]).powi(2) + (u.position_m[1] - p[1]).powi(2);
        count += 1;
    }
    assert!(count > 10_000, "{count} outputs");
    (sum / count as f64).sqrt()
}

#[test]
fn the_tunnel_map_and_silent_readers_halve_the_demo_mines_error() {
    let layout = MineLayout::seed000();
    let config = few_roaming_miners();
    let (steps, truth) = run_feed(&layout, &config);
    let records: Vec<Record> = steps.into_iter().flatten().collect();
    let run = |options: &SiteOptions| {
        let site = Site::from_toml_str(&layout.site_toml(options), "mine.toml").unwrap();
        let (_, out, refused) = track(&site, &records);
        assert!(refused.is_empty());
        rmse_m(&out, &truth, config.start_time_s)
    };
    let plain = run(&SiteOptions {
        without_map: true,
        ..SiteOptions::default()
    });
    let mut site = Site::from_toml_str(&layout.site_toml(&SiteOptions::default()), "mine.toml").unwrap();
    site.tracker.negative_information = false;
    let (_, out, _) = track(&site, &records);
    let map_only = rmse_m(&out, &truth, config.start_time_s);
    let best = run(&SiteOptions::default());
    eprintln!(
        "demo mine, 12 roaming miners for 30 min: RMSE RSSI only {plain:.2} m, + tunnel map {map_only:.2} m, \
         + silent readers {best:.2} m"
    );
    assert!(map_only < 0.8 * plain, "map {map_only:.2} vs {plain:.2} m");
    assert!(
        best < 0.6 * plain && best <= map_only,
        "best {best:.2} vs {map_only:.2} / {plain:.2} m"
    );
}
