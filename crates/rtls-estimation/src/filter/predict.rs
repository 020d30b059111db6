//! The prediction step's pieces shared by the KF, the EKF and the UKF.

use nalgebra::DVector;

use crate::error::{EstimationError, Result};
use crate::gaussian::Vector;
use crate::motion::ControlGain;

/// `B u` with a size check of `u`.
pub(crate) fn control_effect<const N: usize>(b: &ControlGain<N>, control: &DVector<f64>) -> Result<Vector<N>> {
    if b.ncols() != control.len() {
        return Err(EstimationError::DimensionMismatch {
            what: "control input",
            expected: b.ncols(),
            found: control.len(),
        });
    }
    crate::math::ensure_finite(control, "control input")?;
    Ok(b * control)
}
