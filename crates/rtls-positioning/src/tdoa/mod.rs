//! Time difference of arrival (TDOA): fixes from range differences to a reference station.
//!
//! A TDOA `τ_{i,ref}` in seconds is the range difference `r_{i,ref} = c τ_{i,ref}` (m).
//! Range differences are ordered by station, skipping the reference, exactly as
//! `rtls_estimation::measurement::Tdoa` orders them, so the same vector and covariance can go
//! to [`chan`] for a fix or to an EKF/UKF as a raw measurement.
//!
//! Every solver works in the plane (`[f64; 2]` stations, [`crate::Fix2`]) and in space
//! (`[f64; 3]` stations, [`crate::Fix3`]) through one const-generic implementation; the
//! dimension is inferred from the station array.
//!
//! - [`chan`] — Chan & Ho's closed-form estimator (≥ 3 stations in the plane, ≥ 4 in space;
//!   two-step WLS from 4 in the plane and 5 in space).
//! - [`taylor`], [`chan_taylor`] — Gauss–Newton / Levenberg–Marquardt (Foy/Torrieri)
//!   refinement to the maximum-likelihood fix.
//! - [`planar_at_height`] — the planar fix of a tag at a known height from stations at their
//!   own heights (slant-range differences), for 2-D tracking with anchors on the ceiling.
//! - [`cyclic_reference`] — seed 004's rotating master station.
//! - [`range_differences_at`], [`differenced_range_covariance`] — the noise-free measurement
//!   and the covariance of differenced independent TOAs, for simulation and configuration.

mod chan;
mod height;
mod problem;
mod taylor;

pub use chan::{chan, ChanSolution};
pub use height::planar_at_height;
pub use taylor::{chan_taylor, taylor, TAYLOR_MAX_ITERATIONS};

use nalgebra::{DMatrix, SVector};

use crate::error::{PositioningError, Result};

/// The reference (master) station of epoch `epoch` in seed 004's cyclic master-station scheme:
/// `ref(k) = k mod n`.
///
/// Seed 004 computes each epoch's cellular TDOA fix with the master station rotating through
/// the `n` stations ("循环主站"). Every range difference shares the master's error, so a fixed
/// master biased by non-line-of-sight propagation would bias every fix the same way, and a
/// master badly placed for the tag (e.g. where Chan's step 2 is ill-conditioned) would stay
/// bad; rotating spreads both over time for the tracking filter to average. The paper gives
/// no further detail; this is the plain round-robin order.
///
/// # Errors
/// [`PositioningError::InvalidParameter`] (`stations`) if `stations` is 0.
///
/// # Example
/// ```
/// use rtls_positioning::tdoa::cyclic_reference;
/// let masters: Vec<usize> = (0..6).map(|k| cyclic_reference(k, 4)).collect::<Result<_, _>>()?;
/// assert_eq!(masters, [0, 1, 2, 3, 0, 1]);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Seed 004, §3 (simulation: "蜂窝网定位采用循环主站的 TDOA 定位法").
pub fn cyclic_reference(epoch: u64, stations: usize) -> Result<usize> {
    if stations == 0 {
        return Err(PositioningError::InvalidParameter {
            name: "stations",
            reason: "a cyclic reference needs at least one station",
        });
    }
    // ref(k) = k mod n; n fits in u64 and the remainder is below n, so both casts are lossless.
    Ok((epoch % stations as u64) as usize)
}

