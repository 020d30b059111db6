//! Fix-then-filter: one position fix per epoch from a tag's anchor readings (seed 000's
//! positioning stage), with the covariance the filter weighs it by.
//!
//! - Ranges and RSSI: RSSI becomes a range through the reader's log-distance law (the median
//!   range `d = d₀·10^((ρ₀ − ρ)/(10 n))`, delta-method variance `σ_d = σ_X / |dρ/dd|`); readings
//!   of one anchor are averaged with inverse-variance weights; in 2-D a slant range `r` to an
//!   anchor `Δz` above the tag becomes the horizontal range `h = √(r² − Δz²)` with
//!   `σ_h = σ_r · r/h`, floored where `h → 0`
//!   ([`rtls_positioning::multilateration::horizontal_range`]); anchors that share one
//!   position on the tracked axes (in 2-D: one `(x, y)` at different heights) are merged; then
//!   [`rtls_positioning::multilateration::multilaterate`]: weighted Gauss–Newton /
//!   Levenberg–Marquardt from the track's position when there is one (so `D` distinct anchor
//!   positions suffice; `D + 1` otherwise, from the linear fix), again from the weighted
//!   centroid, and a weighted-centroid fix with a large covariance as the last resort. The
//!   method is named on every fix ([`EpochFix::method`]).
//! - TDOA: the largest group of readings sharing one reference anchor (`D + 1` stations). In
//!   2-D the range differences are differences of slant ranges to anchors at their own heights
//!   from a tag at `tag_height_m`, solved exactly by
//!   [`rtls_positioning::tdoa::planar_at_height`]; in 3-D Chan's closed form refined by Taylor
//!   iterations.
//! - Every fix is checked before use ([`rtls_positioning::Fix::check_plausible`]): finite,
//!   covariance symmetric positive definite, and within a few times the anchors' extent (plus
//!   the measured ranges) of their centroid; otherwise the epoch is refused with the reason.
//!   Negative ranges (Wi-Fi FTM / RTT close to an anchor, or a range shorter than the anchor's
//!   bias) are noisy measurements, not errors.

use nalgebra::{DMatrix, SVector};
use rtls_positioning::multilateration::{horizontal_range, multilaterate, GaussNewtonOptions};
use rtls_positioning::pathloss::{DistanceEstimate, LogDistance, PathLossModel};
use rtls_positioning::tdoa::{chan_taylor, planar_at_height};
use rtls_positioning::{Fix, PositioningError};

use super::anchors::{AnchorReading, Anchors};

/// Gauss–Newton settings for epoch fixes: 200 iterations (the Levenberg–Marquardt iteration
/// also stops when the cost no longer falls), relative step 1e-6 (well below centimetre level
/// at site scale).
const OPTIONS: GaussNewtonOptions = GaussNewtonOptions {
    max_iterations: 200,
    relative_tolerance: 1e-6,
};

/// Anchors closer than this on the tracked axes count as one position in the reasons given
/// for an epoch without enough distinct anchors (m).
const CO_LOCATED_M: f64 = 1e-6;

/// One fix of an epoch and how it was made.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct EpochFix<const D: usize> {
    /// The checked fix (finite, covariance SPD, plausible).
    pub(crate) fix: Fix<D>,
    /// `gauss-newton`, `gauss-newton-from-centroid`, `weighted-centroid` (ranges) or `tdoa`.
    pub(crate) method: &'static str,
}

/// The anchor's coordinates on the tracked axes.
fn axes<const D: usize>(position_m: &[f64; 3]) -> [f64; D] {
    let mut out = [0.0; D];
    out.copy_from_slice(&position_m[..D]);
    out
}

