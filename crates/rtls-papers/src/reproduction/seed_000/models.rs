//! The models of seed 000's trackers and bound: the pedestrian CV model, the tunnel map as a
//! pseudo-measurement, and the expected Fisher information of the censored RSSI and the map
//! (the PCRB's `E[J_z]`).

use nalgebra::{DMatrix, DVector};
use rtls_estimation::measurement::{LinearMeasurementModel, MeasurementJacobian, MeasurementModel};
use rtls_estimation::motion::LinearMotionModel;
use rtls_estimation::stats::chi_square_cdf;
use rtls_estimation::{Matrix, Vector};
use rtls_positioning::pathloss::PathLossModel;

use crate::error::{non_negative, positive, Result, SimError};
use rtls_sim::pcrb::measurement_information;
use rtls_sim::scenarios::seed_000::{MineLayout, WalkingLine};
use rtls_sim::sensors::readers::{distance_m, ReaderLayer, ReaderStatus};

/// Position indices `x, y, z` of the state `[x, vx, y, vy, z, vz]`.
pub const POSITION_INDICES: [usize; 3] = [0, 2, 4];

/// A constant-velocity model in 3-D whose white acceleration has one variance in the horizontal
/// axes and another in the vertical: walkers start, stop and turn in plan, but their height only
/// follows the grade of the road.
///
/// Per axis `a` with variance `σ_a²`: `F_a = [[1, T], [0, 1]]`, `G = [T²/2, T]ᵀ`,
/// `Q_a = σ_a² G Gᵀ` (seed 000's `C Q Cᵀ` with `Q = diag(σ_h², σ_h², σ_v²)`).
///
/// # Units
/// Variances in (m/s²)², `T` in s.
///
/// # Example
/// ```
/// use rtls_estimation::motion::LinearMotionModel;
/// use rtls_papers::reproduction::seed_000::PedestrianCv;
/// let model = PedestrianCv::new(0.25, 0.0025)?;
/// let q = model.process_noise_matrix(1.0);
/// assert_eq!((q[(0, 0)], q[(1, 1)], q[(5, 5)]), (0.0625, 0.25, 0.0025)); // σ² T⁴/4, σ² T²
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 000 eq. (5)–(6) and (17); Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with
/// Applications to Tracking and Navigation*, Wiley 2001, §6.3.2 (discrete white-noise
/// acceleration; `σ_a` of the order of the largest velocity change per step).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PedestrianCv {
    horizontal_variance: f64,
    vertical_variance: f64,
}

impl PedestrianCv {
    /// A model with horizontal and vertical acceleration variances ((m/s²)²).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a negative or non-finite variance.
    pub fn new(horizontal_variance: f64, vertical_variance: f64) -> Result<Self> {
        let reason = "a process noise variance must be finite and ≥ 0";
        Ok(Self {
            horizontal_variance: non_negative(horizontal_variance, "horizontal_variance", reason)?,
            vertical_variance: non_negative(vertical_variance, "vertical_variance", reason)?,
        })
    }

    /// Standard deviation of the horizontal white acceleration, m/s².
    #[must_use]
    pub fn horizontal_std_mps2(&self) -> f64 {
        self.horizontal_variance.sqrt()
    }

    /// Standard deviation of the vertical white acceleration, m/s².
    #[must_use]
    pub fn vertical_std_mps2(&self) -> f64 {
        self.vertical_variance.sqrt()
    }
}

impl LinearMotionModel<6> for PedestrianCv {
    fn transition_matrix(&self, dt_s: f64) -> Matrix<6> {
        let mut f = Matrix::<6>::identity();
        for axis in 0..3 {
            // p' = p + T v
            f[(2 * axis, 2 * axis + 1)] = dt_s;
        }
        f
    }

