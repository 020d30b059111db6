//! Signal space: how RSSI readings (and the absence of a reading) become comparable numbers,
//! and the distance between two fingerprints.

use core::cmp::Ordering;

use crate::error::{PositioningError, Result};

/// How a heard RSSI value `ρ` (dBm) is mapped to a non-negative number `ψ(ρ)` before
/// fingerprints are compared. **A reading that is absent is `ψ = 0`** in every representation,
/// which is what makes "not heard" an explicit, documented state rather than a magic RSSI.
///
/// Every representation has a floor `ρ_min` (dBm): the weakest reading the receivers report.
/// A heard reading below the floor is an error (it would mean "weaker than not heard").
///
/// | representation | `ψ(ρ)` for a heard reading | character |
/// |---|---|---|
/// | `Positive` | `ρ − ρ_min` | linear in dB (Euclidean on it = Euclidean on dBm with "not heard = ρ_min") |
/// | `Exponential` | `exp((ρ − ρ_min)/α) / exp(−ρ_min/α)` | strong readings dominate |
/// | `Powed` | `((ρ − ρ_min)/(−ρ_min))^β` | strong readings dominate, weak ones fade to 0 |
///
/// Torres-Sospedra et al. (2015) found the exponential and powed representations
/// (`α = 24`, `β = e`, `ρ_min = −104 dBm` on UJIIndoorLoc) markedly better than raw dBm for
/// multi-device Wi-Fi fingerprinting: weak readings, which differ most between phones, count
/// less.
///
/// # Units
/// `floor_dbm` in dBm, `alpha_db` in dB, `beta` dimensionless.
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::SignalRepresentation;
/// let powed = SignalRepresentation::Powed { floor_dbm: -104.0, beta: 1.0 };
/// assert_eq!(powed.value(-52.0)?, 0.5);
/// assert!(powed.value(-110.0).is_err()); // below the floor
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// J. Torres-Sospedra, R. Montoliu, S. Trilles, Ó. Belmonte, J. Huerta, "Comprehensive
/// analysis of distance and similarity measures for Wi-Fi fingerprinting indoor positioning
/// systems", *Expert Systems with Applications* 42(23), 2015, §3 (data representations).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SignalRepresentation {
    /// `ψ = ρ − ρ_min`.
    Positive {
        /// Floor `ρ_min` (dBm).
        floor_dbm: f64,
    },
    /// `ψ = exp((ρ − ρ_min)/α) / exp(−ρ_min/α)`.
    Exponential {
        /// Floor `ρ_min` (dBm, < 0).
        floor_dbm: f64,
        /// Scale `α` (dB, > 0).
        alpha_db: f64,
    },
    /// `ψ = ((ρ − ρ_min)/(−ρ_min))^β`.
    Powed {
        /// Floor `ρ_min` (dBm, < 0).
        floor_dbm: f64,
        /// Exponent `β` (> 0).
        beta: f64,
    },
}

impl SignalRepresentation {
    /// Torres-Sospedra's powed representation for Wi-Fi: `ρ_min = −104 dBm`, `β = e`.
    pub const POWED_WIFI: Self = Self::Powed {
        floor_dbm: -104.0,
        beta: core::f64::consts::E,
    };

    /// Checks the parameters.
    ///
    /// # Errors
    /// [`PositioningError::InvalidParameter`] naming `floor_dbm`, `alpha_db` or `beta`.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::SignalRepresentation;
    /// assert!(SignalRepresentation::Powed { floor_dbm: -104.0, beta: 0.0 }.validate().is_err());
    /// ```
    pub fn validate(&self) -> Result<()> {
        let floor_dbm = match *self {
            Self::Positive { floor_dbm } => {
                if !floor_dbm.is_finite() {
                    return Err(invalid("floor_dbm", "the floor must be a finite rssi in dBm"));
                }
                return Ok(());
            }
            Self::Exponential { floor_dbm, alpha_db } => {
                if !(alpha_db.is_finite() && alpha_db > 0.0) {
                    return Err(invalid("alpha_db", "the exponential scale must be positive and finite"));
                }
                floor_dbm
            }
            Self::Powed { floor_dbm, beta } => {
                if !(beta.is_finite() && beta > 0.0) {
                    return Err(invalid("beta", "the powed exponent must be positive and finite"));
                }
                floor_dbm
            }
        };
        if floor_dbm.is_finite() && floor_dbm < 0.0 {
            Ok(())
        } else {
            Err(invalid(
                "floor_dbm",
                "the exponential and powed representations need a finite negative floor in dBm",
            ))
        }
    }

