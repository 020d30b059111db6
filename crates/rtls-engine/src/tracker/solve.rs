//! Fix-then-filter: one position fix per epoch from a tag's anchor readings (seed 000's
//! positioning stage), with the covariance the filter weighs it by.
//!
//! - Ranges and RSSI: RSSI becomes a range through the reader's log-distance law (the median
//!   range `d = d₀·10^((ρ₀ − ρ)/(10 n))`, delta-method variance `σ_d = σ_X / |dρ/dd|`); readings
//!   of one anchor are averaged with inverse-variance weights; in 2-D a slant range `r` to an
//!   anchor `Δz` above the tag becomes `√(max(r² − Δz², 0))`; then weighted Gauss–Newton
//!   multilateration with covariance `(Jᵀ W J)⁻¹` (started from the track's position when there
//!   is one, so `D` anchors suffice; `D + 1` otherwise).
//! - TDOA: Chan's closed form refined by Taylor iterations, over the largest group of readings
//!   sharing one reference anchor (`D + 1` stations needed). In 2-D the anchors' heights are
//!   ignored here (the tightly coupled pipeline models them exactly).

use nalgebra::{DMatrix, SVector};
use rtls_positioning::multilateration::{gauss_newton, GaussNewtonOptions, Initial};
use rtls_positioning::pathloss::{DistanceEstimate, LogDistance, PathLossModel};
use rtls_positioning::tdoa::chan_taylor;
use rtls_positioning::Fix;

use super::anchors::{AnchorReading, Anchors};

/// Gauss–Newton settings for epoch fixes: 50 iterations, relative step 1e-6 (well below
/// centimetre level at site scale).
const OPTIONS: GaussNewtonOptions = GaussNewtonOptions {
    max_iterations: 50,
    relative_tolerance: 1e-6,
};

/// The anchor's coordinates on the tracked axes.
fn axes<const D: usize>(position_m: &[f64; 3]) -> [f64; D] {
    let mut out = [0.0; D];
    out.copy_from_slice(&position_m[..D]);
    out
}

/// The fixes of one epoch: at most one from ranges/RSSI and one from TDOA.
///
/// # Errors
/// The reason no fix could be made (too few anchors, degenerate geometry, solver failure).
pub(crate) fn solve_epoch<const D: usize>(
    anchors: &Anchors,
    readings: &[AnchorReading],
    tag_height_m: f64,
    guess_m: Option<SVector<f64, D>>,
) -> Result<Vec<Fix<D>>, String> {
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
        match tdoa_fix::<D>(anchors, readings) {
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

/// Weighted multilateration over the epoch's ranges and RSSI-derived ranges.
fn range_fix<const D: usize>(
    anchors: &Anchors,
    readings: &[AnchorReading],
    tag_height_m: f64,
    guess_m: Option<SVector<f64, D>>,
) -> Result<Fix<D>, String> {
    // per anchor: Σ wᵢ rᵢ and Σ wᵢ with wᵢ = 1/σᵢ²
    let mut sums: Vec<(usize, f64, f64)> = Vec::new();
    for reading in readings {
        let (anchor, range_m, variance_m2) = match *reading {
            AnchorReading::Range {
                anchor,
                range_m,
                variance_m2,
            } => (anchor, range_m, variance_m2),
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
                (anchor, d, (sigma * sigma).max(1e-6))
            }
            AnchorReading::Tdoa { .. } => continue,
        };
        let weight = 1.0 / variance_m2;
        match sums.iter_mut().find(|(a, _, _)| *a == anchor) {
            Some(entry) => {
                entry.1 += weight * range_m;
                entry.2 += weight;
            }
            None => sums.push((anchor, weight * range_m, weight)),
        }
    }
    let mut positions = Vec::with_capacity(sums.len());
    let mut ranges = Vec::with_capacity(sums.len());
    let mut variances = Vec::with_capacity(sums.len());
    for (anchor, weighted_sum, weight_sum) in sums {
        let a = anchors.get(anchor).position_m;
        // r̄ = Σ wᵢ rᵢ / Σ wᵢ, σ̄² = 1 / Σ wᵢ
        // a negative range (Wi-Fi FTM/RTT next to the responder) is a distance of about 0
        let mut range_m = (weighted_sum / weight_sum).max(0.0);
        if D == 2 {
            // r_h = √(max(r² − Δz², 0))
            let dz = a[2] - tag_height_m;
            range_m = (range_m * range_m - dz * dz).max(0.0).sqrt();
        }
        positions.push(axes::<D>(&a));
        ranges.push(range_m);
        variances.push(1.0 / weight_sum);
    }
    let initial = match guess_m {
        Some(guess) if positions.len() >= D => Initial::Guess(guess),
        _ if positions.len() > D => Initial::Linear,
        _ => {
            return Err(format!(
                "{} anchor(s) in the epoch: a {D}-D fix needs {} (or {D} once the track exists)",
                positions.len(),
                D + 1
            ))
        }
    };
    gauss_newton::<D>(&positions, &ranges, &variances, initial, &OPTIONS)
        .map(|solution| solution.fix)
        .map_err(|e| format!("multilateration failed: {e}"))
}

/// `(anchor, range difference m, variance m²)` of one TDOA reading.
type TdoaEntry = (usize, f64, f64);

/// Chan + Taylor over the largest group of TDOA readings that share a reference anchor.
fn tdoa_fix<const D: usize>(anchors: &Anchors, readings: &[AnchorReading]) -> Result<Fix<D>, String> {
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
    let mut stations = vec![axes::<D>(&anchors.get(reference).position_m)];
    stations.extend(group.iter().map(|(a, _, _)| axes::<D>(&anchors.get(*a).position_m)));
    let differences: Vec<f64> = group.iter().map(|(_, r, _)| *r).collect();
    let covariance = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
        group.len(),
        group.iter().map(|(_, _, v)| *v),
    ));
    chan_taylor::<D>(&stations, 0, &differences, &covariance).map_err(|e| format!("TDOA solution failed: {e}"))
}
