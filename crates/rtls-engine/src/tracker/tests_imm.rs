//! `motion_model = "imm"`: a tag that walks straight, turns and walks straight again, tracked
//! by the interacting multiple models; model-switch events and accuracy against the CV model.

use super::tests::{range_records, rmse, run, site, site_text};
use super::*;
use crate::site::Site;

/// Straight east at 1.5 m/s from (2, 10) for 6 s; a left turn at 0.6 rad/s (radius 2.5 m,
/// centripetal acceleration 0.9 m/s²) for 4 s; straight on at the new heading.
fn turner(t: f64) -> [f64; 2] {
    const SPEED_MPS: f64 = 1.5;
    const OMEGA_RAD_S: f64 = 0.6;
    const TURN_START_S: f64 = 6.0;
    const TURN_END_S: f64 = 10.0;
    if t <= TURN_START_S {
        return [2.0 + SPEED_MPS * t, 10.0];
    }
    let radius_m = SPEED_MPS / OMEGA_RAD_S;
    // centre of the turn: left of the heading at its start, (11, 10 + R)
    let centre = [2.0 + SPEED_MPS * TURN_START_S, 10.0 + radius_m];
    let turned = |tau: f64| {
        let angle = OMEGA_RAD_S * tau;
        [centre[0] + radius_m * angle.sin(), centre[1] - radius_m * angle.cos()]
    };
    if t <= TURN_END_S {
        return turned(t - TURN_START_S);
    }
    let end = turned(TURN_END_S - TURN_START_S);
    let heading = OMEGA_RAD_S * (TURN_END_S - TURN_START_S);
    let tau = t - TURN_END_S;
    [
        end[0] + SPEED_MPS * heading.cos() * tau,
        end[1] + SPEED_MPS * heading.sin() * tau,
    ]
}

fn switches(out: &Output) -> Vec<(f64, &'static str, &'static str)> {
    out.events
        .iter()
        .filter_map(|e| match e {
            Event::ModelSwitch { time_s, from, to, .. } => Some((*time_s, *from, *to)),
            _ => None,
        })
        .collect()
}

fn positions(out: &Output, from_s: f64, to_s: f64) -> Vec<(f64, [f64; 3])> {
    out.updates
        .iter()
        .filter(|u| u.time_s >= from_s && u.time_s <= to_s)
        .map(|u| (u.time_s, u.position_m))
        .collect()
}

/// The simulated ranges' errors are independent from one reading to the next: the site says so.
/// White, unbiased ranges as the site states them: no correlation inflation, and no range
/// offsets to learn (the comparison is of motion models).
const WHITE_NOISE: &str = "adaptive_noise = { correlation_s = 0.0 }\nrange_bias = { enabled = false }";

/// The test site under the IMM, with a quiet CV mode (σ_a = 0.05 m/s² instead of the single
/// CV model's 0.5 m/s²): the manoeuvre modes carry the turns.
fn imm_site(pipeline: &str, filter: &str) -> Site {
    let text = site_text(pipeline, filter, WHITE_NOISE)
        .replace("motion_model = \"cv\"", "motion_model = \"imm\"")
        .replace(
            "acceleration_noise_std_mps2 = 0.5",
            "acceleration_noise_std_mps2 = 0.05",
        );
    Site::from_toml_str(&text, "imm.toml").unwrap()
}

