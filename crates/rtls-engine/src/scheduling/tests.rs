//! Scheduling tests against hand-computed cases on seed 003's bed (4 m × 6 m, 2 m cells; nodes
//! 0–11 row by row: node `3·row + col` at `(2·col, 2·row)`; cell `2·row + col`).

use super::*;
use crate::EngineError;

fn bed() -> Layout {
    Layout::grid(4.0, 6.0, 2.0).unwrap()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-12
}

fn invalid_name(err: EngineError) -> &'static str {
    match err {
        EngineError::InvalidParameter { name, .. } => name,
        other => panic!("unexpected error {other}"),
    }
}

#[test]
fn the_grid_numbers_nodes_and_cells_row_by_row() {
    let bed = bed();
    assert_eq!(bed.nodes()[11].position_m, [4.0, 6.0]);
    assert_eq!(bed.nodes()[4].id, "n4");
    // cell 3 = column 1, row 1: x 2–4, y 2–4, corners (2,2), (4,2), (2,4), (4,4)
    assert_eq!(bed.cells()[3].nodes, vec![4, 5, 7, 8]);
    assert_eq!((bed.cells()[3].min_m, bed.cells()[3].max_m), ([2.0, 2.0], [4.0, 4.0]));
    // a point on an inner border belongs to the cell to its right / above
    assert_eq!(bed.cell_of([2.0, 1.0]), Some(1));
    assert_eq!(bed.cell_of([1.0, 2.0]), Some(2));
    // outside: the nearest cell; NaN: none
    assert_eq!(bed.cell_of([-5.0, 99.0]), Some(4));
    assert_eq!(bed.cell_of([4.0, 6.0]), Some(5));
    assert_eq!(bed.cell_of([f64::NAN, 0.0]), None);
    // cell 3 touches every other cell; cell 0 touches 1, 2 and (at a corner) 3
    assert_eq!(bed.neighbours(3), &[0, 1, 2, 4, 5]);
    assert_eq!(bed.neighbours(0), &[1, 2, 3]);
    // the three nodes of cell 0 nearest to (1.8, 0.5): (2,0) 0.54 m, (2,2) 1.51 m, (0,0) 1.87 m
    assert_eq!(bed.nearest_cell_nodes(0, [1.8, 0.5], 3), vec![1, 4, 0]);
    assert_eq!(bed.nearest_cell_nodes(0, [1.8, 0.5], 9).len(), 4);
    assert!(bed.nearest_cell_nodes(17, [1.8, 0.5], 3).is_empty());
    // distance to the nearest inner border: y = 4 is 0.3 m from (1.0, 3.7)
    assert!(close(bed.distance_to_inner_border_m([1.0, 3.7]), 0.3));
    assert!(close(bed.distance_to_inner_border_m([2.5, 1.0]), 0.5));
}

#[test]
fn edge_zones_name_the_neighbours_and_their_shared_nodes() {
    let bed = bed();
    // 0.1 m left of x = 2 in cell 0: cell 1 across, sharing nodes (2,0) and (2,2)
    assert_eq!(
        bed.near_cells(0, [1.9, 1.0], 0.3),
        vec![NearCell {
            cell: 1,
            monitors: vec![1, 4]
        }]
    );
    // cell 3 near its lower-left corner (2, 2): cells 0 (diagonal, corner node 4), 1 (border
    // y = 2: nodes 4, 5) and 2 (border x = 2: nodes 4, 7)
    let near = bed.near_cells(3, [2.1, 2.2], 0.3);
    let got: Vec<(usize, Vec<usize>)> = near.into_iter().map(|n| (n.cell, n.monitors)).collect();
    assert_eq!(got, vec![(0, vec![4]), (1, vec![4, 5]), (2, vec![4, 7])]);
    // outer walls are not borders; mid-cell is in no edge zone; the margin is strict
    assert!(bed.near_cells(0, [0.1, 0.1], 0.3).is_empty());
    assert!(bed.near_cells(2, [1.0, 3.0], 0.3).is_empty());
    assert!(bed.near_cells(0, [1.7, 1.0], 0.3).is_empty());
}

