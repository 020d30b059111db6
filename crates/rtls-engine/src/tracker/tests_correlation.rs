//! Error correlation times per measurement class: fixes made of RSSI (path-loss epoch fixes,
//! fingerprint scans) take `adaptive_noise.rssi_correlation_s`, single RSSI readings
//! `rssi_reading_correlation_s`, everything else `correlation_s`.

use super::tests::{range_records, run, site, standing_rssi_records};
use super::*;

/// RSSI readings round robin over the four anchors every 50 ms (2 dB shadowing) of a tag
/// standing at (8, 6), for 20 s.
fn rssi_records() -> Vec<Record> {
    standing_rssi_records(5, 2.0, 0..400)
}

/// The last update's position covariance trace, m², and every update's position.
fn tracked(
    pipeline: &str,
    filter: &str,
    extra: &str,
    rssi_correlation_s: f64,
    records: Vec<Record>,
) -> (f64, Vec<[f64; 3]>) {
    let mut site = site(pipeline, filter, extra);
    site.tracker.adaptive_noise.rssi_correlation_s = rssi_correlation_s;
    let out = run(&mut Tracker::new(&site).unwrap(), records);
    let last = out.updates.iter().rev().find(|u| !u.predicted).unwrap();
    let [xx, _, yy] = super::tests::horizontal_covariance_m2(last);
    let trace = xx + yy;
    (trace, out.updates.iter().map(|u| u.position_m).collect())
}

#[test]
fn rssi_fixes_take_their_own_correlation_time_and_nothing_else_does() {
    // path-loss epoch fixes every 0.2 s: with τ = 2 s each variance is inflated by
    // 2τ/Δt = 20, so the track's covariance is several times larger than with τ = 0
    let epochs = "epoch_s = 0.19";
    let (independent, _) = tracked("fix-then-filter", "kf", epochs, 0.0, rssi_records());
    let (correlated, _) = tracked("fix-then-filter", "kf", epochs, 2.0, rssi_records());
    assert!(correlated > 3.0 * independent, "{correlated} vs {independent} m²");
    // single RSSI readings (tightly coupled, see below) and UWB epoch fixes do not take it
    for (pipeline, filter, records) in [
        ("tightly-coupled", "ekf", rssi_records()),
        ("fix-then-filter", "kf", range_records(10.0, 7, |_| [8.0, 6.0])),
    ] {
        let a = tracked(pipeline, filter, "", 0.0, records.clone());
        let b = tracked(pipeline, filter, "", 2.0, records);
        assert_eq!(a, b, "{pipeline}");
    }
}

#[test]
fn single_rssi_readings_take_their_own_correlation_time() {
    // each anchor is read every 0.2 s: with τ = 1 s each variance is inflated by 2τ/Δt = 10
    let covariance_trace = |tau_s: f64| {
        let mut site = site("tightly-coupled", "ekf", "");
        site.tracker.adaptive_noise.rssi_reading_correlation_s = tau_s;
        let out = run(&mut Tracker::new(&site).unwrap(), rssi_records());
        let last = out.updates.iter().rev().find(|u| !u.predicted).unwrap();
        let [xx, _, yy] = super::tests::horizontal_covariance_m2(last);
        xx + yy
    };
    let (independent, correlated) = (covariance_trace(0.0), covariance_trace(1.0));
    assert!(correlated > 3.0 * independent, "{correlated} vs {independent} m²");
}
