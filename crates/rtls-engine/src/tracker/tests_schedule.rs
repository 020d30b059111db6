//! `[scheduling]`: seed 003's adaptive task nodes reported by the tracker as a tag crosses the
//! cells of the 4 m × 6 m test bed.

use super::tests::run;
use super::*;
use crate::record::Measurement;
use crate::site::Site;

/// Seed 003's bed: readers `r{row}{column}` on the corners of 2 m cells, 3 task nodes, 0.3 m
/// edge margin, a 0.3 s cycle.
fn bed_site() -> Site {
    let mut text = String::new();
    for row in 0..4 {
        for column in 0..3 {
            text.push_str(&format!(
                "[[readers]]\nid = \"r{row}{column}\"\nposition_m = [{}.0, {}.0]\ntechnology = \"ultrasonic\"\n",
                2 * column,
                2 * row
            ));
        }
    }
    text.push_str("[scheduling]\ncycle_s = 0.3\ntask_nodes = 3\nedge_margin_m = 0.3\ncells = [\n");
    for row in 0..3 {
        for column in 0..2 {
            text.push_str(&format!(
                "  {{ min_m = [{x0}.0, {y0}.0], max_m = [{x1}.0, {y1}.0], readers = [\"r{row}{column}\", \"r{row}{c1}\", \"r{r1}{column}\", \"r{r1}{c1}\"] }},\n",
                x0 = 2 * column,
                y0 = 2 * row,
                x1 = 2 * column + 2,
                y1 = 2 * row + 2,
                r1 = row + 1,
                c1 = column + 1
            ));
        }
    }
    text.push_str(
        "]\n[tracker]\npipeline = \"fix-then-filter\"\nmotion_model = \"cv\"\nfilter = \"kf\"\n\
         acceleration_noise_std_mps2 = 0.3\ngate_probability = 0.999\n\
         initiation = { confirm_updates = 3, within_s = 1.0 }\ncoast_timeout_s = 2.0\n\
         delete_timeout_s = 10.0\nreorder_window_s = 0.0\n",
    );
    Site::from_toml_str(&text, "bed.toml").unwrap()
}

/// A robot driving north at 0.5 m/s along x = 0.7 m from y = 0.5 m, fixes at 10 Hz.
fn path(t: f64) -> [f64; 2] {
    [0.7, 0.5 + 0.5 * t]
}

fn schedules(out: &Output) -> Vec<(f64, Vec<String>, Vec<String>)> {
    out.events
        .iter()
        .filter_map(|e| match e {
            Event::Schedule {
                time_s,
                task_nodes,
                monitors,
                ..
            } => Some((
                *time_s,
                task_nodes.iter().map(|n| n.to_string()).collect(),
                monitors.iter().map(|n| n.to_string()).collect(),
            )),
            _ => None,
        })
        .collect()
}

#[test]
fn task_nodes_follow_the_track_across_cells_with_edge_monitors_at_the_borders() {
    let records: Vec<Record> = (0..90)
        .map(|k| {
            let t = k as f64 * 0.1;
            let p = path(t);
            Record {
                time_s: t,
                tag: "robot-A".into(),
                measurement: Measurement::Fix {
                    position_m: vec![p[0], p[1]],
                    covariance_m2: vec![0.0004, 0.0, 0.0, 0.0004],
                },
            }
        })
        .collect();
    let out = run(&mut Tracker::new(&bed_site()).unwrap(), records);
    let found = schedules(&out);
    // the first: the 3 nodes of cell 0 nearest to (0.7, ~0.6): r00, r10, r01
    let (_, first_nodes, first_monitors) = &found[0];
    assert_eq!(first_nodes, &["r00", "r10", "r01"], "{found:?}");
    assert!(first_monitors.is_empty());
    // once the prediction one cycle ahead crosses y = 2, the rule takes one node of the cell
    // ahead (two kept, one new): the track crosses with the border nodes r10, r11 measuring
    let crossing_s = (2.0 - 0.5) / 0.5;
    let ahead = found
        .iter()
        .find(|(_, nodes, _)| nodes.iter().any(|n| n.starts_with("r2")))
        .unwrap_or_else(|| panic!("{found:?}"));
    assert!(ahead.0 > crossing_s - 0.6 && ahead.0 <= crossing_s, "{ahead:?}");
    assert!(
        ahead.1.contains(&"r10".to_string()) && ahead.1.contains(&"r11".to_string()),
        "{ahead:?}"
    );
    // by the end the task nodes are cell 4's (reader rows 2 and 3)
    let (_, last_nodes, _) = found.last().unwrap();
    assert!(
        last_nodes.iter().all(|n| n.starts_with("r2") || n.starts_with("r3")),
        "{found:?}"
    );
    // events only when the sets change: far fewer than the 90 updates
    assert!(found.len() < 10, "{}", found.len());
    let line: serde_json::Value = serde_json::from_str(
        &out.events
            .iter()
            .find(|e| matches!(e, Event::Schedule { .. }))
            .unwrap()
            .to_json_line(),
    )
    .unwrap();
    assert_eq!(line["type"], "schedule");
    assert_eq!(line["task_nodes"][0], "r00");
}

