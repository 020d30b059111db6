//! Odometry fusion (seed 004): the odometer's speed + heading as a velocity measurement
//! (`z = [x, vx, y, vy]`, `H = I₄`) or as a control input (dead reckoning `x += Δt v_odo`,
//! corrected by the fixes), each with and without estimating the heading drift, against the
//! KF on the fixes alone.
//!
//! Run: `cargo run --release -p rtls-papers --example odometry [runs]` (default 20).
use nalgebra::{DMatrix, DVector, Matrix2};
use rtls_estimation::aided::OdometryDeadReckoning;
use rtls_estimation::filter::KalmanFilter;
use rtls_estimation::measurement::{ComponentSelection, NoiseCovariance};
use rtls_estimation::motion::{ConstantVelocity, NoiseGain, ProcessNoise};
use rtls_estimation::{Gaussian, Matrix, Vector};
use rtls_papers::reproduction::{fused_observation, run_seed_004, Seed004Config, Seed004Run};
use rtls_sim::ErrorSummary;

/// CV KF with the fused `[x, vx, y, vy]` observation (velocity-only when there is no fix).
fn velocity_measurement(run: &Seed004Run) -> Result<Vec<[f64; 2]>, Box<dyn std::error::Error>> {
    let kf = KalmanFilter::default();
    let cv = ConstantVelocity::new(ProcessNoise::discrete(0.01, NoiseGain::seed_004_cv()))?;
    let r = run.fix_covariance_m2;
    let (v0, _) = run.odometry_velocities[0];
    let p0 = run.fixes.iter().flatten().next().ok_or("no fix")?;
    let mut x = Gaussian::new(
        Vector::<4>::new(p0[0], v0[0], p0[1], v0[1]),
        Matrix::<4>::from_diagonal(&Vector::<4>::new(r[(0, 0)], 4.0, r[(1, 1)], 4.0)),
        0.0,
    )?;
    let mut out = Vec::new();
    for ((truth, fix), velocity) in run.truth.iter().zip(&run.fixes).zip(&run.odometry_velocities) {
        let prior = kf.predict(&x, &cv, truth.time_s)?;
        // [x, vx, y, vy] with H = I₄, or the velocity alone without a fix; its own linear model
        let observation = fused_observation(truth.time_s, &fix.map(Into::into), velocity, &r)?;
        x = kf.update(&prior, &observation, observation.z())?.state;
        out.push([x.mean()[0], x.mean()[2]]);
    }
    Ok(out)
}

/// Position-only state driven by the odometry velocity, corrected by the fixes.
fn control_input(run: &Seed004Run) -> Result<Vec<[f64; 2]>, Box<dyn std::error::Error>> {
    let kf = KalmanFilter::default();
    let fix_model = ComponentSelection::<2>::new(&[0, 1], NoiseCovariance::full(to_d(&run.fix_covariance_m2))?)?;
    let p0 = run.fixes.iter().flatten().next().ok_or("no fix")?;
    let mut x = Gaussian::new(Vector::<2>::new(p0[0], p0[1]), run.fix_covariance_m2, 0.0)?;
    let mut out = Vec::new();
    for ((truth, fix), (v, rv)) in run.truth.iter().zip(&run.fixes).zip(&run.odometry_velocities) {
        // x += Δt v_odo,  Q = Δt² R_v + q Δt I
        let model = OdometryDeadReckoning::new(*rv, 0.01)?;
        let prior = kf.predict_with_control(&x, &model, &DVector::from_column_slice(v.as_slice()), truth.time_s)?;
        x = match fix {
            Some(p) => kf.update(&prior, &fix_model, &DVector::from_column_slice(p))?.state,
            None => prior,
        };
        out.push([x.mean()[0], x.mean()[1]]);
    }
    Ok(out)
}

fn to_d(m: &Matrix2<f64>) -> DMatrix<f64> {
    DMatrix::from_column_slice(2, 2, m.as_slice())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let runs: u64 = std::env::args().nth(1).map(|s| s.parse()).transpose()?.unwrap_or(20);
    println!("Seed 004 odometry fusion, mean of per-run RMSE over {runs} runs:");
    for estimate in [true, false] {
        let config = Seed004Config {
            estimate_heading_drift: estimate,
            ..Seed004Config::default()
        };
        let mut sums = [0.0; 3];
        for seed in 0..runs {
            let run = run_seed_004(&config, seed)?;
            let truth = run.truth_positions();
            sums[0] += ErrorSummary::from_positions(&truth, &run.kf)?.rmse_m;
            sums[1] += ErrorSummary::from_positions(&truth, &velocity_measurement(&run)?)?.rmse_m;
            sums[2] += ErrorSummary::from_positions(&truth, &control_input(&run)?)?.rmse_m;
        }
        let n = runs as f64;
        let heading = if estimate {
            "drift estimated"
        } else {
            "drift as growing variance"
        };
        println!("  heading {heading}:");
        println!("    KF on fixes only                  {:6.1} m", sums[0] / n);
        println!("    odometry as velocity measurement  {:6.1} m", sums[1] / n);
        println!("    odometry as control input         {:6.1} m", sums[2] / n);
    }
    Ok(())
}