    fn process_noise_matrix(&self, dt_s: f64) -> Matrix<6> {
        let mut q = Matrix::<6>::zeros();
        // G = [T²/2, T]ᵀ
        let g = [dt_s * dt_s / 2.0, dt_s];
        let variances = [
            self.horizontal_variance,
            self.horizontal_variance,
            self.vertical_variance,
        ];
        for (axis, sigma2) in variances.iter().enumerate() {
            for i in 0..2 {
                for j in 0..2 {
                    // Q_a = σ_a² G Gᵀ
                    q[(2 * axis + i, 2 * axis + j)] = sigma2 * g[i] * g[j];
                }
            }
        }
        q
    }
}

/// How far a tag may lie from the walking line of the map: a walker is anywhere across the
/// tunnel, and helmets sit at different heights.
///
/// # Units
/// m (standard deviations).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapSpread {
    /// Across the tunnel, m.
    pub lateral_std_m: f64,
    /// Above or below the walking line, m.
    pub vertical_std_m: f64,
}

/// Linear soft constraints on the position as a pseudo-measurement of the state
/// `[x, vx, y, vy, z, vz]`: the tunnel map (the two constraints of a [`WalkingLine`]: lateral
/// offset 0, height on the walking line, `R = diag(σ_lat², σ_vert²)`), a height plane near a
/// junction, or a tunnel's end.
///
/// # Example
/// ```
/// use nalgebra::DVector;
/// use rtls_estimation::measurement::MeasurementModel;
/// use rtls_estimation::Vector;
/// use rtls_papers::reproduction::seed_000::{MapSpread, PositionConstraint};
/// use rtls_sim::scenarios::seed_000::WalkingLine;
/// let line = WalkingLine {
///     start_m: [0.0, 0.0, 0.0], direction: [1.0, 0.0], grade: 0.0, length_m: 20.0, dead_start: true, dead_end: true,
/// };
/// let spread = MapSpread { lateral_std_m: 1.0, vertical_std_m: 0.2 };
/// let (model, z) = PositionConstraint::tunnel(&line, &spread)?;
/// // a tag 3 m left of an east-going line, 0.5 m high: offsets (3, 0.5) against z = (0, 0)
/// let h = model.predict(&Vector::<6>::new(5.0, 1.0, 3.0, 0.0, 0.5, 0.0)).expect("linear");
/// assert_eq!((h, z), (DVector::from_vec(vec![3.0, 0.5]), DVector::from_vec(vec![0.0, 0.0])));
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// D. Simon, "Kalman filtering with state constraints: a survey of linear and nonlinear
/// algorithms", *IET Control Theory & Applications* 4(8), 2010, §2.4 (perfect and soft
/// constraints as pseudo-measurements).
#[derive(Debug, Clone, PartialEq)]
pub struct PositionConstraint {
    h: MeasurementJacobian<6>,
    noise: DMatrix<f64>,
}

impl PositionConstraint {
    /// Soft constraints `cᵢ · p = rᵢ` on the position, each with std `σᵢ`: rows
    /// `(cᵢ, rᵢ, σᵢ)`; returns the model and its pseudo-measurement `z = [r₁, r₂, …]`.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] (`std_m`) for a non-positive or non-finite σ;
    /// [`SimError::EmptyInput`] for no rows.
    pub fn new(rows: &[([f64; 3], f64, f64)]) -> Result<(Self, DVector<f64>)> {
        if rows.is_empty() {
            return Err(SimError::EmptyInput {
                what: "position constraint rows",
            });
        }
        let mut h = MeasurementJacobian::<6>::zeros(rows.len());
        let mut z = DVector::zeros(rows.len());
        let mut variances = Vec::with_capacity(rows.len());
        for (row, &(c, r, std_m)) in rows.iter().enumerate() {
            let std_m = positive(std_m, "std_m", "a constraint's spread must be finite and positive")?;
            for (axis, &index) in POSITION_INDICES.iter().enumerate() {
                h[(row, index)] = c[axis];
            }
            z[row] = r;
            variances.push(std_m * std_m);
        }
        // R = diag(σ₁², σ₂², …)
        let noise = DMatrix::from_diagonal(&DVector::from_vec(variances));
        Ok((Self { h, noise }, z))
    }