#[test]
fn cells_without_shared_readers_monitor_each_other_near_the_border() {
    // two cells side by side, each with its own four readers; a robot drives east along y = 1
    let mut text = String::new();
    for (id, x, y) in [
        ("a1", 0.0, 0.0),
        ("a2", 1.8, 0.0),
        ("a3", 0.0, 2.0),
        ("a4", 1.8, 2.0),
        ("b1", 2.2, 0.0),
        ("b2", 4.0, 0.0),
        ("b3", 2.2, 2.0),
        ("b4", 4.0, 2.0),
    ] {
        text.push_str(&format!(
            "[[readers]]\nid = \"{id}\"\nposition_m = [{x:.1}, {y:.1}]\ntechnology = \"ultrasonic\"\n"
        ));
    }
    text.push_str(
        "[scheduling]\ncycle_s = 0.3\ntask_nodes = 3\nedge_margin_m = 0.3\ncells = [\n\
         { min_m = [0.0, 0.0], max_m = [2.0, 2.0], readers = [\"a1\", \"a2\", \"a3\", \"a4\"] },\n\
         { min_m = [2.0, 0.0], max_m = [4.0, 2.0], readers = [\"b1\", \"b2\", \"b3\", \"b4\"] },\n]\n\
         [tracker]\npipeline = \"fix-then-filter\"\nmotion_model = \"cv\"\nfilter = \"kf\"\n\
         acceleration_noise_std_mps2 = 0.3\ngate_probability = 0.999\n\
         initiation = { confirm_updates = 3, within_s = 1.0 }\ncoast_timeout_s = 2.0\n\
         delete_timeout_s = 10.0\nreorder_window_s = 0.0\n",
    );
    let site = Site::from_toml_str(&text, "two-cells.toml").unwrap();
    let records: Vec<Record> = (0..60)
        .map(|k| {
            let t = k as f64 * 0.1;
            Record {
                time_s: t,
                tag: "robot-B".into(),
                measurement: Measurement::Fix {
                    position_m: vec![0.5 + 0.5 * t, 1.0],
                    covariance_m2: vec![0.0004, 0.0, 0.0, 0.0004],
                },
            }
        })
        .collect();
    let out = run(&mut Tracker::new(&site).unwrap(), records);
    let found = schedules(&out);
    let monitored: Vec<_> = found.iter().filter(|(_, _, monitors)| !monitors.is_empty()).collect();
    assert!(!monitored.is_empty(), "{found:?}");
    // the prediction 0.15 m ahead enters the 0.3 m edge zone at x ≈ 1.55 m (t ≈ 2.1 s): cell
    // b's nodes monitor while the robot is in cell a
    let (t, nodes, monitors) = monitored[0];
    assert!((1.8..=2.6).contains(t), "{found:?}");
    assert!(
        nodes.iter().all(|n| n.starts_with('a')) && monitors.iter().all(|m| m.starts_with('b')),
        "{found:?}"
    );
    // beyond the edge zone no monitor remains, and the task nodes are cell b's
    let (_, last_nodes, last_monitors) = found.last().unwrap();
    assert!(
        last_monitors.is_empty() && last_nodes.iter().all(|n| n.starts_with('b')),
        "{found:?}"
    );
}

#[test]
fn scheduling_cells_are_validated_by_name() {
    let text = "[[readers]]\nid = \"a\"\nposition_m = [0.0, 0.0]\ntechnology = \"uwb\"\n\
                [scheduling]\ncycle_s = 0.3\ntask_nodes = 2\nedge_margin_m = 0.3\n\
                cells = [{ min_m = [0.0, 0.0], max_m = [2.0, 2.0], readers = [\"a\", \"ghost\"] }]\n\
                [tracker]\npipeline = \"fix-then-filter\"\nmotion_model = \"cv\"\nfilter = \"kf\"\n\
                acceleration_noise_std_mps2 = 0.3\ngate_probability = 0.999\n\
                initiation = { confirm_updates = 3, within_s = 1.0 }\ncoast_timeout_s = 2.0\n\
                delete_timeout_s = 10.0\nreorder_window_s = 0.0\n";
    let error = Site::from_toml_str(text, "bed.toml").unwrap_err().to_string();
    assert!(error.contains("scheduling.cells[0].readers[1]"), "{error}");
    let error = Site::from_toml_str(&text.replace("cycle_s = 0.3", "cycle_s = 0.0"), "bed.toml")
        .unwrap_err()
        .to_string();
    assert!(error.contains("scheduling.cycle_s"), "{error}");
    let overlapping = text.replace(
        "readers = [\"a\", \"ghost\"] }]",
        "readers = [\"a\"] }, { min_m = [1.0, 1.0], max_m = [3.0, 3.0], readers = [\"a\"] }]",
    );
    let error = Site::from_toml_str(&overlapping, "bed.toml").unwrap_err().to_string();
    assert!(error.contains("scheduling.cells"), "{error}");
}