#[test]
fn cells_that_share_no_node_are_monitored_by_the_neighbours_nearest_nodes() {
    // cell 0: [0, 2] × [0, 2] with corner nodes 0–3; cell 1: [2, 5] × [0, 1] with its own
    // nodes 4 at (3, 0.5) and 5 at (4.5, 0.5) and 6 at (5, 1)
    let node = |id: &str, x: f64, y: f64| Node {
        id: id.to_string(),
        position_m: [x, y],
    };
    let nodes = vec![
        node("a", 0.0, 0.0),
        node("b", 2.0, 0.0),
        node("c", 0.0, 2.0),
        node("d", 2.0, 2.0),
        node("e", 3.0, 0.5),
        node("f", 4.5, 0.5),
        node("g", 5.0, 1.0),
    ];
    let cells = vec![
        Cell {
            min_m: [0.0, 0.0],
            max_m: [2.0, 2.0],
            nodes: vec![0, 1, 2, 3],
        },
        Cell {
            min_m: [2.0, 0.0],
            max_m: [5.0, 1.0],
            nodes: vec![4, 5, 6],
        },
    ];
    let layout = Layout::new(nodes, cells).unwrap();
    assert_eq!(layout.neighbours(0), &[1]);
    // (1.9, 0.5): 0.1 m from cell 1; its nearest nodes: e (1.1 m), f (2.6 m)
    assert_eq!(
        layout.near_cells(0, [1.9, 0.5], 0.3),
        vec![NearCell {
            cell: 1,
            monitors: vec![4, 5]
        }]
    );
    // (1.9, 1.5) is 0.5 m above cell 1 (Chebyshev): outside the zone
    assert!(layout.near_cells(0, [1.9, 1.5], 0.3).is_empty());
    // a point above cell 1 (no cell there) belongs to the nearest cell
    assert_eq!(layout.cell_of([4.0, 1.5]), Some(1));
}

#[test]
fn bad_layouts_are_errors_naming_the_field() {
    let node = |id: &str, x: f64| Node {
        id: id.to_string(),
        position_m: [x, 0.0],
    };
    let cell = |x0: f64, x1: f64, nodes: Vec<usize>| Cell {
        min_m: [x0, 0.0],
        max_m: [x1, 1.0],
        nodes,
    };
    let cases = [
        (Layout::new(vec![], vec![cell(0.0, 1.0, vec![0])]), "nodes"),
        (
            Layout::new(vec![node("a", 0.0), node("a", 1.0)], vec![cell(0.0, 1.0, vec![0])]),
            "nodes",
        ),
        (
            Layout::new(vec![node("a", f64::NAN)], vec![cell(0.0, 1.0, vec![0])]),
            "nodes",
        ),
        (Layout::new(vec![node("a", 0.0)], vec![]), "cells"),
        (
            Layout::new(vec![node("a", 0.0)], vec![cell(1.0, 1.0, vec![0])]),
            "cells",
        ),
        (
            Layout::new(
                vec![node("a", 0.0)],
                vec![cell(0.0, 2.0, vec![0]), cell(1.0, 3.0, vec![0])],
            ),
            "cells",
        ),
        (
            Layout::new(vec![node("a", 0.0)], vec![cell(0.0, 1.0, vec![])]),
            "cells.nodes",
        ),
        (
            Layout::new(vec![node("a", 0.0)], vec![cell(0.0, 1.0, vec![1])]),
            "cells.nodes",
        ),
        (Layout::grid(4.0, 5.0, 2.0), "cell_side_m"),
        (Layout::grid(4.0, 6.0, 0.0), "cell_side_m"),
        (Layout::grid(4.0, f64::INFINITY, 2.0), "cell_side_m"),
    ];
    for (i, (result, field)) in cases.into_iter().enumerate() {
        assert_eq!(invalid_name(result.unwrap_err()), field, "case {i}");
    }
    // touching cells are fine
    assert!(Layout::new(
        vec![node("a", 0.0)],
        vec![cell(0.0, 1.0, vec![0]), cell(1.0, 2.0, vec![0])]
    )
    .is_ok());
}

