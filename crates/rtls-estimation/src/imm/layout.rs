//! State layouts (what each entry of a mode's state means) and the explicit conversions
//! between layouts that let an IMM mix modes of different state size.

use alloc::vec::Vec;

use nalgebra::{DMatrix, DVector};

use crate::error::{EstimationError, Result};

/// A Cartesian axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Axis {
    /// x (m).
    X,
    /// y (m).
    Y,
    /// z (m).
    Z,
}

/// The physical meaning of one state entry.
///
/// # Units
/// Position m, velocity m/s, acceleration m/s², turn rate rad/s.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Component {
    /// Position along an axis (m).
    Position(Axis),
    /// Velocity along an axis (m/s).
    Velocity(Axis),
    /// Acceleration along an axis (m/s²).
    Acceleration(Axis),
    /// Turn rate of a coordinated turn (rad/s, counter-clockwise positive).
    TurnRate,
}

/// The ordered list of [`Component`]s of a state vector: which physical quantity each entry is.
///
/// Layouts make conversions between models explicit: a constant-velocity state
/// `[x, vx, y, vy]` and a constant-acceleration state `[x, vx, y, vy, ax, ay]` share their
/// first four components; the CA state's accelerations have no counterpart in the CV state,
/// and [`convert`] says what fills them.
///
/// # Example
/// ```
/// use rtls_estimation::imm::{Axis, Component, StateLayout};
/// let ca = StateLayout::ca_2d();
/// assert_eq!(ca.len(), 6);
/// assert_eq!(ca.index_of(Component::Acceleration(Axis::Y)), Some(5));
/// assert_eq!(StateLayout::cv_2d().index_of(Component::TurnRate), None);
/// assert!(StateLayout::new(vec![Component::TurnRate, Component::TurnRate]).is_err());
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct StateLayout {
    components: Vec<Component>,
}

impl StateLayout {
    /// A layout from its components, in state order.
    ///
    /// # Errors
    /// [`EstimationError::InvalidParameter`] if the list is empty or names a component twice.
    pub fn new(components: Vec<Component>) -> Result<Self> {
        if components.is_empty() {
            return Err(EstimationError::InvalidParameter {
                name: "layout",
                reason: "a state layout needs at least one component",
            });
        }
        for (i, c) in components.iter().enumerate() {
            if components[..i].contains(c) {
                return Err(EstimationError::InvalidParameter {
                    name: "layout",
                    reason: "a component appears twice in the state layout",
                });
            }
        }
        Ok(Self { components })
    }

    /// Planar position `[x, y]`.
    #[must_use]
    pub fn position_2d() -> Self {
        Self {
            components: alloc::vec![Component::Position(Axis::X), Component::Position(Axis::Y)],
        }
    }

    /// Planar constant velocity `[x, vx, y, vy]` ([`crate::motion::ConstantVelocity`] with
    /// `N = 4`; seed 004 eq. (8)).
    #[must_use]
    pub fn cv_2d() -> Self {
        Self {
            components: alloc::vec![
                Component::Position(Axis::X),
                Component::Velocity(Axis::X),
                Component::Position(Axis::Y),
                Component::Velocity(Axis::Y),
            ],
        }
    }

    /// Planar constant acceleration `[x, vx, y, vy, ax, ay]`
    /// ([`crate::motion::ConstantAcceleration`] with `N = 6`; seed 004 eq. (10)).
    #[must_use]
    pub fn ca_2d() -> Self {
        let mut layout = Self::cv_2d();
        layout.components.push(Component::Acceleration(Axis::X));
        layout.components.push(Component::Acceleration(Axis::Y));
        layout
    }

    /// Planar coordinated turn with the rate as a state `[x, vx, y, vy, ω]`
    /// ([`crate::motion::CoordinatedTurnWithRate`]).
    #[must_use]
    pub fn ct_2d() -> Self {
        let mut layout = Self::cv_2d();
        layout.components.push(Component::TurnRate);
        layout
    }

