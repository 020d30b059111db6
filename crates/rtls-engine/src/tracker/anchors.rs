//! The site's readers as the tracker uses them: id → position, state and radio parameters, and
//! the conversion of a record's anchor measurement into a resolved [`AnchorReading`].

use std::collections::HashMap;

use crate::record::Measurement;
use crate::site::{Reader, Site};

/// Radio parameters of one anchor.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Anchor {
    pub(crate) id: String,
    pub(crate) position_m: [f64; 3],
    pub(crate) working: bool,
    /// `σ_r`, m (from `radio.range`).
    pub(crate) range_std_m: Option<f64>,
    /// Constant range bias removed from every range, m.
    pub(crate) range_bias_m: f64,
    /// Range scale the bias-corrected range is divided by (1: none).
    pub(crate) range_scale: f64,
    /// `(ρ₀ dBm, d₀ m, n, σ_X dB)` of the log-distance law.
    pub(crate) path_loss: Option<[f64; 4]>,
    /// The weakest RSSI the reader reports, dBm (negative information).
    pub(crate) sensitivity_dbm: Option<f64>,
}

impl Anchor {
    fn from_reader(reader: &Reader) -> Self {
        let radio = reader.radio.as_ref();
        let range = radio.and_then(|r| r.range.as_ref());
        Self {
            id: reader.id.clone(),
            position_m: reader.position_xyz_m(),
            working: reader.working,
            range_std_m: range.map(|r| r.range_std_m),
            range_bias_m: range.map_or(0.0, |r| r.bias_m),
            range_scale: range.map_or(1.0, |r| r.scale),
            path_loss: radio.and_then(|r| r.path_loss.as_ref()).map(|p| {
                [
                    p.reference_power_dbm,
                    p.reference_distance_m,
                    p.exponent,
                    p.shadowing_std_db,
                ]
            }),
            sensitivity_dbm: radio.and_then(|r| r.sensitivity_dbm),
        }
    }
}

/// A resolved anchor measurement: anchor indices, bias-corrected value and its variance.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) enum AnchorReading {
    /// Bias- and scale-corrected range `(r − b) / s` (m), variance m², to the anchor at `position_m` (the
    /// reader's site position, or the record's for a moving anchor).
    Range {
        anchor: usize,
        position_m: [f64; 3],
        range_m: f64,
        variance_m2: f64,
    },
    /// RSSI (dBm), shadowing variance dB².
    Rssi {
        anchor: usize,
        rssi_dbm: f64,
        /// The reader's law `[ρ₀ dBm, d₀ m, n, σ_X dB]`.
        law: [f64; 4],
        variance_db2: f64,
    },
    /// `‖p − anchor‖ − ‖p − reference‖` (m), variance m².
    Tdoa {
        anchor: usize,
        reference: usize,
        range_difference_m: f64,
        variance_m2: f64,
    },
}

impl AnchorReading {
    /// The reader it came from.
    pub(crate) fn anchor(&self) -> usize {
        match *self {
            Self::Range { anchor, .. } | Self::Rssi { anchor, .. } | Self::Tdoa { anchor, .. } => anchor,
        }
    }
}

/// Anchors whose plan positions spread less than this across their line, as a share of their
/// spread along it, are taken as a line: a fix from their ranges alone has two mirror images
/// across it.
const LINE_SPREAD_RATIO: f64 = 0.1;

/// `[λ₁, λ₂]`, `λ₁ ≥ λ₂`, of the scatter of `points` (plan positions, m):
///
/// ```text
/// S = Σ (p − p̄)(p − p̄)ᵀ,   λ₁,₂ = (sₓₓ + s_yy)/2 ± √(((sₓₓ − s_yy)/2)² + sₓ_y²)
/// ```
fn plan_scatter(points: &[[f64; 2]]) -> [f64; 2] {
    if points.is_empty() {
        return [0.0, 0.0];
    }
    let n = points.len() as f64;
    // p̄
    let mean = points
        .iter()
        .fold([0.0, 0.0], |m, p| [m[0] + p[0] / n, m[1] + p[1] / n]);
    // sₓₓ, s_yy, sₓ_y
    let (sxx, syy, sxy) = points.iter().fold((0.0, 0.0, 0.0), |(xx, yy, xy), p| {
        let (dx, dy) = (p[0] - mean[0], p[1] - mean[1]);
        (xx + dx * dx, yy + dy * dy, xy + dx * dy)
    });
    let half_trace = 0.5 * (sxx + syy);
    let root = (0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy).sqrt();
    [half_trace + root, (half_trace - root).max(0.0)]
}

