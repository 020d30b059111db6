//! The measurement side of a seed 001 run: the paper's single-epoch joint TOA-RSS fixes, and
//! the measurement information at the true states for the posterior Cramér–Rao bound.

use nalgebra::{DMatrix, DVector, Vector2};
use rtls_estimation::measurement::MeasurementModel;
use rtls_estimation::Vector;
use rtls_positioning::multilateration::{toa_rss, GaussNewtonOptions, Initial, RangeObservation, RssObservation};
use rtls_positioning::pathloss::{Breakpoint, BreakpointParameters};
use rtls_positioning::PositioningError;

use super::{JointMeasurement, Seed001Config};
use crate::error::{Result, SimError};
use rtls_sim::pcrb::measurement_information;

/// The paper's positioning stage: a joint TOA + RSS maximum-likelihood fix per epoch
/// (Gauss–Newton / Levenberg–Marquardt from the previous fix, which also picks the side of the
/// two stations' mirror ambiguity), `None` where it fails.
pub(super) fn joint_fixes(config: &Seed001Config, measurements: &[DVector<f64>]) -> Result<Vec<Option<[f64; 2]>>> {
    let law = config.rss_law;
    // the received-power view of the same law: ρ = 0 dBm − P(d)
    let radio = Breakpoint::new(BreakpointParameters {
        transmit_power_dbm: 0.0,
        reference_loss_db: law.p0_db(),
        reference_distance_m: law.reference_distance_m(),
        near_exponent: law.exponent(),
        far_exponent: law.far_exponent(),
        breakpoint_m: law.breakpoint_m(),
        shadowing_std_db: config.shadowing_std_db,
        form: law.form(),
    })?;
    let stations = config.stations_m.len();
    let options = GaussNewtonOptions::default();
    let x0 = config.truth.initial_state;
    let mut guess = Vector2::new(x0[0], x0[2]);
    let mut fixes = Vec::with_capacity(measurements.len());
    for z in measurements {
        let ranges: Vec<RangeObservation> = (0..stations)
            .map(|i| RangeObservation {
                anchor: i,
                range_m: z[i].max(0.0),
                variance_m2: config.range_std_m.powi(2),
            })
            .collect();
        let rss: Vec<RssObservation<'_>> = (0..stations)
            .map(|i| RssObservation {
                anchor: i,
                rssi_dbm: -z[stations + i],
                model: &radio,
            })
            .collect();
        match toa_rss(&config.stations_m, &ranges, &rss, Initial::Guess(guess), &options) {
            Ok(fix) => {
                guess = fix.fix.position;
                fixes.push(Some([guess[0], guess[1]]));
            }
            Err(
                PositioningError::DidNotConverge { .. }
                | PositioningError::DegenerateGeometry { .. }
                | PositioningError::NoConsistentSolution { .. },
            ) => fixes.push(None),
            Err(other) => return Err(other.into()),
        }
    }
    Ok(fixes)
}

/// One information matrix per epoch.
pub(super) type InformationPerEpoch = Vec<DMatrix<f64>>;

/// `Hᵀ R⁻¹ H` at every true state, for the joint measurement and for the ranges alone.
pub(super) fn information_at_truth(
    config: &Seed001Config,
    joint: &JointMeasurement,
    truth: &[[f64; 4]],
) -> Result<(InformationPerEpoch, InformationPerEpoch)> {
    let stations = config.stations_m.len();
    let r = DMatrix::from_column_slice(2 * stations, 2 * stations, joint.noise().matrix().as_slice());
    let r_toa = r.view((0, 0), (stations, stations)).into_owned();
    let mut information = Vec::with_capacity(truth.len());
    let mut toa_information = Vec::with_capacity(truth.len());
    for (state, t) in truth.iter().zip(config.truth.times_s()) {
        // H = ∂h/∂x at the true state
        let h = MeasurementModel::<4>::jacobian(joint, &Vector::<4>::from(*state)).map_err(SimError::estimation(t))?;
        let h = DMatrix::from_column_slice(h.nrows(), 4, h.as_slice());
        // J = Hᵀ R⁻¹ H (joint), and with the range rows only
        information.push(measurement_information(&h, &r)?);
        toa_information.push(measurement_information(&h.rows(0, stations).into_owned(), &r_toa)?);
    }
    Ok((information, toa_information))
}
