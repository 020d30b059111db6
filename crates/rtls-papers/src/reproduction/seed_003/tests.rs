//! Runs of the seed 003 simulation: determinism and token timing, every method on a lone
//! robot, clocks and energy bookkeeping, bad configurations.

use super::*;
use rtls_sim::scenarios::seed_003::planar_route;

fn two_robots_meeting() -> Seed003Config {
    // robot 0 crosses cell 0 → 1; robot 1 waits in cell 1 near the path, then leaves
    let a = planar_route(&[[0.6, 0.8], [3.4, 0.8], [3.4, 1.6]], 0.5, 0.0, &[]).unwrap();
    let b = planar_route(&[[3.0, 1.4], [3.0, 3.4]], 0.5, 4.0, &[]).unwrap();
    Seed003Config::paper(vec![a, b], 7.0).unwrap()
}

#[test]
fn a_run_is_reproducible_and_its_timing_follows_the_tokens() {
    let config = two_robots_meeting();
    let run = run_seed_003(&config, Method::PaperEkf, 11).unwrap();
    assert_eq!(run, run_seed_003(&config, Method::PaperEkf, 11).unwrap());
    assert!(run.counters.cycles > 15, "{:?}", run.counters);
    // firings in time order, reports after their ranging slot, cycles back to back
    assert!(run.firings.windows(2).all(|w| w[0].time_s <= w[1].time_s));
    assert!(run.firings.iter().all(|f| f.arrival_s >= f.time_s + 0.075 - 1e-12));
    assert!(run.cycle_starts_s.windows(2).all(|w| w[1] > w[0] + 0.2));
    // bounds are positive and finite, one per robot and epoch
    for e in &run.epochs {
        assert_eq!(
            (e.bound_m2.len(), e.model_bound_m2.len(), e.estimate_m.len()),
            (2, 2, 2)
        );
        assert!(e
            .bound_m2
            .iter()
            .chain(&e.model_bound_m2)
            .all(|b| b.is_finite() && *b > 0.0));
    }
    let c = run.counters;
    assert_eq!(c.schedule_decisions, 2 * c.cycles);
    assert!(c.awake_node_cycles <= 12 * c.cycles && c.awake_node_cycles >= 3 * c.cycles);
}

#[test]
fn every_method_tracks_a_lone_robot_within_centimetres() {
    let route = planar_route(&[[0.6, 0.8], [3.4, 0.8], [3.4, 3.2]], 0.5, 0.0, &[]).unwrap();
    let config = Seed003Config::paper(vec![route], 10.0).unwrap();
    for method in Method::ALL {
        let run = run_seed_003(&config, method, 5).unwrap();
        let errors: Vec<f64> = run
            .epochs
            .iter()
            .skip(5)
            .map(|e| (e.estimate_m[0][0] - e.truth_m[0][0]).hypot(e.estimate_m[0][1] - e.truth_m[0][1]))
            .collect();
        let rmse = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
        if rmse >= 0.15 {
            for (e, f) in run.epochs.iter().zip(0..) {
                eprintln!(
                    "{f} t={:.2} truth={:?} est={:?}",
                    e.time_s, e.truth_m[0], e.estimate_m[0]
                );
            }
            for f in run.firings.iter().take(40) {
                eprintln!("{f:?}");
            }
        }
        assert!(rmse < 0.15, "{method:?}: {rmse}");
        assert_eq!(run.counters.wrong_associations, 0, "{method:?}");
    }
}

#[test]
fn clocks_stamp_the_ranges_and_the_ledger_books_every_cycle() {
    let mut config = two_robots_meeting();
    // exact clocks: stamps are the firing times
    config.clock.drift_std_ppm = 0.0;
    config.clock.sync_jitter_std_s = 0.0;
    let exact = run_seed_003(&config, Method::AssociatedEkf, 3).unwrap();
    assert!(exact.firings.iter().all(|f| f.stamp_s == f.time_s));
    assert_eq!(exact.clock.stamp_error_max_s, 0.0);
    // 1 % drift, re-synced every cycle: the error is at most the drift over one cycle
    config.clock.drift_std_ppm = 10_000.0;
    let synced = run_seed_003(&config, Method::AssociatedEkf, 3).unwrap();
    let longest_cycle_s = synced
        .cycle_starts_s
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(0.0, f64::max);
    // |δ| < 5 σ = 5 %: at most 5 % of the time since the last broadcast
    assert!(
        synced.clock.stamp_error_max_s < 0.05 * longest_cycle_s,
        "{:?}",
        synced.clock
    );
    assert!(synced.clock.stamp_error_max_s > 0.0);
    // free-running after the first sync: the error grows with time, far beyond one cycle
    config.clock.resync_every_cycle = false;
    let free = run_seed_003(&config, Method::AssociatedEkf, 3).unwrap();
    assert!(
        free.clock.stamp_error_max_s > 5.0 * synced.clock.stamp_error_max_s,
        "{:?}",
        free.clock
    );
    let late: Vec<f64> = free
        .firings
        .iter()
        .filter(|f| f.node == free.firings[0].node)
        .map(|f| (f.stamp_s - f.time_s).abs())
        .collect();
    assert!(late.last().unwrap() > late.first().unwrap());
    // the range error is the drift times the range: < 5 % of the 3 m window
    assert!(free.clock.range_bias_max_m > 0.0 && free.clock.range_bias_max_m < 0.15);
    // the engine's ledger saw every cycle and the same wake-ups the run counted
    for run in [&exact, &synced, &free] {
        assert_eq!(run.energy.cycles(), run.counters.cycles);
        let awake: usize = run.energy.scheduled().iter().map(|n| n.awake_cycles).sum();
        assert_eq!(awake, run.counters.awake_node_cycles);
        let reports: usize = run.energy.scheduled().iter().map(|n| n.reports).sum();
        assert_eq!(reports, run.counters.firings);
        assert!((run.energy.duration_s() - run.end_s).abs() < 1e-9);
    }
}

#[test]
fn bad_configurations_are_errors() {
    let config = two_robots_meeting();
    let mut bad = config.clone();
    bad.scheduling.task_nodes = 5;
    assert!(run_seed_003(&bad, Method::LeastSquares, 0).is_err());
    let mut bad = config.clone();
    bad.duration_s = 100.0;
    assert!(matches!(
        bad.validate(),
        Err(SimError::InvalidParameter { name: "duration_s", .. })
    ));
    let mut bad = config.clone();
    bad.clock.drift_std_ppm = -1.0;
    assert!(matches!(
        run_seed_003(&bad, Method::PaperEkf, 0),
        Err(SimError::InvalidParameter {
            name: "drift_std_ppm",
            ..
        })
    ));
    let mut bad = config.clone();
    bad.energy.all_on_sonars_per_node = 0;
    assert!(matches!(
        bad.validate(),
        Err(SimError::InvalidParameter {
            name: "all_on_sonars_per_node",
            ..
        })
    ));
    let mut bad = config.clone();
    bad.timing.comm_slot_s = 0.0;
    assert!(matches!(
        bad.validate(),
        Err(SimError::InvalidParameter {
            name: "comm_slot_s",
            ..
        })
    ));
    let mut bad = config;
    bad.robots.clear();
    assert!(bad.validate().is_err());
}