#[test]
fn the_imm_reports_the_turn_as_model_switches_and_tracks_it_better_than_cv() {
    for (pipeline, filter) in [("fix-then-filter", "kf"), ("tightly-coupled", "ekf")] {
        let records = || {
            let mut records = range_records(18.0, 11, turner);
            if pipeline == "tightly-coupled" {
                // one anchor per 25 ms slot (seed 003's one-observation updates)
                for (i, record) in records.iter_mut().enumerate() {
                    record.time_s += (i % 4) as f64 * 0.025;
                }
            }
            records
        };
        let imm = run(&mut Tracker::new(&imm_site(pipeline, filter)).unwrap(), records());
        let cv = run(
            &mut Tracker::new(&site(pipeline, filter, WHITE_NOISE)).unwrap(),
            records(),
        );
        let found = switches(&imm);
        // out of the quiet mode within 2 s of the turn's start, back to CV within 4 s of its end
        let onset = found
            .iter()
            .find(|(t, from, to)| *t >= 6.0 && *from == "CV" && *to != "CV")
            .unwrap_or_else(|| panic!("{pipeline}: no switch out of CV after 6 s: {found:?}"));
        assert!(onset.0 < 8.0, "{pipeline}: late onset {onset:?}");
        let back = found
            .iter()
            .find(|(t, _, to)| *t >= 10.0 && *to == "CV")
            .unwrap_or_else(|| panic!("{pipeline}: no switch back to CV after 10 s: {found:?}"));
        assert!(back.0 < 14.0, "{pipeline}: late return {back:?}");
        // the straight walk before the turn, once converged, is CV throughout
        assert!(
            found.iter().all(|(t, _, _)| !(3.0..6.0).contains(t)),
            "{pipeline}: switches on the straight: {found:?}"
        );
        // every update says which mode is reported, and during the turn it is not CV
        assert!(imm.updates.iter().all(|u| u.mode.is_some()));
        assert!(cv.updates.iter().all(|u| u.mode.is_none()));
        let in_turn: Vec<&TrackUpdate> = imm.updates.iter().filter(|u| (8.0..9.5).contains(&u.time_s)).collect();
        assert!(in_turn.iter().all(|u| u.mode != Some("CV")), "{pipeline}");
        // accuracy through the turn: the IMM beats the single CV model of the same noise
        let (imm_error, cv_error) = (
            rmse(&positions(&imm, 6.0, 12.0), turner, 6.0),
            rmse(&positions(&cv, 6.0, 12.0), turner, 6.0),
        );
        println!("{pipeline}: turn RMSE IMM {imm_error:.4} m, CV {cv_error:.4} m; switches {found:?}");
        assert!(imm_error < cv_error, "{pipeline}: IMM {imm_error} vs CV {cv_error}");
        // and on the straight, where its quiet CV mode leads, it beats CV too
        let (imm_straight, cv_straight) = (
            rmse(&positions(&imm, 3.0, 6.0), turner, 3.0),
            rmse(&positions(&cv, 3.0, 6.0), turner, 3.0),
        );
        println!("{pipeline}: straight RMSE IMM {imm_straight:.4} m, CV {cv_straight:.4} m");
        assert!(
            imm_straight < cv_straight,
            "{pipeline}: {imm_straight} vs {cv_straight}"
        );
    }
}

#[test]
fn model_switch_events_are_json_lines_and_accelerometers_are_used_under_the_imm() {
    let event = Event::ModelSwitch {
        tag: "w1".into(),
        time_s: 9.5,
        from: "CV",
        to: "CT",
        probability: 0.71,
    };
    let value: serde_json::Value = serde_json::from_str(&event.to_json_line()).unwrap();
    assert_eq!(value["type"], "model-switch");
    assert_eq!(value["from"], "CV");
    assert_eq!(value["to"], "CT");
    assert_eq!(value["probability"], 0.71);

    let mut tracker = Tracker::new(&imm_site("fix-then-filter", "kf")).unwrap();
    let mut records = range_records(2.0, 3, turner);
    records.push(Record {
        time_s: 1.05,
        tag: "w1".into(),
        measurement: crate::record::Measurement::Accelerometer {
            acceleration_mps2: vec![0.1, 0.0],
            std_mps2: None,
        },
    });
    records.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    let out = run(&mut tracker, records);
    // the CV mode's control input (tests_robust checks its effect)
    let refused = out.events.iter().any(|e| {
        matches!(
            e,
            Event::Rejected {
                kind: "accelerometer",
                ..
            }
        )
    });
    assert!(!refused, "{:?}", out.events);
    let line: serde_json::Value = serde_json::from_str(&out.updates[0].to_json_line()).unwrap();
    assert_eq!(line["mode"], "CV");
}

#[test]
fn imm_settings_are_validated_by_name() {
    let text = site_text("fix-then-filter", "kf", "imm = { switch_probability = 1.5 }")
        .replace("motion_model = \"cv\"", "motion_model = \"imm\"");
    let error = Site::from_toml_str(&text, "imm.toml").unwrap_err().to_string();
    assert!(error.contains("tracker.imm.switch_probability"), "{error}");
    // a partial table keeps the other defaults
    let text = site_text("fix-then-filter", "kf", "imm = { ca_sojourn_s = 2.0 }")
        .replace("motion_model = \"cv\"", "motion_model = \"imm\"");
    let site = Site::from_toml_str(&text, "imm.toml").unwrap();
    assert_eq!(site.tracker.imm.ca_sojourn_s, 2.0);
    assert_eq!(site.tracker.imm.switch_probability, 0.6);
}