/// `√(λ₂ / λ₁)` of the scatter of `points` (plan positions, m; see [`plan_scatter`]): 0 for
/// points on a line (or fewer than two distinct), 1 for a spread equal in every direction.
pub(crate) fn plan_spread_ratio(points: &[[f64; 2]]) -> f64 {
    let [largest, smallest] = plan_scatter(points);
    if largest > 0.0 {
        (smallest / largest).sqrt()
    } else {
        0.0
    }
}

/// How far below anchors that hang at one height a 3-D fix starts, m: only the side of their
/// plane matters (the fix's two mirror images lie on either side), and tags are carried below
/// the anchors.
const BELOW_ANCHORS_M: f64 = 1.5;

/// A start for a 3-D fix from anchors at `points` (m) when they hang at one height (their
/// heights' spread `σ_z` below [`LINE_SPREAD_RATIO`] × their plan spread `√(λ₁/n)`): the
/// anchors' plan centroid, [`BELOW_ANCHORS_M`] under their mean height. `None` when their
/// heights spread enough to tell the sides apart, or for fewer than three.
pub(crate) fn start_below_plane(points: &[[f64; 3]]) -> Option<[f64; 3]> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let mean = points
        .iter()
        .fold([0.0; 3], |m, p| [m[0] + p[0] / n, m[1] + p[1] / n, m[2] + p[2] / n]);
    // σ_z = √(Σ (z − z̄)² / n), plan spread √(λ₁ / n)
    let z_std = (points.iter().map(|p| (p[2] - mean[2]).powi(2)).sum::<f64>() / n).sqrt();
    let plan: Vec<[f64; 2]> = points.iter().map(|p| [p[0], p[1]]).collect();
    let plan_std = (plan_scatter(&plan)[0] / n).sqrt();
    (z_std < LINE_SPREAD_RATIO * plan_std).then(|| [mean[0], mean[1], mean[2] - BELOW_ANCHORS_M])
}

/// Whether plan positions lie (nearly) on one line ([`LINE_SPREAD_RATIO`]).
pub(crate) fn on_a_line(points: &[[f64; 2]]) -> bool {
    plan_spread_ratio(points) < LINE_SPREAD_RATIO
}

/// All readers of a site, indexed by id.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Anchors {
    by_id: HashMap<String, usize>,
    list: Vec<Anchor>,
    /// Whether the working anchors lie on one line in plan (a drift's, a corridor's): then no
    /// set of them resolves the mirror ambiguity, and a track starts from what it hears.
    working_on_a_line: bool,
    /// The working anchors' RMS spread along their widest plan axis, `√(λ₁ / n)`, m (0 for
    /// fewer than two distinct).
    working_plan_spread_m: f64,
}

impl Anchors {
    pub(crate) fn new(site: &Site) -> Self {
        let list: Vec<Anchor> = site.readers.iter().map(Anchor::from_reader).collect();
        let by_id = list.iter().enumerate().map(|(i, a)| (a.id.clone(), i)).collect();
        let working: Vec<[f64; 2]> = list
            .iter()
            .filter(|a| a.working)
            .map(|a| [a.position_m[0], a.position_m[1]])
            .collect();
        let working_plan_spread_m = if working.is_empty() {
            0.0
        } else {
            (plan_scatter(&working)[0] / working.len() as f64).sqrt()
        };
        Self {
            by_id,
            list,
            working_on_a_line: on_a_line(&working),
            working_plan_spread_m,
        }
    }

    /// The working anchors' RMS spread along their widest plan axis, `√(λ₁ / n)`, m: a fix
    /// whose standard deviation exceeds it says no more than "among the anchors".
    pub(crate) fn working_plan_spread_m(&self) -> f64 {
        self.working_plan_spread_m
    }

    /// Whether the site's working anchors lie on one line in plan.
    pub(crate) fn working_on_a_line(&self) -> bool {
        self.working_on_a_line
    }

    /// The position of `reading`'s anchor, m (the record's own for a moving anchor's range).
    pub(crate) fn position(&self, reading: &AnchorReading) -> [f64; 3] {
        match *reading {
            AnchorReading::Range { position_m, .. } => position_m,
            other => self.list[other.anchor()].position_m,
        }
    }

    /// The plan position of `reading`'s anchor (the record's own for a moving anchor's range).
    pub(crate) fn plan_position(&self, reading: &AnchorReading) -> [f64; 2] {
        let position_m = self.position(reading);
        [position_m[0], position_m[1]]
    }

    pub(crate) fn get(&self, index: usize) -> &Anchor {
        &self.list[index]
    }

