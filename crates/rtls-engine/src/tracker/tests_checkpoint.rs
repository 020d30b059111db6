//! A tracker's state ([`TrackerState`]) restored into a fresh tracker of the same site, through
//! an encoding that keeps non-finite floats (CBOR): the records after the checkpoint give
//! exactly the outputs of a tracker that never stopped.

use super::tests::site_text;
use super::tests_rewind::three_walkers;
use super::*;
use crate::site::Site;

/// What a run produced, as text (every float printed exactly).
fn outputs(out: &Output) -> Vec<String> {
    let updates = out.updates.iter().map(|u| format!("{u:?}"));
    let events = out.events.iter().map(|e| format!("{e:?}"));
    updates.chain(events).collect()
}

/// Pushes `records`, reporting after every `batch` of them as the server does.
fn feed(tracker: &mut Tracker, records: &[Record], out: &mut Output) {
    for batch in records.chunks(40) {
        for record in batch {
            tracker.push(record.clone(), out).unwrap();
        }
        tracker.report_pending(out).unwrap();
    }
}

/// The state through CBOR and back.
fn encoded_and_decoded(state: &TrackerState) -> TrackerState {
    let mut bytes = Vec::new();
    ciborium::into_writer(state, &mut bytes).unwrap();
    ciborium::from_reader(bytes.as_slice()).unwrap()
}

#[test]
fn a_restored_tracker_continues_exactly_as_the_one_that_never_stopped() {
    for (name, pipeline, extra, rewind) in [
        ("tightly coupled", "tightly-coupled", "", false),
        ("fix-then-filter", "fix-then-filter", "", false),
        ("tightly coupled, rewinding", "tightly-coupled", "", true),
        ("fix-then-filter, rewinding", "fix-then-filter", "", true),
        ("tightly coupled, IMM", "tightly-coupled", "imm", false),
    ] {
        let mut text = site_text(pipeline, "ekf", extra);
        if rewind {
            text = text.replace(
                "reorder_window_s = 0.5",
                "reorder_window_s = 0.0\nrewind_horizon_s = 2.0",
            );
        }
        if extra == "imm" {
            text = text
                .replace("motion_model = \"cv\"", "motion_model = \"imm\"")
                .replace("\nimm\n", "\n");
        }
        let site = Site::from_toml_str(&text, "checkpoint.toml").unwrap();
        let records = three_walkers(16.0, 3);
        let split = records.len() / 2 + 7;

        let mut whole = Tracker::new(&site).unwrap();
        let mut before = Output::default();
        feed(&mut whole, &records[..split], &mut before);
        let state = encoded_and_decoded(&whole.state());
        let mut after_whole = Output::default();
        feed(&mut whole, &records[split..], &mut after_whole);
        whole.finish(&mut after_whole).unwrap();

        let mut resumed = Tracker::new(&site).unwrap();
        resumed.restore(state).unwrap();
        assert_eq!(resumed.track_count(), 3, "{name}");
        let mut after_resumed = Output::default();
        feed(&mut resumed, &records[split..], &mut after_resumed);
        resumed.finish(&mut after_resumed).unwrap();

        let (expected, got) = (outputs(&after_whole), outputs(&after_resumed));
        assert!(
            expected.len() > 100,
            "{name}: {} outputs after the split",
            expected.len()
        );
        assert!(
            after_whole.events.iter().any(|e| format!("{e:?}").contains("office")),
            "{name}: the walkers cross the office after the split"
        );
        assert_eq!(got, expected, "{name}");
        // a tracker that starts from its priors does not give the same tracks
        let mut fresh = Tracker::new(&site).unwrap();
        let mut after_fresh = Output::default();
        feed(&mut fresh, &records[split..], &mut after_fresh);
        assert_ne!(outputs(&after_fresh), expected, "{name}");
    }
}