    /// Spatial constant velocity `[x, vx, y, vy, z, vz]`.
    #[must_use]
    pub fn cv_3d() -> Self {
        let mut layout = Self::cv_2d();
        layout.components.push(Component::Position(Axis::Z));
        layout.components.push(Component::Velocity(Axis::Z));
        layout
    }

    /// Spatial constant acceleration `[x, vx, y, vy, z, vz, ax, ay, az]`.
    #[must_use]
    pub fn ca_3d() -> Self {
        let mut layout = Self::cv_3d();
        layout.components.push(Component::Acceleration(Axis::X));
        layout.components.push(Component::Acceleration(Axis::Y));
        layout.components.push(Component::Acceleration(Axis::Z));
        layout
    }

    /// The components in state order.
    #[must_use]
    pub fn components(&self) -> &[Component] {
        &self.components
    }

    /// Number of state entries.
    #[must_use]
    pub fn len(&self) -> usize {
        self.components.len()
    }

    /// Always `false` (a layout has at least one component); here for API completeness.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.components.is_empty()
    }

    /// The state index of `component`, if the layout has it.
    #[must_use]
    pub fn index_of(&self, component: Component) -> Option<usize> {
        self.components.iter().position(|&c| c == component)
    }
}

/// What fills the components of the target layout that the source estimate lacks.
#[derive(Debug, Clone, Copy)]
pub enum Fill<'a> {
    /// Zero mean and zero variance: what the source model asserts (a CV model says the
    /// acceleration is zero, a straight-line model that the turn rate is zero). Used for the
    /// combined output of an IMM.
    Zero,
    /// Mean and (co)variance of the missing components taken from another estimate in the target
    /// layout (`mean`, `covariance`), uncorrelated with the converted components. In IMM mixing
    /// this is the target mode's own previous estimate ("unbiased mixing"), so a CA mode does
    /// not see its acceleration estimate dragged to zero by a CV mode's assertion.
    From {
        /// Mean in the target layout.
        mean: &'a DVector<f64>,
        /// Covariance in the target layout.
        covariance: &'a DMatrix<f64>,
    },
}

/// Converts an estimate `(mean, covariance)` from layout `from` into layout `to`.
///
/// ```text
/// shared components:   x_to[i] = x_from[s(i)],   P_to[i, j] = P_from[s(i), s(j)]
/// missing components:  from `fill` (zero, or the fill estimate's entries; cross terms 0)
/// dropped components:  marginalised out (exact for a Gaussian)
/// ```
/// `s(i)` is the index in `from` of the component at index `i` of `to`.
///
/// # Errors
/// [`EstimationError::DimensionMismatch`] if the mean, covariance or fill do not have their
/// layout's size.
///
/// # Example
/// ```
/// use rtls_estimation::imm::{convert, Fill, StateLayout};
/// use nalgebra::{DMatrix, DVector};
/// // CV [x, vx, y, vy] → CA [x, vx, y, vy, ax, ay]: accelerations asserted zero.
/// let cv_mean = DVector::from_vec(vec![1.0, 2.0, 3.0, 4.0]);
/// let cv_cov = DMatrix::identity(4, 4);
/// let (m, p) = convert(&cv_mean, &cv_cov, &StateLayout::cv_2d(), &StateLayout::ca_2d(), Fill::Zero)?;
/// assert_eq!(m.as_slice(), &[1.0, 2.0, 3.0, 4.0, 0.0, 0.0]);
/// assert_eq!(p[(5, 5)], 0.0);
/// // and back: the accelerations are marginalised out.
/// let (back, _) = convert(&m, &p, &StateLayout::ca_2d(), &StateLayout::cv_2d(), Fill::Zero)?;
/// assert_eq!(back, cv_mean);
/// # Ok::<(), rtls_estimation::EstimationError>(())
/// ```
///
/// # References
/// K. Granström, P. Willett, Y. Bar-Shalom, "Systematic approach to IMM mixing for unequal
/// dimension states", *IEEE Trans. Aerospace and Electronic Systems* 51(4), 2015 (zero
/// padding is biased; fill from the target mode's own estimate).
pub fn convert(
    mean: &DVector<f64>,
    covariance: &DMatrix<f64>,
    from: &StateLayout,
    to: &StateLayout,
    fill: Fill<'_>,
) -> Result<(DVector<f64>, DMatrix<f64>)> {
    check_estimate(mean, covariance, from.len(), "converted estimate")?;
    if let Fill::From { mean, covariance } = fill {
        check_estimate(mean, covariance, to.len(), "fill estimate")?;
    }
    let source: Vec<Option<usize>> = to.components().iter().map(|&c| from.index_of(c)).collect();
    let n = to.len();
    let mut out_mean = DVector::zeros(n);
    let mut out_cov = DMatrix::zeros(n, n);
    for i in 0..n {
        match (source[i], fill) {
            // x_to[i] = x_from[s(i)]
            (Some(si), _) => out_mean[i] = mean[si],
            (None, Fill::From { mean: fill_mean, .. }) => out_mean[i] = fill_mean[i],
            (None, Fill::Zero) => {}
        }
        for j in 0..n {
            out_cov[(i, j)] = match (source[i], source[j], fill) {
                // P_to[i, j] = P_from[s(i), s(j)]
                (Some(si), Some(sj), _) => covariance[(si, sj)],
                // missing × missing: the fill's own block
                (
                    None,
                    None,
                    Fill::From {
                        covariance: fill_cov, ..
                    },
                ) => fill_cov[(i, j)],
                // cross terms between converted and filled entries, and zero fill
                _ => 0.0,
            };
        }
    }
    Ok((out_mean, out_cov))
}