    /// `ψ(ρ)` of a heard reading.
    ///
    /// # Errors
    /// [`PositioningError::NonFinite`] for a NaN/∞ reading;
    /// [`PositioningError::InvalidParameter`] (`rssi_dbm`) for a reading below the floor.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::SignalRepresentation;
    /// let positive = SignalRepresentation::Positive { floor_dbm: -100.0 };
    /// assert_eq!(positive.value(-60.0)?, 40.0);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    pub fn value(&self, rssi_dbm: f64) -> Result<f64> {
        if !rssi_dbm.is_finite() {
            return Err(PositioningError::NonFinite { what: "rssi reading" });
        }
        if rssi_dbm < self.floor_dbm() {
            return Err(invalid(
                "rssi_dbm",
                "a heard reading is below the representation's floor_dbm; lower the floor to the receivers' weakest reading",
            ));
        }
        self.value_above_floor(rssi_dbm)
    }

    /// `ψ(ρ)` of a finite reading at or above the floor (the caller has checked both).
    ///
    /// # Errors
    /// [`PositioningError::NonFinite`] if the representation overflows.
    pub(crate) fn value_above_floor(&self, rssi_dbm: f64) -> Result<f64> {
        let psi = match *self {
            // ψ = ρ − ρ_min
            Self::Positive { floor_dbm } => rssi_dbm - floor_dbm,
            // ψ = exp((ρ − ρ_min)/α) / exp(−ρ_min/α) = exp(ρ/α)
            Self::Exponential { alpha_db, .. } => (rssi_dbm / alpha_db).exp(),
            // ψ = ((ρ − ρ_min)/(−ρ_min))^β
            Self::Powed { floor_dbm, beta } => ((rssi_dbm - floor_dbm) / -floor_dbm).powf(beta),
        };
        if psi.is_finite() {
            Ok(psi)
        } else {
            Err(PositioningError::NonFinite {
                what: "represented rssi (reading too strong for the representation)",
            })
        }
    }

    /// The floor `ρ_min` (dBm).
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::fingerprint::SignalRepresentation;
    /// assert_eq!(SignalRepresentation::POWED_WIFI.floor_dbm(), -104.0);
    /// ```
    #[must_use]
    pub fn floor_dbm(&self) -> f64 {
        match *self {
            Self::Positive { floor_dbm } | Self::Exponential { floor_dbm, .. } | Self::Powed { floor_dbm, .. } => {
                floor_dbm
            }
        }
    }
}

/// The distance between two represented fingerprints `a`, `b` (one value per anchor,
/// `0` = not heard).
///
/// | distance | `D(a, b)` |
/// |---|---|
/// | `Euclidean` | `√Σ (a_x − b_x)²` |
/// | `Manhattan` | `Σ |a_x − b_x|` |
/// | `Sorensen` | `Σ |a_x − b_x| / Σ (a_x + b_x)` (Bray–Curtis; in `[0, 1]`) |
///
/// Seed 002 uses Euclidean on dBm (`Positive` representation). Sørensen with the powed
/// representation was the best pair for UJIIndoorLoc in Torres-Sospedra et al. (2015) and in
/// our evaluation (`docs/FINGERPRINTING.md`).
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::SignalDistance;
/// assert_eq!(SignalDistance::Manhattan, SignalDistance::Manhattan);
/// ```
///
/// # References
/// Seed 002 eq. (1); Torres-Sospedra et al. (2015), Table 1 (distance and similarity
/// functions).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SignalDistance {
    /// `√Σ (a_x − b_x)²`.
    Euclidean,
    /// `Σ |a_x − b_x|`.
    Manhattan,
    /// `Σ |a_x − b_x| / Σ (a_x + b_x)`.
    Sorensen,
}

/// A representation and a distance: the geometry of signal space.
///
/// [`Default`] is seed 002's: Euclidean on dBm with the floor at −150 dBm (seed 002's anchors
/// are all heard, so the floor only matters for absent readings). **Where anchors can be
/// missed, set the floor to the receivers' sensitivity**: "not heard" is compared as the floor,
/// and a floor far below the sensitivity turns every anchor missed by a little into a large
/// distance (on a 520-anchor grid site the mean error rose from 2.3 m to 9.2 m with −150 dBm
/// against a −85 dBm sensitivity, `docs/FINGERPRINTING.md`).
///
/// # Example
/// ```
/// use rtls_positioning::fingerprint::{SignalDistance, SignalRepresentation, SignalSpace};
/// let wifi = SignalSpace::powed_sorensen();
/// assert_eq!(wifi.distance, SignalDistance::Sorensen);
/// assert_eq!(wifi.representation, SignalRepresentation::POWED_WIFI);
/// ```
///
/// # References
/// Seed 002 §1.2; Torres-Sospedra et al. (2015).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SignalSpace {
    /// How readings are represented.
    pub representation: SignalRepresentation,
    /// How represented fingerprints are compared.
    pub distance: SignalDistance,
}

impl Default for SignalSpace {
    fn default() -> Self {
        Self {
            representation: SignalRepresentation::Positive { floor_dbm: -150.0 },
            distance: SignalDistance::Euclidean,
        }
    }
}

impl SignalSpace {
    /// Powed representation (`ρ_min = −104 dBm`, `β = e`) with the Sørensen distance: the
    /// recommended space for multi-device Wi-Fi fingerprinting.
    #[must_use]
    pub fn powed_sorensen() -> Self {
        Self {
            representation: SignalRepresentation::POWED_WIFI,
            distance: SignalDistance::Sorensen,
        }
    }
}