/// The fixes of one epoch: at most one from ranges/RSSI and one from TDOA.
///
/// # Errors
/// The reason no fix could be made (too few distinct anchors, degenerate geometry, an
/// implausible fix, solver failure).
pub(crate) fn solve_epoch<const D: usize>(
    anchors: &Anchors,
    readings: &[AnchorReading],
    tag_height_m: f64,
    guess_m: Option<SVector<f64, D>>,
) -> Result<Vec<EpochFix<D>>, String> {
    let mut fixes = Vec::new();
    let mut reasons = Vec::new();
    let has_ranges = readings
        .iter()
        .any(|r| matches!(r, AnchorReading::Range { .. } | AnchorReading::Rssi { .. }));
    if has_ranges {
        match range_fix::<D>(anchors, readings, tag_height_m, guess_m) {
            Ok(fix) => fixes.push(fix),
            Err(reason) => reasons.push(reason),
        }
    }
    if readings.iter().any(|r| matches!(r, AnchorReading::Tdoa { .. })) {
        match tdoa_fix::<D>(anchors, readings, tag_height_m) {
            Ok(fix) => fixes.push(fix),
            Err(reason) => reasons.push(reason),
        }
    }
    if fixes.is_empty() {
        Err(reasons.join("; "))
    } else {
        Ok(fixes)
    }
}

/// Per anchor of the epoch: `(anchor, range m, variance m²)` on the tracked axes (in 2-D the
/// horizontal range with its propagated variance).
///
/// # Errors
/// A bad path-loss law or RSSI value, or a non-finite projection.
fn epoch_ranges<const D: usize>(
    anchors: &Anchors,
    readings: &[AnchorReading],
    tag_height_m: f64,
) -> Result<Vec<EpochRange>, String> {
    // per anchor position: Σ wᵢ rᵢ and Σ wᵢ with wᵢ = 1/σᵢ² (a moving anchor's ranges from
    // different places are different stations)
    let mut sums: Vec<EpochRange> = Vec::new();
    for reading in readings {
        let (anchor, position_m, range_m, variance_m2) = match *reading {
            AnchorReading::Range {
                anchor,
                position_m,
                range_m,
                variance_m2,
            } => (anchor, position_m, range_m, variance_m2),
            AnchorReading::Rssi {
                anchor, rssi_dbm, law, ..
            } => {
                let [p0, d0, n, sigma_db] = law;
                let law = LogDistance::new(p0, n, d0, sigma_db).map_err(|e| e.to_string())?;
                // d = μ⁻¹(ρ), σ_d = σ_X / |dμ/dd|
                let d = law
                    .estimate_distance_m(rssi_dbm, DistanceEstimate::Median)
                    .map_err(|e| e.to_string())?;
                let sigma = law.range_std_m(d).map_err(|e| e.to_string())?;
                (anchor, anchors.get(anchor).position_m, d, (sigma * sigma).max(1e-6))
            }
            AnchorReading::Tdoa { .. } => continue,
        };
        let weight = 1.0 / variance_m2;
        match sums
            .iter_mut()
            .find(|e| e.anchor == anchor && e.position_m == position_m)
        {
            Some(entry) => {
                entry.range_m += weight * range_m;
                entry.variance_m2 += weight;
            }
            None => sums.push(EpochRange {
                anchor,
                position_m,
                range_m: weight * range_m,
                variance_m2: weight,
            }),
        }
    }
    let mut out = Vec::with_capacity(sums.len());
    for sum in sums {
        // r̄ = Σ wᵢ rᵢ / Σ wᵢ, σ̄² = 1 / Σ wᵢ
        let (range_m, variance_m2) = (sum.range_m / sum.variance_m2, 1.0 / sum.variance_m2);
        if D == 2 {
            // h = √(r² − Δz²), σ_h = σ_r · r/h (floored at the anchor's foot)
            let dz = sum.position_m[2] - tag_height_m;
            let h = horizontal_range(range_m, variance_m2, dz).map_err(|e| {
                format!(
                    "range to anchor `{}` cannot be projected: {e}",
                    anchors.get(sum.anchor).id
                )
            })?;
            out.push(EpochRange {
                range_m: h.range_m,
                variance_m2: h.variance_m2,
                ..sum
            });
        } else {
            out.push(EpochRange {
                range_m,
                variance_m2,
                ..sum
            });
        }
    }
    Ok(out)
}