    /// The two constraints of a tunnel's walking line (lateral offset 0, height on the line)
    /// with `R = diag(σ_lat², σ_vert²)`.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] (`lateral_std_m`, `vertical_std_m`) for a non-positive
    /// or non-finite spread.
    pub fn tunnel(line: &WalkingLine, spread: &MapSpread) -> Result<(Self, DVector<f64>)> {
        let reason = "the map spreads must be finite and positive";
        let lateral = positive(spread.lateral_std_m, "lateral_std_m", reason)?;
        let vertical = positive(spread.vertical_std_m, "vertical_std_m", reason)?;
        let ((c_lat, r_lat), (c_vert, r_vert)) = (line.lateral(), line.vertical());
        Self::new(&[(c_lat, r_lat, lateral), (c_vert, r_vert, vertical)])
    }
}

impl MeasurementModel<6> for PositionConstraint {
    fn dim(&self) -> usize {
        self.h.nrows()
    }

    fn predict(&self, x: &Vector<6>) -> rtls_estimation::Result<DVector<f64>> {
        // h(x) = H x
        Ok(&self.h * x)
    }

    fn jacobian(&self, _x: &Vector<6>) -> rtls_estimation::Result<MeasurementJacobian<6>> {
        Ok(self.h.clone())
    }

    fn noise_covariance(&self) -> &DMatrix<f64> {
        &self.noise
    }
}

impl LinearMeasurementModel<6> for PositionConstraint {
    fn matrix(&self) -> &MeasurementJacobian<6> {
        &self.h
    }
}

/// The expected Fisher information about the state `[x, vx, y, vy, z, vz]` at the true
/// position `truth_m`: the RSSI of every working reader, censored at the sensitivity, plus the
/// tunnel map.
///
/// A reader at distance `d` with mean power `m = μ(d) − L` (`L`: excess and obstacle losses)
/// reports `ρ = m + X` only if `ρ ≥ S`. With `c = (S − m)/σ_X`, the score of `m` is `(ρ − m)/σ²`
/// when heard and `−φ(c)/(σ Φ(c))` when not, so the information about `m` is
///
/// ```text
/// I(m) = [1 − Φ(c) + c φ(c) + φ(c)²/Φ(c)] / σ_X²       (→ 1/σ² in range, → 0 far away)
/// J_i  = I(m) μ′(d)² u uᵀ,   u = (p − r_i)/d           at the position indices
/// ```
///
/// (silence is information too: a reader that does not hear the tag says it is far). The map
/// adds `Hᵀ R⁻¹ H` of the [`PositionConstraint`] of the walking line nearest the truth. A broken
/// reader adds nothing.
///
/// # Errors
/// [`SimError::LengthMismatch`] unless `excess_loss_db` has one entry per reader; the errors
/// of [`PositionConstraint::new`].
///
/// # References
/// P. Tichavský, C. H. Muravchik, A. Nehorai, *IEEE Trans. Signal Processing* 46(5), 1998
/// (`E[J_z]` in the PCRB); J. Tobin, "Estimation of relationships for limited dependent
/// variables", *Econometrica* 26(1), 1958 (the censored-normal likelihood).
pub fn expected_information(
    layer: &ReaderLayer,
    layout: &MineLayout,
    map: &MapSpread,
    truth_m: [f64; 3],
    excess_loss_db: &[f64],
) -> Result<DMatrix<f64>> {
    let mut j = reader_information(layer, truth_m, excess_loss_db, censored_information_fraction)?;
    if let Some(line) = layout.nearest_walking_line(truth_m) {
        let (model, _) = PositionConstraint::tunnel(&line, map)?;
        let h = DMatrix::from_column_slice(2, 6, model.matrix().as_slice());
        j += measurement_information(&h, model.noise_covariance())?;
    }
    Ok(j)
}

