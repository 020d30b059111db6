//! The accelerometer-driven prediction of a single-model CV track: a held accelerometer sample
//! is the control input, and the process noise is what the sample does not know.
//!
//! ```text
//! x⁻ = F x̂ + B a,                 F = blockdiag([[1, Δt], [0, 1]]),  B = blockdiag([Δt²/2, Δt]ᵀ)
//! Q  = Q_c(σ_r²) + B ε² Bᵀ        σ_r: tracker.aided_acceleration_noise_std_mps2 (continuous
//!                                 white acceleration the accelerometer misses);
//!                                 ε: the sample's std_mps2, its error held over the step
//! ```
//!
//! With `σ_r = 0` this is the textbook accelerometer-aided model (Bar-Shalom, Li, Kirubarajan
//! 2001, §6.3.2 with the accelerometer as input; seed 002 §1.2), which
//! `rtls_estimation::aided::TextbookAccelerometerModel` implements for one fixed sample.
//!
//! # Units
//! m, m/s, m/s², s.

use rtls_estimation::motion::{ConstantVelocity, ControlGain, LinearMotionModel, NoiseGain, ProcessNoise};
use rtls_estimation::Matrix;

use crate::error::Result;

/// An accelerometer sample a track holds: the control input of its next predictions (for at
/// most [`super::track::ACCELERATION_HOLD_S`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct HeldAcceleration {
    /// The sample's time, s.
    pub(super) time_s: f64,
    /// `a`, m/s², `[x, y, z]` (0 on axes the sample did not give).
    pub(super) acceleration_mps2: [f64; 3],
    /// `ε`, the sample's per-axis error std, m/s² (0 when the record states none).
    pub(super) std_mps2: f64,
}

/// The CV model driven by one held sample: transition and control gain of the CV model, noise
/// `Q_c(σ_r²) + B ε² Bᵀ` (see the [module documentation](self)).
#[derive(Debug, Clone, Copy)]
pub(super) struct AidedMotion {
    /// CV with acceleration input and the residual continuous noise `σ_r²`.
    residual: ConstantVelocity,
    /// CV whose discrete noise through the kinematic gain is the sample's `ε²`.
    sample: ConstantVelocity,
}

impl AidedMotion {
    /// The model for a sample of error std `sample_std_mps2` on top of `residual` (a CV model
    /// with the residual noise and the acceleration input).
    ///
    /// # Errors
    /// [`crate::EngineError::Estimation`] for a non-finite or negative std.
    pub(super) fn new(residual: ConstantVelocity, sample_std_mps2: f64) -> Result<Self> {
        let sample = ConstantVelocity::new(ProcessNoise::discrete(
            sample_std_mps2 * sample_std_mps2,
            NoiseGain::kinematic(),
        ))?;
        Ok(Self { residual, sample })
    }
}

impl<const N: usize> LinearMotionModel<N> for AidedMotion {
    fn transition_matrix(&self, dt_s: f64) -> Matrix<N> {
        LinearMotionModel::<N>::transition_matrix(&self.residual, dt_s)
    }

    fn process_noise_matrix(&self, dt_s: f64) -> Matrix<N> {
        // Q = Q_c(σ_r²) + B ε² Bᵀ
        LinearMotionModel::<N>::process_noise_matrix(&self.residual, dt_s)
            + LinearMotionModel::<N>::process_noise_matrix(&self.sample, dt_s)
    }