/// The noise-free range differences `r_{i,ref} = ‖p − s_i‖ − ‖p − s_ref‖` (m) of a position
/// `p`, for every station `i ≠ ref` in station order, in the plane or in space (`D` = 2 or 3,
/// or any other dimension).
///
/// # Errors
/// [`PositioningError::Underdetermined`] for fewer than 2 stations;
/// [`PositioningError::InvalidParameter`] (`reference`) if `reference ≥ n`;
/// [`PositioningError::NonFinite`] for a NaN/∞ station or position.
///
/// # Example
/// ```
/// use nalgebra::Vector2;
/// use rtls_positioning::tdoa::range_differences_at;
/// let stations = [[0.0, 0.0], [6.0, 0.0], [0.0, 8.0]];
/// let r = range_differences_at(&stations, 1, &Vector2::new(0.0, 0.0))?;
/// assert_eq!(r, vec![-6.0, 2.0]); // 0 − 6, 8 − 6
/// let spatial = [[0.0, 0.0, 0.0], [0.0, 0.0, 3.0], [4.0, 0.0, 0.0]];
/// let r = range_differences_at(&spatial, 0, &nalgebra::Vector3::new(0.0, 0.0, 3.0))?;
/// assert_eq!(r, vec![-3.0, 2.0]); // 0 − 3, 5 − 3
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Chan & Ho (1994), eq. (2): `r_{i,1} = r_i − r_1`.
pub fn range_differences_at<const D: usize>(
    stations_m: &[[f64; D]],
    reference: usize,
    position_m: &SVector<f64, D>,
) -> Result<Vec<f64>> {
    if stations_m.len() < 2 {
        return Err(PositioningError::Underdetermined {
            anchors: stations_m.len(),
            needed: 2,
        });
    }
    if reference >= stations_m.len() {
        return Err(PositioningError::InvalidParameter {
            name: "reference",
            reason: "the reference index must be below the number of stations",
        });
    }
    let range = |s: &[f64; D]| (position_m - SVector::<f64, D>::from(*s)).norm();
    // r_ref = ‖p − s_ref‖
    let reference_m = range(&stations_m[reference]);
    // r_{i,ref} = ‖p − s_i‖ − r_ref
    let differences: Vec<f64> = stations_m
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != reference)
        .map(|(_, s)| range(s) - reference_m)
        .collect();
    if reference_m.is_finite() && differences.iter().all(|v| v.is_finite()) {
        Ok(differences)
    } else {
        Err(PositioningError::NonFinite {
            what: "stations or position",
        })
    }
}