#[test]
fn predictions_are_accepted_only_when_most_nodes_coincide() {
    let bed = bed();
    let scheduler = TaskScheduler::new(3, 0.3).unwrap();
    // (0.9, 0.5) in cell 0: (0,0) 1.03 m, (2,0) 1.21 m, (0,2) 1.75 m, (2,2) 1.86 m
    let current = scheduler.initial(&bed, [0.9, 0.5]).unwrap();
    assert_eq!(current, vec![0, 1, 3]);
    // small move: the same nodes, accepted, unchanged
    let d = scheduler.decide(&bed, &current, [0.95, 0.5]).unwrap();
    assert_eq!(
        (d.accepted, d.changed, d.task_nodes.clone()),
        (true, false, vec![0, 1, 3])
    );
    // crossing x = 1: (2,0) 1.03 m, (0,0) 1.21 m, (2,2) 1.75 m; two of three coincide
    let d = scheduler.decide(&bed, &current, [1.1, 0.5]).unwrap();
    assert_eq!((d.accepted, d.changed), (true, true));
    assert_eq!(
        (d.proposal.clone(), d.task_nodes.clone()),
        (vec![1, 0, 4], vec![1, 0, 4])
    );
    // a prediction two cells away shares no node: rejected, the current nodes measure again,
    // nearest to the prediction (1, 5) first: (2,2) 3.16 m, then (0,0) and (2,0) at 5.10 m
    let d = scheduler.decide(&bed, &[1, 0, 4], [1.0, 5.0]).unwrap();
    assert_eq!(d.cell, 4);
    assert_eq!((d.accepted, d.changed), (false, false));
    assert_eq!(d.proposal, vec![6, 7, 9]);
    assert_eq!(d.task_nodes, vec![1, 0, 4]);
    assert_eq!(d.firing_nodes, vec![4, 0, 1]);
    // one in common, one new out of two: a tie is not a majority
    let two = TaskScheduler::new(2, 0.3).unwrap();
    let d = two.decide(&bed, &[0, 1], [1.05, 1.0]).unwrap();
    assert_eq!((d.proposal.clone(), d.accepted), (vec![1, 4], false));
}

#[test]
fn edge_monitors_fire_with_the_task_nodes_nearest_first() {
    let bed = bed();
    // two task nodes, 0.15 m from the corner (2, 4) of cell 2: (2,4) 0.21 m, (2,2) 1.856 m and
    // (0,4) 1.856 m (tie: lower index first)
    let scheduler = TaskScheduler::new(2, 0.3).unwrap();
    let p = [1.85, 3.85];
    let current = scheduler.initial(&bed, p).unwrap();
    assert_eq!(current, vec![7, 4]);
    let d = scheduler.decide(&bed, &current, p).unwrap();
    // cells 3 (nodes 4, 7), 4 (nodes 6, 7) and 5 (node 7) are within the margin: node 6 is new
    assert_eq!(d.monitors, vec![6]);
    assert_eq!(d.firing_nodes, vec![7, 4, 6]);
    // with three task nodes the shared border nodes are task nodes already
    let three = TaskScheduler::new(3, 0.3).unwrap();
    let d = three.decide(&bed, &[7, 4, 6], p).unwrap();
    assert!(d.monitors.is_empty());
    assert_eq!(d.firing_nodes, vec![7, 4, 6]);
    // a rejected prediction keeps the old nodes but is monitored around the prediction
    let d = scheduler.decide(&bed, &[0, 1], [1.9, 1.0]).unwrap();
    assert!(!d.accepted);
    assert_eq!(d.monitors, vec![4]);
}

#[test]
fn plan_updates_every_track_or_none() {
    let bed = bed();
    let scheduler = TaskScheduler::new(3, 0.3).unwrap();
    let mut current = vec![vec![0, 1, 3], vec![6, 7, 9]];
    let decisions = scheduler.plan(&bed, &mut current, &[[1.1, 0.5], [1.0, 5.0]]).unwrap();
    assert_eq!(decisions.len(), 2);
    assert_eq!(current, vec![vec![1, 0, 4], vec![6, 7, 9]]);
    // a NaN prediction is an error naming the position, and nothing changes
    let err = scheduler
        .plan(&bed, &mut current, &[[0.9, 0.5], [f64::NAN, 1.0]])
        .unwrap_err();
    assert_eq!(invalid_name(err), "position_m");
    assert_eq!(current, vec![vec![1, 0, 4], vec![6, 7, 9]]);
    let err = scheduler.plan(&bed, &mut current, &[[0.9, 0.5]]).unwrap_err();
    assert_eq!(invalid_name(err), "predicted_m");
    assert_eq!(invalid_name(TaskScheduler::new(0, 0.3).unwrap_err()), "task_nodes");
    assert_eq!(invalid_name(TaskScheduler::new(3, -0.1).unwrap_err()), "edge_margin_m");
}