#[test]
fn a_state_of_the_other_dimension_is_refused_and_changes_nothing() {
    let planar = Site::from_toml_str(&site_text("tightly-coupled", "ekf", ""), "2d.toml").unwrap();
    let spatial_text = site_text("tightly-coupled", "ekf", "")
        .replace("[tracker]\n", "[tracker]\ndimensions = 3\n")
        .replace("tag_height_m = 1.0\n", "");
    let spatial = Site::from_toml_str(&spatial_text, "3d.toml").unwrap();
    let mut tracker = Tracker::new(&planar).unwrap();
    let mut out = Output::default();
    feed(&mut tracker, &three_walkers(3.0, 5), &mut out);
    let state = tracker.state();
    let mut other = Tracker::new(&spatial).unwrap();
    let error = other.restore(state).unwrap_err();
    assert!(matches!(error, EngineError::Checkpoint(_)), "{error}");
    assert!(error.to_string().contains("2-D tracks for a 3-D site"), "{error}");
    assert_eq!(other.track_count(), 0);
}

#[test]
fn alarm_flags_and_zone_memberships_follow_their_zone_ids() {
    let site = Site::from_toml_str(&site_text("tightly-coupled", "ekf", ""), "zones.toml").unwrap();
    let mut tracker = Tracker::new(&site).unwrap();
    let mut out = Output::default();
    feed(&mut tracker, &three_walkers(16.0, 9), &mut out);
    let inside = tracker.head_count("office");
    assert!(inside > 0, "a walker is in the office at the end");
    // the office is dropped and re-added under the new tracker: memberships go with the id
    let mut resumed = Tracker::new(&site).unwrap();
    let zones: Vec<_> = site.zones.iter().filter(|z| z.id != "pit").cloned().collect();
    resumed.replace_zones(zones).unwrap();
    resumed.restore(tracker.state()).unwrap();
    assert_eq!(resumed.head_count("office"), inside);
    assert_eq!(resumed.head_count("pit"), 0);
}

/// The segments each reported state belongs to, in output order.
fn segments(out: &Output) -> Vec<u64> {
    out.states.iter().flatten().map(|state| state.segment).collect()
}

/// The segments of `tag`'s reported states.
fn segments_of(out: &Output, tag: &str) -> Vec<u64> {
    out.states
        .iter()
        .flatten()
        .filter(|state| &*out.updates[state.update].tag == tag)
        .map(|state| state.segment)
        .collect()
}

/// A track's segments are numbered by its own tracker, not by the process: two trackers given
/// the same records report the same segments, and a track created after a restore does not
/// take a restored track's number.
#[test]
fn segments_are_numbered_per_tracker_and_survive_a_restore() {
    let site = Site::from_toml_str(&site_text("fix-then-filter", "ekf", ""), "segments.toml").unwrap();
    let records = three_walkers(8.0, 5);
    let run = || {
        let mut tracker = Tracker::new(&site).unwrap();
        let mut out = Output::keeping_states();
        feed(&mut tracker, &records, &mut out);
        (tracker, out)
    };
    let (first, first_out) = run();
    let (_, second_out) = run();
    assert!(!segments(&first_out).is_empty());
    assert_eq!(segments(&first_out), segments(&second_out));

    let mut restored = Tracker::new(&site).unwrap();
    restored.restore(encoded_and_decoded(&first.state())).unwrap();
    let newcomer: Vec<Record> = records
        .iter()
        .filter(|record| record.tag == records[0].tag)
        .map(|record| Record {
            time_s: record.time_s + 8.0,
            tag: "newcomer".into(),
            measurement: record.measurement.clone(),
        })
        .collect();
    let mut out = Output::keeping_states();
    feed(&mut restored, &newcomer, &mut out);
    let old: std::collections::HashSet<u64> = segments(&first_out).iter().map(|s| s >> 32).collect();
    let new = segments_of(&out, "newcomer");
    assert!(!new.is_empty());
    assert!(new.iter().all(|s| !old.contains(&(s >> 32))), "{old:?} {new:?}");
}