    /// Every anchor, in site order (the index is the anchor's).
    pub(crate) fn iter(&self) -> impl Iterator<Item = &Anchor> {
        self.list.iter()
    }

    /// The index of a working anchor, or why it cannot be used.
    fn working(&self, id: &str) -> Result<usize, String> {
        let index = *self
            .by_id
            .get(id)
            .ok_or_else(|| format!("anchor `{id}` is not a reader of the site"))?;
        if self.list[index].working {
            Ok(index)
        } else {
            Err(format!("reader `{id}` is marked broken (working = false)"))
        }
    }

    /// Checks that every anchor id of `measurement` is a reader of the site; returns the field
    /// and reason of the first unknown one.
    pub(crate) fn check_ids(&self, measurement: &Measurement) -> Result<(), (String, String)> {
        let known = |field: &str, id: &str| {
            if self.by_id.contains_key(id) {
                Ok(())
            } else {
                Err((field.to_string(), format!("`{id}` is not a reader of the site")))
            }
        };
        match measurement {
            Measurement::Range { anchor, .. } | Measurement::Rssi { anchor, .. } => known("anchor", anchor),
            Measurement::Tdoa { anchor, reference, .. } => {
                known("anchor", anchor)?;
                known("reference", reference)
            }
            Measurement::RssiVector { readings } => {
                for (i, reading) in readings.iter().enumerate() {
                    known(&format!("readings[{i}].anchor"), &reading.anchor)?;
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }

    /// Resolves a range / RSSI / TDOA measurement (anything else is `Ok(None)`).
    ///
    /// # Errors
    /// A reason when an anchor is unknown or broken, or when no noise level is known (no
    /// `std_m` in the record and no `radio.range` / `radio.path_loss` in the site).
    pub(crate) fn resolve(&self, measurement: &Measurement) -> Result<Option<AnchorReading>, String> {
        match measurement {
            Measurement::Range {
                anchor,
                range_m,
                std_m,
                anchor_position_m,
            } => {
                let index = self.working(anchor)?;
                let a = &self.list[index];
                // a moving anchor's position in the record; a 2-D one keeps the reader's height
                let position_m = match anchor_position_m.as_deref() {
                    Some([x, y]) => [*x, *y, a.position_m[2]],
                    Some([x, y, z]) => [*x, *y, *z],
                    Some(_) => return Err("`anchor_position_m` must have 2 or 3 components".to_string()),
                    None => a.position_m,
                };
                let std_m = std_m.or(a.range_std_m).ok_or_else(|| {
                    format!("no range noise: give `std_m` in the record or `radio.range` for reader `{anchor}`")
                })?;
                Ok(Some(AnchorReading::Range {
                    anchor: index,
                    position_m,
                    // (r − b) / s, σ² / s²
                    range_m: (range_m - a.range_bias_m) / a.range_scale,
                    variance_m2: floor_variance(std_m * std_m / (a.range_scale * a.range_scale)),
                }))
            }
            Measurement::Rssi { anchor, rssi_dbm } => {
                let index = self.working(anchor)?;
                let law = self.list[index]
                    .path_loss
                    .ok_or_else(|| format!("RSSI needs `radio.path_loss` for reader `{anchor}` in the site"))?;
                Ok(Some(AnchorReading::Rssi {
                    anchor: index,
                    rssi_dbm: *rssi_dbm,
                    law,
                    variance_db2: floor_variance(law[3] * law[3]),
                }))
            }
            Measurement::Tdoa {
                anchor,
                reference,
                range_difference_m,
                std_m,
            } => {
                let a = self.working(anchor)?;
                let b = self.working(reference)?;
                let std_m = std_m
                    .or_else(|| {
                        // σ_Δr² = σ_a² + σ_b² from the readers' range noise
                        let (sa, sb) = (self.list[a].range_std_m?, self.list[b].range_std_m?);
                        Some((sa * sa + sb * sb).sqrt())
                    })
                    .ok_or_else(|| {
                        format!(
                            "no TDOA noise: give `std_m` in the record or `radio.range` for readers \
                             `{anchor}` and `{reference}`"
                        )
                    })?;
                Ok(Some(AnchorReading::Tdoa {
                    anchor: a,
                    reference: b,
                    // range biases cancel only if equal: Δr − (b_a − b_b)
                    range_difference_m: range_difference_m - (self.list[a].range_bias_m - self.list[b].range_bias_m),
                    variance_m2: floor_variance(std_m * std_m),
                }))
            }
            _ => Ok(None),
        }
    }
}

/// A zero standard deviation would make `S` singular: floor variances at (1 mm)² / (0.01 dB)².
fn floor_variance(variance: f64) -> f64 {
    variance.max(1e-6)
}
