//! One odometry record (speed, heading and their standard deviations) as a velocity
//! measurement whose covariance is positive definite, standstill and exact headings included.

use nalgebra::{Matrix2, Vector2};

use crate::error::{EstimationError, Result};

/// The least standard deviation of an odometry velocity on every axis, m/s: 1 cm/s, well
/// below a walking speed's resolution (≈ 0.1 m/s) and any wheel odometer's.
pub const ODOMETRY_VELOCITY_FLOOR_MPS: f64 = 0.01;

/// The velocity `[vx, vy]` and its covariance `R_v` of a speed `s` along a heading `θ` with
/// standard deviations `σ_s` and `σ_θ`, positive definite by construction:
/// ```text
/// v    = s [cos θ, sin θ]ᵀ
/// U    = [[cos θ, −sin θ], [sin θ, cos θ]]       along-track and cross-track directions
/// σ∥²  = σ_s² + σ_f²
/// σ⊥²  = s² σ_θ² + σ_f²                           s ≠ 0 (J diag(σ_s², σ_θ²) Jᵀ, J = ∂v/∂(s, θ))
/// σ⊥²  = σ_s² + σ_f²                              s = 0
/// R_v  = U diag(σ∥², σ⊥²) Uᵀ
/// ```
/// with the floor `σ_f` = [`ODOMETRY_VELOCITY_FLOOR_MPS`]. Without it, `J diag(σ_s², σ_θ²) Jᵀ`
/// is singular whenever `s σ_θ = 0` or `σ_s = 0`. At a standstill (`s = 0` exactly, what an
/// odometer reports when the wheels do not turn) the heading says nothing about the direction
/// of the velocity, so the covariance is isotropic, `(σ_s² + σ_f²) I`.
///
/// # Units
/// `speed_mps` and `speed_std_mps` in m/s, `heading_rad` and `heading_std_rad` in rad
/// (counter-clockwise from +x); the velocity in m/s, the covariance in (m/s)².
///
/// # Errors
/// [`EstimationError::NonFinite`] for a NaN/∞ speed or heading;
/// [`EstimationError::InvalidParameter`] for a negative or non-finite standard deviation.
///
/// # Example
/// ```
/// use rtls_estimation::aided::{odometry_velocity, ODOMETRY_VELOCITY_FLOOR_MPS};
/// // standing still: σ_s² + σ_f² on both axes, whatever the heading
/// let (v, r) = odometry_velocity(0.0, 1.0, 0.1, 0.0)?;
/// assert_eq!(v[0].abs() + v[1].abs(), 0.0);
/// let floor = ODOMETRY_VELOCITY_FLOOR_MPS.powi(2);
/// assert!((r[(0, 0)] - (0.01 + floor)).abs() < 1e-15 && (r[(1, 1)] - (0.01 + floor)).abs() < 1e-15);
/// // an exact heading: only the floor across track (the y axis here)
/// let (_, r) = odometry_velocity(2.0, 0.0, 0.1, 0.0)?;
/// assert!((r[(1, 1)] - floor).abs() < 1e-15);
/// assert!(r.cholesky().is_some());
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// Bar-Shalom, Li, Kirubarajan (2001), §1.4.13 (first-order propagation of a covariance
/// through a nonlinear map); seed 004 eq. (9) (odometry as a velocity observation).
pub fn odometry_velocity(
    speed_mps: f64,
    heading_rad: f64,
    speed_std_mps: f64,
    heading_std_rad: f64,
) -> Result<(Vector2<f64>, Matrix2<f64>)> {
    if !speed_mps.is_finite() || !heading_rad.is_finite() {
        return Err(EstimationError::NonFinite {
            what: "odometry speed or heading",
        });
    }
    if !(speed_std_mps.is_finite() && speed_std_mps >= 0.0 && heading_std_rad.is_finite() && heading_std_rad >= 0.0) {
        return Err(EstimationError::InvalidParameter {
            name: "odometry standard deviations",
            reason: "speed_std_mps and heading_std_rad must be finite and non-negative",
        });
    }
    let s = speed_mps;
    let (sin, cos) = crate::math::sin_cos(heading_rad);
    // v = s [cos θ, sin θ]ᵀ
    let v = Vector2::new(s * cos, s * sin);
    // σ_f²
    let floor = ODOMETRY_VELOCITY_FLOOR_MPS * ODOMETRY_VELOCITY_FLOOR_MPS;
    // σ∥² = σ_s² + σ_f²
    let along = speed_std_mps * speed_std_mps + floor;
    // σ⊥² = s² σ_θ² + σ_f², or σ_s² + σ_f² at a standstill
    let cross = if s == 0.0 {
        along
    } else {
        s * s * heading_std_rad * heading_std_rad + floor
    };
    // R_v = U diag(σ∥², σ⊥²) Uᵀ
    let u = Matrix2::new(cos, -sin, sin, cos);
    let mut r = u * Matrix2::new(along, 0.0, 0.0, cross) * u.transpose();
    // exact symmetry (the product is symmetric up to rounding)
    r = (r + r.transpose()) * 0.5;
    Ok((v, r))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_covariance_is_the_jacobian_form_plus_the_floor() {
        let (s, theta, ss, st) = (1.7, 0.6, 0.2, 0.05);
        let (v, r) = odometry_velocity(s, theta, ss, st).unwrap();
        let (sin, cos) = theta.sin_cos();
        // J = [[cos θ, −s sin θ], [sin θ, s cos θ]]
        let j = Matrix2::new(cos, -s * sin, sin, s * cos);
        let reference = j * Matrix2::new(ss * ss, 0.0, 0.0, st * st) * j.transpose()
            + Matrix2::identity() * ODOMETRY_VELOCITY_FLOOR_MPS.powi(2);
        assert!((r - reference).amax() < 1e-15, "{r} vs {reference}");
        assert!((v - Vector2::new(s * cos, s * sin)).amax() < 1e-15);
    }

    #[test]
    fn standstill_and_exact_headings_are_positive_definite() {
        for (s, ss, st) in [
            (0.0, 0.1, 0.05),
            (0.0, 0.0, 0.0),
            (1.0, 0.1, 0.0),
            (1.0, 0.0, 0.0),
            (1e-300, 0.0, 0.0),
        ] {
            for theta in [0.0, 0.3, core::f64::consts::FRAC_PI_2, -2.0] {
                let (_, r) = odometry_velocity(s, theta, ss, st).unwrap();
                assert!(r.cholesky().is_some(), "s {s}, σ_s {ss}, σ_θ {st}, θ {theta}: {r}");
                let min_eigenvalue = r.symmetric_eigenvalues().min();
                assert!(min_eigenvalue >= 0.99 * ODOMETRY_VELOCITY_FLOOR_MPS.powi(2));
            }
        }
        // at a standstill the heading carries nothing: isotropic
        let (_, r) = odometry_velocity(0.0, 0.7, 0.3, 0.01).unwrap();
        assert!((r[(0, 1)]).abs() < 1e-15 && (r[(0, 0)] - r[(1, 1)]).abs() < 1e-15);
    }

    #[test]
    fn bad_inputs_are_errors() {
        assert!(odometry_velocity(f64::NAN, 0.0, 0.1, 0.1).is_err());
        assert!(odometry_velocity(1.0, f64::INFINITY, 0.1, 0.1).is_err());
        assert!(odometry_velocity(1.0, 0.0, -0.1, 0.1).is_err());
        assert!(odometry_velocity(1.0, 0.0, 0.1, f64::NAN).is_err());
    }
}