#[test]
fn tokens_serialise_a_cell_and_a_node_and_the_channel() {
    let timing = TokenTiming::new(0.065, 0.010).unwrap();
    let request = |node, cell| FiringRequest { node, cell };
    // three firings in cell 0; cell 5 in parallel, but node 4 also fires for cell 0
    let requests = [
        request(0, 0),
        request(4, 0),
        request(1, 0),
        request(4, 5),
        request(8, 5),
    ];
    let cycle = timing.cycle(10.0, &requests).unwrap();
    assert!(close(cycle.broadcast_end_s, 10.01));
    // slots: 0 → requests 0 and 3; 1 → 1 and 4; 2 → 2
    let order: Vec<(usize, usize)> = cycle.firings.iter().map(|f| (f.request, f.slot)).collect();
    assert_eq!(order, vec![(0, 0), (3, 0), (1, 1), (4, 1), (2, 2)]);
    // firing at 10.01 + slot · 0.065; reports one at a time, each when its ranging is over
    let expected = [
        (10.01, 10.085),
        (10.01, 10.095),
        (10.075, 10.15),
        (10.075, 10.16),
        (10.14, 10.215),
    ];
    for (f, (time_s, arrival_s)) in cycle.firings.iter().zip(expected) {
        assert!(close(f.time_s, time_s) && close(f.arrival_s, arrival_s), "{f:?}");
        assert_eq!((f.node, f.cell), (requests[f.request].node, requests[f.request].cell));
    }
    assert!(close(cycle.end_s, 10.215));
    // no firings: the cycle is the broadcast
    let empty = timing.cycle(3.0, &[]).unwrap();
    assert!(empty.firings.is_empty() && close(empty.end_s, 3.01));
    assert_eq!(invalid_name(TokenTiming::new(0.0, 0.01).unwrap_err()), "ranging_slot_s");
    assert_eq!(
        invalid_name(TokenTiming::new(0.065, f64::NAN).unwrap_err()),
        "comm_slot_s"
    );
    assert_eq!(invalid_name(timing.cycle(f64::INFINITY, &[]).unwrap_err()), "start_s");
}

fn model() -> EnergyModel {
    EnergyModel {
        power: PowerModel::cc2420_srf08(),
        sonar_ping_s: 0.0002,
        echo_window_s: 0.0175,
        all_on_sonars_per_node: 6,
    }
}

#[test]
fn energy_counts_broadcast_awake_time_reports_and_sonars() {
    let timing = TokenTiming::new(0.065, 0.010).unwrap();
    // node 0 fires twice (2 sonars, then 1), node 1 once; node 2 only hears the broadcast
    let requests = [
        FiringRequest { node: 0, cell: 0 },
        FiringRequest { node: 1, cell: 0 },
        FiringRequest { node: 0, cell: 0 },
    ];
    let cycle = timing.cycle(0.0, &requests).unwrap();
    // firings at 0.010, 0.075, 0.140; reports 0.075–0.085, 0.140–0.150, 0.205–0.215
    assert!(close(cycle.end_s, 0.215));
    let mut ledger = EnergyLedger::new(3, model()).unwrap();
    ledger.record_cycle(&cycle, &[2, 1, 1]).unwrap();
    let s = ledger.scheduled();
    let on = 0.0002 + 0.0175;
    // node 0: broadcast 0.010 + awake 0.010–0.215 minus 2 reports of 0.010
    assert!(close(s[0].radio_rx_s, 0.010 + 0.205 - 0.020) && close(s[0].radio_tx_s, 0.020));
    assert!(close(s[0].sonar_on_s, 3.0 * on));
    assert_eq!((s[0].awake_cycles, s[0].reports, s[0].sonars_fired), (1, 2, 3));
    // node 1: broadcast + awake 0.010–0.150 minus its report
    assert!(close(s[1].radio_rx_s, 0.010 + 0.140 - 0.010) && close(s[1].radio_tx_s, 0.010));
    assert!(close(s[1].sonar_on_s, on));
    // node 2: the broadcast only
    assert_eq!(
        s[2],
        NodeUsage {
            radio_rx_s: 0.010,
            ..NodeUsage::default()
        }
    );
    // all on: 0.215 s awake each, one report, six sonars
    for a in ledger.all_on() {
        assert!(close(a.radio_rx_s, 0.205) && close(a.radio_tx_s, 0.010));
        assert!(close(a.sonar_on_s, 6.0 * on));
        assert_eq!((a.awake_cycles, a.reports, a.sonars_fired), (1, 1, 6));
    }
    // joules: P_rx = 56.4 mW, P_tx = 52.2 mW, P_sonar = 75 mW
    let p = PowerModel::cc2420_srf08();
    assert!(close(s[0].radio_j(&p), 0.195 * 0.0564 + 0.020 * 0.0522));
    assert!(close(s[0].sonar_j(&p), 3.0 * on * 0.075));
    let totals = ledger.totals();
    // radio on-time: scheduled 0.215 + 0.150 + 0.010 = 0.375 s against 3 × 0.215 s
    assert!(close(totals.scheduled.radio_on_s(), 0.375));
    assert!(close(totals.radio_time_saving_percent(), 100.0 * (1.0 - 0.375 / 0.645)));
    assert!(close(totals.sonar_time_saving_percent(), 100.0 * (1.0 - 4.0 / 18.0)));
    let scheduled_j = 0.345 * 0.0564 + 0.030 * 0.0522 + 4.0 * on * 0.075;
    let all_on_j = 3.0 * (0.205 * 0.0564 + 0.010 * 0.0522 + 6.0 * on * 0.075);
    assert!((totals.energy_saving_percent() - 100.0 * (1.0 - scheduled_j / all_on_j)).abs() < 1e-9);
    assert_eq!((ledger.cycles(), close(ledger.duration_s(), 0.215)), (1, true));
}