/// One station of an epoch's range fix: the anchor, its position (m), the combined range (m)
/// and its variance (m²). While summing, `range_m` holds `Σ wᵢ rᵢ` and `variance_m2` `Σ wᵢ`.
#[derive(Debug, Clone, Copy)]
struct EpochRange {
    anchor: usize,
    position_m: [f64; 3],
    range_m: f64,
    variance_m2: f64,
}

/// Weighted multilateration over the epoch's ranges and RSSI-derived ranges.
fn range_fix<const D: usize>(
    anchors: &Anchors,
    readings: &[AnchorReading],
    tag_height_m: f64,
    guess_m: Option<SVector<f64, D>>,
) -> Result<EpochFix<D>, String> {
    let per_anchor = epoch_ranges::<D>(anchors, readings, tag_height_m)?;
    let indices: Vec<(usize, [f64; 3])> = per_anchor.iter().map(|e| (e.anchor, e.position_m)).collect();
    let positions: Vec<[f64; D]> = per_anchor.iter().map(|e| axes::<D>(&e.position_m)).collect();
    let ranges: Vec<f64> = per_anchor.iter().map(|e| e.range_m).collect();
    let variances: Vec<f64> = per_anchor.iter().map(|e| e.variance_m2).collect();
    match multilaterate::<D>(&positions, &ranges, &variances, guess_m, &OPTIONS) {
        Ok(fix) => Ok(EpochFix {
            fix: fix.fix,
            method: fix.method.name(),
        }),
        Err(PositioningError::Underdetermined { anchors: distinct, .. }) => Err(format!(
            "{distinct} distinct anchor position(s) in the epoch{}{}: a {D}-D fix needs {} (or {D} once the \
             track exists)",
            co_located_note::<D>(anchors, &indices),
            // (before the `: `, so that `rtls track`'s summary of reasons shows it)
            if distinct <= 1 {
                " (readers that report one at a time need a `tracker.epoch_s` that spans a round, or none \
                 for automatic epochs, which refuse only a tag's first lone reading)"
            } else {
                ""
            },
            D + 1
        )),
        Err(e) => Err(format!(
            "multilateration failed: {e}{}",
            co_located_note::<D>(anchors, &indices)
        )),
    }
}

/// ` (anchors `A` and `B` share one position …, counted once)` for every pair of the epoch's
/// anchors at one position on the tracked axes, or an empty string.
fn co_located_note<const D: usize>(anchors: &Anchors, stations: &[(usize, [f64; 3])]) -> String {
    let mut pairs = Vec::new();
    for (k, &(first, first_m)) in stations.iter().enumerate() {
        for &(second, second_m) in &stations[k + 1..] {
            let (a, b) = (anchors.get(first), anchors.get(second));
            let apart_m = axes::<D>(&first_m)
                .iter()
                .zip(axes::<D>(&second_m))
                .map(|(x, y)| (x - y).powi(2))
                .sum::<f64>()
                .sqrt();
            if apart_m <= CO_LOCATED_M {
                pairs.push(format!("`{}` and `{}`", a.id, b.id));
            }
        }
    }
    if pairs.is_empty() {
        String::new()
    } else {
        let plane = if D == 2 { " in the plane (x, y)" } else { "" };
        format!(
            " (anchors {} share one position{plane} and count once)",
            pairs.join(", ")
        )
    }
}

/// `(anchor, range difference m, variance m²)` of one TDOA reading.
type TdoaEntry = (usize, f64, f64);