/// The covariance `Q = D diag(σ²) Dᵀ` (m²) of range differences formed from independent
/// ranges (TOAs) of variances `σ_i²` (m²): `Q_ii = σ_i² + σ_ref²`, `Q_ij = σ_ref²` (`i ≠ j`),
/// rows and columns in station order skipping the reference.
///
/// With equal variances this is `σ² (I + 1 1ᵀ)`, the matrix
/// `rtls_estimation::measurement::Tdoa::planar_from_toa_variance` builds. A TDOA standard
/// deviation `σ_τ` in seconds is `σ = c σ_τ` in metres.
///
/// # Errors
/// [`PositioningError::Underdetermined`] for fewer than 2 variances;
/// [`PositioningError::InvalidParameter`] (`reference`) if `reference ≥ n`, or
/// (`range_variances_m2`) unless every variance is positive;
/// [`PositioningError::NonFinite`] for a NaN/∞ variance.
///
/// # Example
/// ```
/// use rtls_positioning::tdoa::differenced_range_covariance;
/// let q = differenced_range_covariance(&[1.0, 2.0, 3.0], 1)?;
/// assert_eq!(q.nrows(), 2);
/// assert_eq!(q[(0, 0)], 3.0); // σ₀² + σ_ref²
/// assert_eq!(q[(1, 1)], 5.0); // σ₂² + σ_ref²
/// assert_eq!(q[(0, 1)], 2.0); // σ_ref², shared through the reference
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// Chan & Ho (1994), §II (`Q` is the TDOA covariance); the differencing follows from
/// `r_{i,ref} = r_i − r_ref`.
pub fn differenced_range_covariance(range_variances_m2: &[f64], reference: usize) -> Result<DMatrix<f64>> {
    let n = range_variances_m2.len();
    if n < 2 {
        return Err(PositioningError::Underdetermined { anchors: n, needed: 2 });
    }
    if reference >= n {
        return Err(PositioningError::InvalidParameter {
            name: "reference",
            reason: "the reference index must be below the number of stations",
        });
    }
    if !range_variances_m2.iter().all(|v| v.is_finite()) {
        return Err(PositioningError::NonFinite {
            what: "range variances",
        });
    }
    if !range_variances_m2.iter().all(|&v| v > 0.0) {
        return Err(PositioningError::InvalidParameter {
            name: "range_variances_m2",
            reason: "every range variance must be strictly positive",
        });
    }
    let others: Vec<f64> = range_variances_m2
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != reference)
        .map(|(_, &v)| v)
        .collect();
    let reference_m2 = range_variances_m2[reference];
    // Q = σ_ref² 1 1ᵀ + diag(σ_i²)
    Ok(DMatrix::from_fn(n - 1, n - 1, |i, j| {
        if i == j {
            others[i] + reference_m2
        } else {
            reference_m2
        }
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    #[test]
    fn cyclic_reference_is_round_robin() {
        for stations in 1..7usize {
            for epoch in 0..50u64 {
                let r = cyclic_reference(epoch, stations).unwrap();
                assert!(r < stations);
                assert_eq!(r as u64, epoch % stations as u64);
            }
        }
        // Every station is master exactly once per cycle.
        let mut seen = [0usize; 5];
        for epoch in 1000..1005 {
            seen[cyclic_reference(epoch, 5).unwrap()] += 1;
        }
        assert_eq!(seen, [1; 5]);
        assert_eq!(cyclic_reference(u64::MAX, 4).unwrap(), 3);
        assert!(matches!(
            cyclic_reference(3, 0),
            Err(PositioningError::InvalidParameter { name: "stations", .. })
        ));
    }

    #[test]
    fn range_differences_skip_the_reference_in_station_order() {
        let stations = [[0.0, 0.0], [30.0, 0.0], [0.0, 30.0], [30.0, 30.0]];
        let p = Vector2::new(3.0, 4.0);
        let d = |s: [f64; 2]| ((3.0 - s[0]).powi(2) + (4.0 - s[1]).powi(2)).sqrt();
        let r = range_differences_at(&stations, 1, &p).unwrap();
        let r_ref = d(stations[1]);
        assert_eq!(r.len(), 3);
        assert!((r[0] - (5.0 - r_ref)).abs() < 1e-12);
        assert!((r[1] - (d(stations[2]) - r_ref)).abs() < 1e-12);
        assert!((r[2] - (d(stations[3]) - r_ref)).abs() < 1e-12);
        assert!(matches!(
            range_differences_at(&stations[..1], 0, &p),
            Err(PositioningError::Underdetermined { anchors: 1, needed: 2 })
        ));
        assert!(matches!(
            range_differences_at(&stations, 4, &p),
            Err(PositioningError::InvalidParameter { name: "reference", .. })
        ));
        assert!(matches!(
            range_differences_at(&stations, 0, &Vector2::new(f64::NAN, 0.0)),
            Err(PositioningError::NonFinite { .. })
        ));
    }

    #[test]
    fn differenced_covariance_is_d_sigma_dt() {
        let variances = [1.5, 2.0, 0.5, 4.0];
        for reference in 0..4 {
            let q = differenced_range_covariance(&variances, reference).unwrap();
            // D = rows e_i − e_ref for i ≠ ref
            let others: Vec<usize> = (0..4).filter(|&i| i != reference).collect();
            let mut d = DMatrix::zeros(3, 4);
            for (row, &i) in others.iter().enumerate() {
                d[(row, i)] = 1.0;
                d[(row, reference)] = -1.0;
            }
            let expected =
                &d * DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(&variances)) * d.transpose();
            assert!((q - expected).amax() < 1e-15, "reference {reference}");
        }
        assert!(matches!(
            differenced_range_covariance(&[1.0], 0),
            Err(PositioningError::Underdetermined { .. })
        ));
        assert!(matches!(
            differenced_range_covariance(&[1.0, 1.0], 2),
            Err(PositioningError::InvalidParameter { name: "reference", .. })
        ));
        assert!(matches!(
            differenced_range_covariance(&[1.0, 0.0], 0),
            Err(PositioningError::InvalidParameter {
                name: "range_variances_m2",
                ..
            })
        ));
        assert!(matches!(
            differenced_range_covariance(&[1.0, f64::NAN], 0),
            Err(PositioningError::NonFinite { .. })
        ));
    }
}