#[test]
fn ledgers_merge_and_reject_bad_input() {
    let timing = TokenTiming::new(0.065, 0.010).unwrap();
    let cycle = timing.cycle(0.0, &[FiringRequest { node: 1, cell: 0 }]).unwrap();
    let mut a = EnergyLedger::new(2, model()).unwrap();
    a.record_cycle(&cycle, &[1]).unwrap();
    let mut b = a.clone();
    b.merge(&a).unwrap();
    assert_eq!(b.cycles(), 2);
    assert!(close(b.scheduled()[1].radio_tx_s, 2.0 * a.scheduled()[1].radio_tx_s));
    assert!(close(b.all_on()[0].sonar_on_s, 2.0 * a.all_on()[0].sonar_on_s));
    // errors leave the ledger as it was
    let before = a.clone();
    assert_eq!(invalid_name(a.record_cycle(&cycle, &[]).unwrap_err()), "sonars_fired");
    let far = timing.cycle(0.0, &[FiringRequest { node: 7, cell: 0 }]).unwrap();
    assert_eq!(invalid_name(a.record_cycle(&far, &[1]).unwrap_err()), "node");
    assert_eq!(a, before);
    let other = EnergyLedger::new(3, model()).unwrap();
    assert_eq!(invalid_name(a.merge(&other).unwrap_err()), "other");
    let mut bad = model();
    bad.power.sonar_w = -1.0;
    assert_eq!(invalid_name(EnergyLedger::new(2, bad).unwrap_err()), "sonar_w");
    bad = model();
    bad.all_on_sonars_per_node = 0;
    assert_eq!(invalid_name(bad.validate().unwrap_err()), "all_on_sonars_per_node");
}

#[test]
fn a_neighbour_sharing_no_node_takes_over_but_a_jump_does_not() {
    // three 2 m cells in a row, each with its own two nodes
    let nodes = (0..6)
        .map(|i| Node {
            id: format!("n{i}"),
            position_m: [0.2 + 2.0 * (i / 2) as f64 + 1.6 * (i % 2) as f64, 1.0],
        })
        .collect();
    let cells = (0..3)
        .map(|c| Cell {
            min_m: [2.0 * c as f64, 0.0],
            max_m: [2.0 * c as f64 + 2.0, 2.0],
            nodes: vec![2 * c, 2 * c + 1],
        })
        .collect();
    let row = Layout::new(nodes, cells).unwrap();
    // seed 003's rule as printed: the track keeps its old cell's nodes
    let paper = TaskScheduler::new(2, 0.0).unwrap();
    let d = paper.decide(&row, &[0, 1], [2.5, 1.0]).unwrap();
    assert_eq!((d.accepted, d.task_nodes), (false, vec![0, 1]));
    let scheduler = paper.with_neighbour_handover();
    // into the neighbouring cell: the old nodes cannot measure there, the proposal is taken
    let d = scheduler.decide(&row, &[0, 1], [2.5, 1.0]).unwrap();
    assert_eq!(
        (d.cell, d.accepted, d.changed, d.task_nodes),
        (1, true, true, vec![2, 3])
    );
    // a jump two cells away is still refused (seed 003's rule)
    let d = scheduler.decide(&row, &[0, 1], [4.5, 1.0]).unwrap();
    assert_eq!((d.cell, d.accepted, d.task_nodes), (2, false, vec![0, 1]));
}