/// Checks that a dynamic estimate has `n` entries and a square `n × n` covariance.
pub(crate) fn check_estimate(
    mean: &DVector<f64>,
    covariance: &DMatrix<f64>,
    n: usize,
    what: &'static str,
) -> Result<()> {
    if mean.len() != n {
        return Err(EstimationError::DimensionMismatch {
            what,
            expected: n,
            found: mean.len(),
        });
    }
    if covariance.nrows() != n || covariance.ncols() != n {
        return Err(EstimationError::DimensionMismatch {
            what,
            expected: n,
            found: covariance.nrows(),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversion_from_ct_to_ca_fills_acceleration_and_drops_turn_rate() {
        let ct_mean = DVector::from_vec(alloc::vec![1.0, 2.0, 3.0, 4.0, 0.1]);
        let mut ct_cov = DMatrix::identity(5, 5);
        ct_cov[(0, 4)] = 0.3;
        ct_cov[(4, 0)] = 0.3;
        ct_cov[(1, 3)] = 0.2;
        ct_cov[(3, 1)] = 0.2;
        let fill_mean = DVector::from_vec(alloc::vec![9.0, 9.0, 9.0, 9.0, 0.5, -0.5]);
        let fill_cov = DMatrix::from_diagonal_element(6, 6, 7.0);
        let (m, p) = convert(
            &ct_mean,
            &ct_cov,
            &StateLayout::ct_2d(),
            &StateLayout::ca_2d(),
            Fill::From {
                mean: &fill_mean,
                covariance: &fill_cov,
            },
        )
        .unwrap();
        assert_eq!(m.as_slice(), &[1.0, 2.0, 3.0, 4.0, 0.5, -0.5]);
        assert_eq!(p[(1, 3)], 0.2);
        assert_eq!(p[(4, 4)], 7.0);
        assert_eq!(p[(0, 4)], 0.0, "filled entries are uncorrelated with converted ones");
        assert_eq!(p.nrows(), 6);
    }

    #[test]
    fn conversion_rejects_wrong_sizes() {
        let mean = DVector::zeros(3);
        let cov = DMatrix::identity(3, 3);
        let err = convert(&mean, &cov, &StateLayout::cv_2d(), &StateLayout::ca_2d(), Fill::Zero);
        assert!(matches!(
            err,
            Err(EstimationError::DimensionMismatch {
                expected: 4,
                found: 3,
                ..
            })
        ));
    }
}