/// The naive information: only the readers that hear the tag count, each with the full
/// information of an uncensored reading, weighted by its detection probability
/// (`E[Σ_heard Hᵢᵀ Hᵢ/σ_X²] = Σᵢ (1 − Φ(cᵢ)) μ′(dᵢ)² uᵢ uᵢᵀ/σ_X²`), and no map. Silence and the
/// map are ignored, so a PCRB from it is no bound for estimators that use them; the report
/// shows it beside the real one.
///
/// # Errors
/// As [`expected_information`].
pub fn detected_information(layer: &ReaderLayer, truth_m: [f64; 3], excess_loss_db: &[f64]) -> Result<DMatrix<f64>> {
    // P(heard) = 1 − Φ(c)
    reader_information(layer, truth_m, excess_loss_db, |c| Ok(1.0 - normal_cdf(c)?))
}

/// `Σᵢ w(cᵢ) μ′(dᵢ)² uᵢ uᵢᵀ / σ_X²` over the working readers at the position indices, with
/// `cᵢ = (S − mᵢ)/σ_X` and `w` the share of an uncensored reading's information that counts.
fn reader_information(
    layer: &ReaderLayer,
    truth_m: [f64; 3],
    excess_loss_db: &[f64],
    share: impl Fn(f64) -> Result<f64>,
) -> Result<DMatrix<f64>> {
    if excess_loss_db.len() != layer.readers().len() {
        return Err(SimError::LengthMismatch {
            what: "excess losses vs readers",
            expected: layer.readers().len(),
            found: excess_loss_db.len(),
        });
    }
    let law = layer.radio().law();
    let sigma_db = law.shadowing_std_db().max(1e-9);
    let mut j = DMatrix::zeros(6, 6);
    for (reader, &excess_db) in layer.readers().iter().zip(excess_loss_db) {
        if reader.status == ReaderStatus::Broken {
            continue;
        }
        let range_m = distance_m(truth_m, reader.position_m).max(1e-3);
        // c = (S − m)/σ,  m = μ(d) − L
        let mean_dbm = law.mean_rssi_dbm(range_m) - excess_db - reader.obstacle_loss_db;
        let c = (layer.radio().sensitivity_dbm() - mean_dbm) / sigma_db;
        // w(c) μ′(d)² / σ²
        let slope = law.slope_db_per_m(range_m);
        let weight = share(c)? * slope * slope / (sigma_db * sigma_db);
        for (a, &ia) in POSITION_INDICES.iter().enumerate() {
            for (b, &ib) in POSITION_INDICES.iter().enumerate() {
                // J += w μ′² u uᵀ
                j[(ia, ib)] += weight * (truth_m[a] - reader.position_m[a]) * (truth_m[b] - reader.position_m[b])
                    / (range_m * range_m);
            }
        }
    }
    Ok(j)
}

/// `Φ(c) = ½ (1 + sign(c) P_χ²₁(c²))`, the standard normal CDF.
fn normal_cdf(c: f64) -> Result<f64> {
    let p = chi_square_cdf(c * c, 1.0).map_err(SimError::estimation(0.0))?;
    Ok(0.5 * (1.0 + c.signum() * p))
}

