//! Seed 000's predictive hazard alarm: predict the track over a horizon and find when the
//! probability of being inside a hazard zone first reaches a threshold.
//!
//! At each step `τ = k·Δ ≤ H` the CV prediction gives the position mean `p̂(τ)` and covariance
//! `P(τ)`. With `d(τ)` the zone's signed distance at the mean (negative inside) and `n` the unit
//! gradient of `d` there (the outward normal of the nearest border), the entry probability is
//! approximated by the half-plane through the nearest border point:
//! `P_in(τ) ≈ Φ(−d(τ) / σ_n(τ))`, `σ_n² = nᵀ P(τ) n`.
//! The alarm's time to entry is the first `τ` with `P_in(τ) ≥ p_alarm`; `p_alarm = 0.5` is the
//! mean path entering, lower values warn earlier as the uncertainty grows.

use rtls_estimation::filter::KalmanFilter;
use rtls_estimation::motion::ConstantVelocity;
use rtls_estimation::stats::chi_square_cdf;
use rtls_estimation::Gaussian;

use crate::error::Result;
use crate::site::AlarmSettings;
use crate::zones::Zone;

/// Step of the central differences of the signed distance, m.
const GRADIENT_STEP_M: f64 = 1e-3;

/// `Φ(z)`, the standard normal CDF: `½(1 + sign(z)·F_χ²₁(z²))`.
fn normal_cdf(z: f64) -> Result<f64> {
    let half_mass = 0.5 * chi_square_cdf(z * z, 1.0)?;
    Ok(if z >= 0.0 { 0.5 + half_mass } else { 0.5 - half_mass })
}

/// The position `[x, y, z]` and its covariance on the tracked axes of a CV state: the `D × D`
/// block, row-major, in the first `D²` entries (the rest zero), so nothing is allocated.
pub(crate) fn position_of<const N: usize>(state: &Gaussian<N>, tag_height_m: f64) -> ([f64; 3], [f64; 9]) {
    let x = state.mean();
    let p = state.covariance();
    let d = N / 2;
    let position = if d == 3 {
        [x[0], x[2], x[4]]
    } else {
        [x[0], x[2], tag_height_m]
    };
    let mut covariance = [0.0; 9];
    for i in 0..d {
        for j in 0..d {
            covariance[i * d + j] = p[(2 * i, 2 * j)];
        }
    }
    (position, covariance)
}

/// `σ_n` of `P` (row-major `D × D`) along the unit normal of the zone border nearest to `point`.
fn normal_std_m(zone: &Zone, point: [f64; 3], covariance: &[f64], dimensions: usize) -> f64 {
    let mut gradient = [0.0; 3];
    for (axis, g) in gradient.iter_mut().enumerate().take(dimensions) {
        let mut plus = point;
        let mut minus = point;
        plus[axis] += GRADIENT_STEP_M;
        minus[axis] -= GRADIENT_STEP_M;
        // ∂d/∂pᵢ ≈ (d(p + h eᵢ) − d(p − h eᵢ)) / 2h
        *g = (zone.signed_distance_m(plus) - zone.signed_distance_m(minus)) / (2.0 * GRADIENT_STEP_M);
    }
    let norm = gradient.iter().map(|g| g * g).sum::<f64>().sqrt();
    if norm > 0.5 {
        // σ_n² = nᵀ P n, n = ∇d / ‖∇d‖
        let n: Vec<f64> = gradient[..dimensions].iter().map(|g| g / norm).collect();
        let mut variance = 0.0;
        for i in 0..dimensions {
            for j in 0..dimensions {
                variance += n[i] * covariance[i * dimensions + j] * n[j];
            }
        }
        variance.max(0.0).sqrt()
    } else {
        // on a ridge of d (equidistant from two borders): the largest axis variance
        (0..dimensions)
            .map(|i| covariance[i * dimensions + i])
            .fold(0.0, f64::max)
            .sqrt()
    }
}

/// A predicted entry into a zone.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PredictedEntry {
    /// Index of the zone in the alarm-zone list.
    pub(crate) zone: usize,
    /// Time until `P_in` first reaches the threshold, s.
    pub(crate) time_to_entry_s: f64,
    /// `P_in` then.
    pub(crate) probability: f64,
}