    fn control_matrix(&self, dt_s: f64) -> Option<ControlGain<N>> {
        LinearMotionModel::<N>::control_matrix(&self.residual, dt_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With no residual noise the model is the textbook accelerometer model of
    /// rtls-estimation, term by term.
    #[test]
    fn without_residual_noise_it_is_the_textbook_model() {
        use rtls_estimation::aided::{AccelerometerSample, TextbookAccelerometerModel};
        let residual = ConstantVelocity::new(ProcessNoise::continuous(0.0))
            .unwrap()
            .with_acceleration_input();
        let aided = AidedMotion::new(residual, 0.05).unwrap();
        let sample = AccelerometerSample::new([0.3, -0.1], [0.05f64.powi(2); 2]).unwrap();
        let textbook = TextbookAccelerometerModel::new(0.0).unwrap().for_sample(&sample);
        for dt in [0.5, 1.0, 2.0] {
            let (q, q_ref) = (
                LinearMotionModel::<4>::process_noise_matrix(&aided, dt),
                textbook.process_noise_matrix(dt),
            );
            assert!((q - q_ref).abs().max() < 1e-15, "Δt = {dt}: {q} vs {q_ref}");
            assert_eq!(
                LinearMotionModel::<4>::transition_matrix(&aided, dt),
                textbook.transition_matrix(dt)
            );
            assert_eq!(
                LinearMotionModel::<4>::control_matrix(&aided, dt),
                textbook.control_matrix(dt)
            );
        }
    }

    /// The residual noise adds the continuous white-acceleration block `q [[Δt³/3, Δt²/2],
    /// [Δt²/2, Δt]]`.
    #[test]
    fn the_residual_adds_continuous_noise() {
        let residual = ConstantVelocity::new(ProcessNoise::continuous(0.04))
            .unwrap()
            .with_acceleration_input();
        let aided = AidedMotion::new(residual, 0.0).unwrap();
        let q = LinearMotionModel::<4>::process_noise_matrix(&aided, 2.0);
        assert!((q[(0, 0)] - 0.04 * 8.0 / 3.0).abs() < 1e-15);
        assert!((q[(0, 1)] - 0.04 * 2.0).abs() < 1e-15);
        assert!((q[(1, 1)] - 0.04 * 2.0).abs() < 1e-15);
        assert!(AidedMotion::new(residual, f64::NAN).is_err());
    }

    /// End to end: with `aided_acceleration_noise_std_mps2 = 0` the tracker's fix after an
    /// accelerometer sample is the textbook KF's (`Q = B ε² Bᵀ` from the record's `std_mps2`);
    /// without the key the prediction keeps the white acceleration σ_a and the update differs.
    #[test]
    fn the_tracker_predicts_with_the_samples_noise() {
        use nalgebra::{DVector, Vector4};
        use rtls_estimation::aided::{AccelerometerSample, TextbookAccelerometerModel};
        use rtls_estimation::filter::KalmanFilter;
        use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
        use rtls_estimation::Gaussian;

        use crate::record::{Measurement, Record};
        use crate::site::Site;
        use crate::tracker::{Output, Tracker};

        let run = |aided_key: &str| {
            let text = format!(
                "readers = [ {{ id = \"A\", position_m = [0.0, 0.0], technology = \"uwb\" }} ]\n\
                 [tracker]\npipeline = \"fix-then-filter\"\nfilter = \"kf\"\n\
                 acceleration_noise_std_mps2 = 1.0\n{aided_key}\ninitial_speed_std_mps = 0.5\n\
                 reorder_window_s = 0.0\n[tracker.adaptive_noise]\nenabled = false\ncorrelation_s = 0.0\n"
            );
            let site = Site::from_toml_str(&text, "site.toml").unwrap();
            let mut tracker = Tracker::new(&site).unwrap();
            let mut out = Output::default();
            let record = |time_s: f64, measurement: Measurement| Record {
                time_s,
                tag: "t".into(),
                measurement,
            };
            let fix = |x: f64, y: f64| Measurement::Fix {
                position_m: vec![x, y],
                covariance_m2: vec![1.5, 0.0, 0.0, 2.0],
            };
            let sample = Measurement::Accelerometer {
                acceleration_mps2: vec![0.4, -0.2],
                std_mps2: Some(0.05),
            };
            for r in [
                record(0.0, fix(1.0, 2.0)),
                record(1.0, sample),
                record(1.0, fix(1.5, 1.7)),
            ] {
                tracker.push(r, &mut out).unwrap();
            }
            tracker.finish(&mut out).unwrap();
            out.updates.last().cloned().unwrap()
        };
        // the textbook KF from the same start: x₀ = [1, 0, 2, 0], P₀ = diag(1.5, 0.25, 2, 0.25)
        let kf = KalmanFilter::default();
        let x0 = Gaussian::new(
            Vector4::new(1.0, 0.0, 2.0, 0.0),
            nalgebra::Matrix4::from_diagonal(&Vector4::new(1.5, 0.25, 2.0, 0.25)),
            0.0,
        )
        .unwrap();
        let sample = AccelerometerSample::new([0.4, -0.2], [0.05f64.powi(2); 2]).unwrap();
        let model = TextbookAccelerometerModel::new(0.0).unwrap().for_sample(&sample);
        let prior = kf
            .predict_with_control(&x0, &model, &DVector::from_column_slice(&[0.4, -0.2]), 1.0)
            .unwrap();
        let h = ComponentSelection::<4>::position(2, NoiseCovariance::diagonal(&[1.5, 2.0]).unwrap()).unwrap();
        let expected = kf
            .update(&prior, &h, &DVector::from_column_slice(&[1.5, 1.7]))
            .unwrap()
            .state;

        let aided = run("aided_acceleration_noise_std_mps2 = 0.0");
        assert!((aided.position_m[0] - expected.mean()[0]).abs() < 1e-12, "{aided:?}");
        assert!((aided.position_m[1] - expected.mean()[2]).abs() < 1e-12, "{aided:?}");
        assert!((aided.position_covariance_m2[0] - expected.covariance()[(0, 0)]).abs() < 1e-12);
        let plain = run("");
        assert!((plain.position_m[0] - aided.position_m[0]).abs() > 1e-3, "{plain:?}");
    }
}