/// The test site with `motion_model` and its extra keys in `[tracker]`.
fn model_site(filter: &str, motion_model: &str, extra: &str) -> Site {
    let text = site_text("tightly-coupled", filter, WHITE_NOISE).replace(
        "motion_model = \"cv\"",
        &format!("motion_model = \"{motion_model}\"\n{extra}"),
    );
    Site::from_toml_str(&text, "models.toml").unwrap()
}

#[test]
fn the_coordinated_turn_alone_follows_the_turn_better_than_cv_with_either_filter() {
    let records = || {
        let mut records = range_records(18.0, 11, turner);
        for (i, record) in records.iter_mut().enumerate() {
            record.time_s += (i % 4) as f64 * 0.025;
        }
        records
    };
    let cv = run(
        &mut Tracker::new(&site("tightly-coupled", "ekf", WHITE_NOISE)).unwrap(),
        records(),
    );
    let cv_error = rmse(&positions(&cv, 6.0, 12.0), turner, 6.0);
    for filter in ["ekf", "ukf"] {
        let ct = run(
            &mut Tracker::new(&model_site(filter, "ct", "initial_turn_rate_std_radps = 0.5")).unwrap(),
            records(),
        );
        // one mode: every update names it, and it never switches
        assert!(ct.updates.iter().all(|u| u.mode == Some("CT")), "{filter}");
        assert!(switches(&ct).is_empty(), "{filter}");
        let ct_error = rmse(&positions(&ct, 6.0, 12.0), turner, 6.0);
        println!("{filter}: turn RMSE CT {ct_error:.4} m, CV {cv_error:.4} m");
        assert!(ct_error < cv_error, "{filter}: CT {ct_error} vs CV {cv_error}");
    }
}

#[test]
fn an_imm_of_chosen_modes_runs_those_modes_only() {
    let site = model_site("ukf", "imm", "");
    let text = site_text("tightly-coupled", "ukf", WHITE_NOISE)
        .replace("motion_model = \"cv\"", "motion_model = \"imm\"")
        + "\n[tracker.imm]\nmodes = [\"cv\", \"ct\"]\n";
    let chosen = Site::from_toml_str(&text, "modes.toml").unwrap();
    let out = run(&mut Tracker::new(&chosen).unwrap(), range_records(18.0, 11, turner));
    assert!(out.updates.iter().all(|u| matches!(u.mode, Some("CV" | "CT"))));
    assert!(
        switches(&out).iter().any(|(_, _, to)| *to == "CT"),
        "{:?}",
        switches(&out)
    );
    // the default set has three modes
    assert_eq!(site.tracker.imm.modes, None);
}

#[test]
fn mode_sets_and_the_turn_in_3d_are_checked_by_the_loader() {
    let base =
        site_text("tightly-coupled", "ukf", WHITE_NOISE).replace("motion_model = \"cv\"", "motion_model = \"imm\"");
    for (modes, field) in [
        ("[]", "tracker.imm.modes"),
        ("[\"cv\", \"cv\"]", "tracker.imm.modes"),
        ("[\"cv\", \"singer\"]", "tracker.imm.modes"),
    ] {
        let text = format!("{base}\n[tracker.imm]\nmodes = {modes}\n");
        let error = Site::from_toml_str(&text, "modes.toml").unwrap_err().to_string();
        assert!(error.contains(field), "{modes}: {error}");
    }
    let spatial = base.replace("tag_height_m = 1.0\n", "dimensions = 3\n");
    let text = format!("{spatial}\n[tracker.imm]\nmodes = [\"cv\", \"ct\"]\n");
    let error = Site::from_toml_str(&text, "modes.toml").unwrap_err().to_string();
    assert!(error.contains("tracker.imm.modes"), "{error}");
    let text = spatial.replace("motion_model = \"imm\"", "motion_model = \"ct\"");
    let error = Site::from_toml_str(&text, "modes.toml").unwrap_err().to_string();
    assert!(error.contains("tracker.motion_model"), "{error}");
}