/// `σ² I(m) = 1 − Φ(c) + c φ(c) + φ(c)²/Φ(c)`: the share of an uncensored reading's
/// information that a reading censored at `c` standard deviations above its mean keeps.
fn censored_information_fraction(c: f64) -> Result<f64> {
    // beyond ±6σ the limits 1 (always heard) and 0 (never heard) hold to 10⁻⁷
    if c <= -6.0 {
        return Ok(1.0);
    }
    if c >= 6.0 {
        return Ok(0.0);
    }
    // Φ(c),  φ(c) = e^{−c²/2}/√(2π)
    let cdf = normal_cdf(c)?;
    let pdf = (-0.5 * c * c).exp() / (2.0 * std::f64::consts::PI).sqrt();
    Ok((1.0 - cdf + c * pdf + pdf * pdf / cdf.max(f64::MIN_POSITIVE)).clamp(0.0, 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};

    /// With equal variances the pedestrian model is rtls-estimation's CV model.
    #[test]
    fn pedestrian_model_matches_the_library_cv_model() {
        let ours = PedestrianCv::new(0.7, 0.7).unwrap();
        let cv = ConstantVelocity::new(ProcessNoise::discrete(0.7, NoiseGain::kinematic())).unwrap();
        for dt in [0.5, 1.0, 2.0] {
            let (f, q) = (ours.transition_matrix(dt), ours.process_noise_matrix(dt));
            let (fc, qc) = (
                LinearMotionModel::<6>::transition_matrix(&cv, dt),
                LinearMotionModel::<6>::process_noise_matrix(&cv, dt),
            );
            assert!((f - fc).abs().max() < 1e-15 && (q - qc).abs().max() < 1e-15);
        }
        let q = PedestrianCv::new(0.5, 0.01).unwrap().process_noise_matrix(1.0);
        assert_eq!((q[(0, 1)], q[(4, 5)], q[(0, 4)]), (0.25, 0.005, 0.0));
        assert!(PedestrianCv::new(-1.0, 0.0).is_err());
    }

    /// The censored information: all of it well inside the range, none far outside, and at the
    /// threshold `1/2 + φ(0)²/(1/2) = 1/2 + 1/π`; it equals a Monte Carlo estimate of E[score²].
    #[test]
    fn censored_information_has_the_right_limits_and_value() {
        assert_eq!(censored_information_fraction(-7.0).unwrap(), 1.0);
        assert_eq!(censored_information_fraction(7.0).unwrap(), 0.0);
        let at_threshold = censored_information_fraction(0.0).unwrap();
        assert!((at_threshold - (0.5 + 1.0 / std::f64::consts::PI)).abs() < 1e-9);
        let mut last = 1.0;
        for k in -50..50 {
            let f = censored_information_fraction(k as f64 * 0.1).unwrap();
            assert!(f <= last + 1e-12 && (0.0..=1.0).contains(&f), "not decreasing at {k}");
            last = f;
        }
        // Monte Carlo of the score: (ρ − m)/σ² heard, −φ(c)/(σΦ(c)) not heard (σ = 1, c = 0.7)
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let c: f64 = 0.7;
        let pdf = (-0.5 * c * c).exp() / (2.0 * std::f64::consts::PI).sqrt();
        let cdf = normal_cdf(c).unwrap();
        let n = 200_000;
        let mean_square = (0..n)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut rng);
                if z >= c {
                    z * z
                } else {
                    (pdf / cdf).powi(2)
                }
            })
            .sum::<f64>()
            / n as f64;
        let f = censored_information_fraction(c).unwrap();
        assert!((mean_square / f - 1.0).abs() < 0.02, "{mean_square} vs {f}");
    }

    #[test]
    fn the_tunnel_constraint_pulls_to_the_walking_line() {
        let line = WalkingLine {
            start_m: [0.0, 0.0, 0.0],
            direction: [0.6, 0.8],
            grade: 0.1,
            length_m: 10.0,
            dead_start: true,
            dead_end: false,
        };
        let spread = MapSpread {
            lateral_std_m: 1.0,
            vertical_std_m: 0.1,
        };
        let (model, z) = PositionConstraint::tunnel(&line, &spread).unwrap();
        // a point on the walking line satisfies both rows exactly
        let on_line = Vector::<6>::new(3.0, 0.0, 4.0, 0.0, 0.5, 0.0);
        assert!((model.predict(&on_line).unwrap() - &z).norm() < 1e-12);
        // 2 m to the left: lateral residual 2 (left normal (−0.8, 0.6))
        let left = Vector::<6>::new(3.0 - 1.6, 0.0, 4.0 + 1.2, 0.0, 0.5, 0.0);
        assert!((model.predict(&left).unwrap()[0] - z[0] - 2.0).abs() < 1e-12);
        let bad = MapSpread {
            lateral_std_m: 0.0,
            ..spread
        };
        assert!(PositionConstraint::tunnel(&line, &bad).is_err());
    }
}