/// The TDOA fix over the largest group of TDOA readings that share a reference anchor.
fn tdoa_fix<const D: usize>(
    anchors: &Anchors,
    readings: &[AnchorReading],
    tag_height_m: f64,
) -> Result<EpochFix<D>, String> {
    // group by reference; keep the group with the most distinct anchors
    let mut groups: Vec<(usize, Vec<TdoaEntry>)> = Vec::new();
    for reading in readings {
        if let AnchorReading::Tdoa {
            anchor,
            reference,
            range_difference_m,
            variance_m2,
        } = *reading
        {
            let slot = match groups.iter().position(|(r, _)| *r == reference) {
                Some(i) => i,
                None => {
                    groups.push((reference, Vec::new()));
                    groups.len() - 1
                }
            };
            let group = &mut groups[slot].1;
            match group.iter_mut().find(|(a, _, _)| *a == anchor) {
                // repeated pair: keep the latest
                Some(entry) => *entry = (anchor, range_difference_m, variance_m2),
                None => group.push((anchor, range_difference_m, variance_m2)),
            }
        }
    }
    let (reference, group) = groups
        .into_iter()
        .max_by_key(|(_, g)| g.len())
        .ok_or_else(|| "no TDOA readings".to_string())?;
    if group.len() < D {
        return Err(format!(
            "{} station(s) share reference `{}`: a {D}-D TDOA fix needs {}",
            group.len() + 1,
            anchors.get(reference).id,
            D + 1
        ));
    }
    // stations: the reference first (index 0), then the others in order
    let indices: Vec<usize> = core::iter::once(reference)
        .chain(group.iter().map(|(a, _, _)| *a))
        .collect();
    let differences: Vec<f64> = group.iter().map(|(_, r, _)| *r).collect();
    let covariance = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
        group.len(),
        group.iter().map(|(_, _, v)| *v),
    ));
    let planar: Vec<[f64; D]> = indices.iter().map(|&a| axes::<D>(&anchors.get(a).position_m)).collect();
    let fix = if D == 2 {
        // slant-range differences from a tag at tag_height_m to anchors at their heights
        let stations: Vec<[f64; 3]> = indices.iter().map(|&a| anchors.get(a).position_m).collect();
        planar_at_height(&stations, 0, &differences, &covariance, tag_height_m).map(|f| {
            let mut fix = Fix::<D> {
                position: SVector::zeros(),
                covariance: nalgebra::SMatrix::zeros(),
            };
            fix.position.copy_from_slice(f.position.as_slice());
            fix.covariance.copy_from_slice(f.covariance.as_slice());
            fix
        })
    } else {
        chan_taylor::<D>(&planar, 0, &differences, &covariance).map(|fix| inflated(fix, &planar, &group))
    }
    .map_err(|e| {
        let stations: Vec<(usize, [f64; 3])> = indices.iter().map(|&a| (a, anchors.get(a).position_m)).collect();
        format!("TDOA solution failed: {e}{}", co_located_note::<D>(anchors, &stations))
    })?;
    fix.check_plausible(&planar, 0.0)
        .map_err(|e| format!("TDOA fix refused: {e}"))?;
    Ok(EpochFix { fix, method: "tdoa" })
}

/// A Chan + Taylor fix with its covariance scaled by the a-posteriori variance factor (as
/// `multilaterate` and `planar_at_height` do):
/// ```text
/// χ² = Σ_i (r_i − (‖p − s_i‖ − ‖p − s_0‖))² / σ_i²    (diagonal Q; station 0 the reference)
/// σ̂₀² = max(1, χ² / (m − D)) when m > D,  P ← σ̂₀² P
/// ```
/// (Teunissen, *Adjustment Theory*, 2000, §4.4.)
fn inflated<const D: usize>(mut fix: Fix<D>, stations: &[[f64; D]], group: &[TdoaEntry]) -> Fix<D> {
    let distance = |s: &[f64; D]| (fix.position - SVector::<f64, D>::from(*s)).norm();
    let reference_m = distance(&stations[0]);
    // χ² = Σ e_i² / σ_i²
    let chi_square: f64 = group
        .iter()
        .zip(&stations[1..])
        .map(|((_, r, v), s)| (r - (distance(s) - reference_m)).powi(2) / v)
        .sum();
    let dof = group.len().saturating_sub(D);
    if dof > 0 && chi_square.is_finite() {
        // σ̂₀² = max(1, χ²/dof)
        fix.covariance *= (chi_square / dof as f64).max(1.0);
    }
    fix
}

#[cfg(test)]
#[path = "tests_solve.rs"]
mod tests;