/// The zones of `zones` (skipping those listed in `inside`) that the track is predicted to enter
/// within the horizon.
///
/// # Errors
/// A failed prediction (non-finite state).
pub(crate) fn predict_entries<const N: usize>(
    state: &Gaussian<N>,
    motion: &ConstantVelocity,
    zones: &[Zone],
    inside: &[bool],
    settings: &AlarmSettings,
    tag_height_m: f64,
) -> Result<Vec<PredictedEntry>> {
    let dimensions = N / 2;
    let kf = KalmanFilter::default();
    let mut entries: Vec<PredictedEntry> = Vec::new();
    let steps = (settings.horizon_s / settings.step_s).ceil() as usize;
    for k in 1..=steps {
        let tau = (k as f64 * settings.step_s).min(settings.horizon_s);
        // x̂(τ) = F(τ) x̂, P(τ) = F P Fᵀ + Q(τ)
        let predicted = kf.predict(state, motion, state.time_s() + tau)?;
        let (point, covariance) = position_of(&predicted, tag_height_m);
        for (index, zone) in zones.iter().enumerate() {
            if inside[index] || entries.iter().any(|e| e.zone == index) {
                continue;
            }
            let distance_m = zone.signed_distance_m(point);
            let sigma_m = normal_std_m(zone, point, &covariance[..dimensions * dimensions], dimensions);
            // P_in = Φ(−d/σ_n); a certain position is inside exactly when d ≤ 0
            let probability = if sigma_m > 0.0 {
                normal_cdf(-distance_m / sigma_m)?
            } else if distance_m <= 0.0 {
                1.0
            } else {
                0.0
            };
            if probability >= settings.entry_probability {
                entries.push(PredictedEntry {
                    zone: index,
                    time_to_entry_s: tau,
                    probability,
                });
            }
        }
    }
    Ok(entries)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::zones::{Shape, ZoneKind};
    use rtls_estimation::motion::ProcessNoise;
    use rtls_estimation::{Matrix, Vector};

    fn wall_zone() -> Zone {
        // everything with x ≥ 10 (a wide box)
        Zone {
            id: "collapse".into(),
            name: "collapse".into(),
            kind: ZoneKind::Hazard,
            readers: vec![],
            shape: Shape::Box {
                min_m: [10.0, -100.0, -10.0],
                max_m: [200.0, 100.0, 10.0],
            },
        }
    }

    #[test]
    fn normal_cdf_matches_known_values() {
        assert!((normal_cdf(0.0).unwrap() - 0.5).abs() < 1e-12);
        assert!((normal_cdf(1.0).unwrap() - 0.841_344_746_068_542_9).abs() < 1e-9);
        assert!((normal_cdf(-1.959_963_984_540_054).unwrap() - 0.025).abs() < 1e-9);
    }

    #[test]
    fn a_walker_heading_for_the_zone_is_warned_with_the_mean_path_entry_time() {
        // at x = 0 moving +1 m/s, tiny uncertainty: the mean reaches x = 10 at τ = 10 s
        let motion = ConstantVelocity::new(ProcessNoise::continuous(1e-6)).unwrap();
        let state = Gaussian::new(
            Vector::<4>::new(0.0, 1.0, 0.0, 0.0),
            Matrix::<4>::identity() * 1e-6,
            0.0,
        )
        .unwrap();
        let settings = AlarmSettings {
            horizon_s: 15.0,
            step_s: 0.5,
            entry_probability: 0.5,
        };
        let entries = predict_entries(&state, &motion, &[wall_zone()], &[false], &settings, 0.0).unwrap();
        assert_eq!(entries.len(), 1);
        assert!((entries[0].time_to_entry_s - 10.0).abs() < 1e-9, "{entries:?}");
        // a shorter horizon sees nothing
        let short = AlarmSettings {
            horizon_s: 8.0,
            ..settings
        };
        assert!(predict_entries(&state, &motion, &[wall_zone()], &[false], &short, 0.0)
            .unwrap()
            .is_empty());
    }

    #[test]
    fn uncertainty_brings_a_low_threshold_alarm_forward() {
        // σ_a = 1 m/s²: the position spread grows ∝ τ^1.5, so P_in = 0.1 comes before the mean
        let motion = ConstantVelocity::new(ProcessNoise::continuous(1.0)).unwrap();
        let state = Gaussian::new(
            Vector::<4>::new(0.0, 1.0, 0.0, 0.0),
            Matrix::<4>::identity() * 0.01,
            0.0,
        )
        .unwrap();
        let at = |p: f64| {
            let settings = AlarmSettings {
                horizon_s: 15.0,
                step_s: 0.5,
                entry_probability: p,
            };
            predict_entries(&state, &motion, &[wall_zone()], &[false], &settings, 0.0).unwrap()[0]
        };
        let (early, mean) = (at(0.1), at(0.5));
        assert!((mean.time_to_entry_s - 10.0).abs() < 1e-9);
        assert!(
            early.time_to_entry_s < mean.time_to_entry_s - 1.0,
            "{early:?} vs {mean:?}"
        );
        assert!(early.probability >= 0.1 && early.probability < 0.5);
    }
}
