//! Solving a tag's buffered anchor readings into fixes on the tracked axes: the epoch fix of
//! fix-then-filter, a tightly coupled track's start and its check fixes ([`super::check`]).

use nalgebra::SVector;
use rtls_estimation::Gaussian;

use super::anchors::AnchorReading;
use super::solve::{solve_epoch, EpochFix};
use super::track::{dimensions, Shared, Track};

/// A fix as `(position, row-major covariance, method)` on the tracked axes.
pub(super) type FlatFix = (Vec<f64>, Vec<f64>, &'static str);

/// Solves readings into fixes `(position, row-major covariance, method)` on the tracked axes.
pub(super) fn solve<const N: usize>(
    shared: &Shared,
    readings: &[AnchorReading],
    guess: Option<&Gaussian<N>>,
) -> std::result::Result<Vec<FlatFix>, String> {
    fn flatten<const D: usize>(fix: &EpochFix<D>) -> FlatFix {
        (
            fix.fix.position.iter().copied().collect(),
            fix.fix.covariance.transpose().iter().copied().collect(),
            fix.method,
        )
    }
    let tag_height_m = shared.tag_height_m;
    if dimensions::<N>() == 3 {
        // without a prediction, anchors at one height leave the fix two mirror images across
        // their plane: start below it. The start only picks the side, it is no prior: with
        // it the solver takes three anchors for a 3-D fix, so it is given only when the
        // readings hold the four a fix without a prediction needs (seed 000's mine walk,
        // `rtls repro mekf`: 3-D RMSE 6.50 m when three faint readers started a track, 4.69 m
        // now)
        let guess = guess
            .map(|g| SVector::<f64, 3>::new(g.mean()[0], g.mean()[2], g.mean()[4]))
            .or_else(|| {
                let mut points: Vec<[f64; 3]> = readings.iter().map(|r| shared.anchors.position(r)).collect();
                points.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
                points.dedup();
                if points.len() < 4 {
                    return None;
                }
                super::anchors::start_below_plane(&points).map(SVector::from)
            });
        Ok(solve_epoch::<3>(&shared.anchors, readings, tag_height_m, guess)?
            .iter()
            .map(flatten)
            .collect())
    } else {
        let guess = guess.map(|g| SVector::<f64, 2>::new(g.mean()[0], g.mean()[2]));
        Ok(solve_epoch::<2>(&shared.anchors, readings, tag_height_m, guess)?
            .iter()
            .map(flatten)
            .collect())
    }
}

/// Whether a fix's plan standard deviation `√(σₓ² + σ_y²)` exceeds the working anchors' spread
/// ([`Anchors::working_plan_spread_m`](super::anchors::Anchors::working_plan_spread_m)): it
/// says no more than "among the anchors" (three faint RSSI readings: σ of 150 m), and an EKF
/// linearised there overshoots by tens of metres on its first readings.
pub(super) fn uninformative<const N: usize>(shared: &Shared, (_, covariance, _): &FlatFix) -> bool {
    let spread_m = shared.anchors.working_plan_spread_m();
    // σₓ² + σ_y² from the row-major D × D covariance
    let plan_variance_m2 = covariance[0] + covariance[dimensions::<N>() + 1];
    spread_m > 0.0 && (plan_variance_m2.is_nan() || plan_variance_m2.sqrt() > spread_m)
}

/// A range with the track's learnt offset of its anchor removed (`[tracker.range_bias]`):
/// `r − b̂`, variance `σ² + P_b`. Other readings as they are.
pub(super) fn corrected_range<const N: usize>(
    shared: &Shared,
    track: &Track<N>,
    reading: AnchorReading,
    time_s: f64,
) -> AnchorReading {
    match (&shared.range_bias, reading) {
        (
            Some(model),
            AnchorReading::Range {
                anchor,
                position_m,
                range_m,
                variance_m2,
            },
        ) => {
            let (offset_m, offset_variance_m2) = track.range_bias.offset(model, anchor, time_s);
            AnchorReading::Range {
                anchor,
                position_m,
                range_m: range_m - offset_m,
                variance_m2: variance_m2 + offset_variance_m2,
            }
        }
        (_, other) => other,
    }
}