/// A sparse represented fingerprint: `(anchor, ψ)` for the heard anchors, increasing anchor.
pub(crate) type SparseFingerprint = [(u32, f64)];

/// Distance between two sparse fingerprints (increasing anchor, absent = 0), and whether they
/// share at least one heard anchor. One merge pass over both lists.
pub(crate) fn sparse_distance(distance: SignalDistance, a: &SparseFingerprint, b: &SparseFingerprint) -> (f64, bool) {
    let (mut i, mut j) = (0, 0);
    // Σ (a−b)², Σ |a−b|, Σ (a+b)
    let (mut squares, mut absolutes, mut totals) = (0.0, 0.0, 0.0);
    let mut shared = false;
    while i < a.len() || j < b.len() {
        let (va, vb) = match (a.get(i), b.get(j)) {
            (Some(&(xa, va)), Some(&(xb, vb))) => match xa.cmp(&xb) {
                Ordering::Less => {
                    i += 1;
                    (va, 0.0)
                }
                Ordering::Greater => {
                    j += 1;
                    (0.0, vb)
                }
                Ordering::Equal => {
                    i += 1;
                    j += 1;
                    shared = true;
                    (va, vb)
                }
            },
            (Some(&(_, va)), None) => {
                i += 1;
                (va, 0.0)
            }
            (None, Some(&(_, vb))) => {
                j += 1;
                (0.0, vb)
            }
            (None, None) => break,
        };
        let d = va - vb;
        squares += d * d;
        absolutes += d.abs();
        totals += va + vb;
    }
    let value = match distance {
        SignalDistance::Euclidean => squares.sqrt(),
        SignalDistance::Manhattan => absolutes,
        // Σ|a−b| / Σ(a+b); two empty fingerprints are identical
        SignalDistance::Sorensen => {
            if totals > 0.0 {
                absolutes / totals
            } else {
                0.0
            }
        }
    };
    (value, shared)
}

fn invalid(name: &'static str, reason: &'static str) -> PositioningError {
    PositioningError::InvalidParameter { name, reason }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dense(sparse: &SparseFingerprint, n: usize) -> Vec<f64> {
        let mut v = vec![0.0; n];
        for &(x, value) in sparse {
            v[x as usize] = value;
        }
        v
    }

    #[test]
    fn sparse_distances_equal_the_dense_formulas() {
        let a = [(0, 3.0), (2, 1.0), (5, 4.0)];
        let b = [(1, 2.0), (2, 3.0), (6, 1.0)];
        let (da, db) = (dense(&a, 7), dense(&b, 7));
        let euclid = da.iter().zip(&db).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt();
        let manhattan: f64 = da.iter().zip(&db).map(|(x, y)| (x - y).abs()).sum();
        let total: f64 = da.iter().zip(&db).map(|(x, y)| x + y).sum();
        let (e, shared) = sparse_distance(SignalDistance::Euclidean, &a, &b);
        assert!(shared);
        assert!((e - euclid).abs() < 1e-12);
        assert!((sparse_distance(SignalDistance::Manhattan, &a, &b).0 - manhattan).abs() < 1e-12);
        assert!((sparse_distance(SignalDistance::Sorensen, &a, &b).0 - manhattan / total).abs() < 1e-12);
        let (_, shared) = sparse_distance(SignalDistance::Euclidean, &[(0, 1.0)], &[(1, 1.0)]);
        assert!(!shared);
        assert_eq!(sparse_distance(SignalDistance::Sorensen, &[], &[]), (0.0, false));
    }

    #[test]
    fn representations_follow_their_formulas_and_reject_bad_input() {
        let exp = SignalRepresentation::Exponential {
            floor_dbm: -104.0,
            alpha_db: 24.0,
        };
        let v = exp.value(-50.0).unwrap();
        assert!((v - ((54.0f64 / 24.0).exp() / (104.0f64 / 24.0).exp())).abs() < 1e-15);
        let powed = SignalRepresentation::POWED_WIFI;
        assert!((powed.value(-104.0).unwrap()).abs() < 1e-300);
        assert!((powed.value(0.0).unwrap() - 1.0).abs() < 1e-15);
        assert!(matches!(
            powed.value(-105.0),
            Err(PositioningError::InvalidParameter { name: "rssi_dbm", .. })
        ));
        assert!(powed.value(f64::NAN).is_err());
        assert!(SignalRepresentation::Positive { floor_dbm: f64::NAN }
            .validate()
            .is_err());
        assert!(SignalRepresentation::Powed {
            floor_dbm: 10.0,
            beta: 2.0
        }
        .validate()
        .is_err());
        assert!(SignalRepresentation::Exponential {
            floor_dbm: -100.0,
            alpha_db: -1.0
        }
        .validate()
        .is_err());
        assert!(SignalSpace::default().representation.validate().is_ok());
        assert!(SignalSpace::powed_sorensen().representation.validate().is_ok());
    }
}
