//! The reader layer of a mine personnel-location system (seed 000): fixed readers that hear
//! 2.4 GHz active tags through a log-distance law with log-normal shadowing and a sensitivity
//! threshold, readers broken by a collapse, and the two positioning methods the paper runs at
//! this layer — RSSI multilateration and range-free DV-Hop.
//!
//! A tag no working reader hears gives **no detection at all**, so both positioning methods
//! return an empty location (`None`): seed 000's "empty location" counted by the PEL.

use rand::Rng;
use rand_distr::StandardNormal;
use rtls_positioning::multilateration::{gauss_newton, GaussNewtonOptions, Initial};
use rtls_positioning::pathloss::{DistanceEstimate, LogDistance, PathLossModel};
use rtls_positioning::range_free::{range_weighted_centroid, DvHop, DvHopOptions};
use rtls_positioning::PositioningError;

use crate::error::{finite, non_negative, Result, SimError};

/// Whether a reader answers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReaderStatus {
    /// Powered and connected: hears tags.
    Working,
    /// Destroyed or cut off (e.g. by a collapse): hears nothing.
    Broken,
}

/// A fixed reader: where it is, whether it works, and the extra attenuation of equipment parked
/// next to it (seed 000 Fig. 2: machinery near readers R2, R4, R5 acts as an obstacle).
///
/// # Units
/// `position_m` in m, `obstacle_loss_db` in dB (added to the path loss of every tag it hears).
#[derive(Debug, Clone, PartialEq)]
pub struct Reader {
    /// Label used in reports (e.g. "R7").
    pub name: String,
    /// Antenna position `[x, y, z]`, m.
    pub position_m: [f64; 3],
    /// Working or broken.
    pub status: ReaderStatus,
    /// Attenuation of obstacles next to the reader, dB (`≥ 0`; 0 for a clear site).
    pub obstacle_loss_db: f64,
}

/// The radio of the reader layer: the log-distance law with log-normal shadowing
/// (`ρ = ρ_T − 10 η lg(d/d₀) − L + X`, `X ~ N(0, σ_X²)`, `L` the excess loss of walls, debris and
/// obstacles) and the readers' sensitivity: a tag is heard only if `ρ ≥ S`.
///
/// # Units
/// dBm for `ρ`, `ρ_T` and `S`; m for distances; dB for `σ_X` and losses.
///
/// # Example
/// ```
/// use rtls_positioning::pathloss::LogDistance;
/// use rtls_sim::sensors::readers::ReaderRadio;
/// let radio = ReaderRadio::new(LogDistance::new(-50.0, 2.5, 1.0, 4.0)?, -85.0)?;
/// // the mean power equals the sensitivity at d₀ · 10^((ρ_T − S)/(10 η)) = 10^1.4 m
/// assert!((radio.median_detection_range_m() - 10f64.powf(1.4)).abs() < 1e-9);
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// Seed 000 §3.3 (tags out of every reader's range give empty locations); T. S. Rappaport,
/// *Wireless Communications*, 2nd ed., 2002, §4.9 (log-distance law, log-normal shadowing).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReaderRadio {
    law: LogDistance,
    sensitivity_dbm: f64,
}

impl ReaderRadio {
    /// A radio with path-loss law `law` and reader sensitivity `sensitivity_dbm`.
    ///
    /// # Errors
    /// [`SimError::NonFinite`] for a NaN/∞ sensitivity; [`SimError::InvalidParameter`]
    /// (`sensitivity_dbm`) if it is above the law's reference power (no tag would ever be
    /// heard beyond `d₀`).
    pub fn new(law: LogDistance, sensitivity_dbm: f64) -> Result<Self> {
        finite(sensitivity_dbm, "reader sensitivity")?;
        if sensitivity_dbm >= law.reference_rssi_dbm() {
            return Err(SimError::InvalidParameter {
                name: "sensitivity_dbm",
                reason: "the sensitivity must lie below the reference power ρ_T, or no tag is heard beyond d₀",
            });
        }
        Ok(Self { law, sensitivity_dbm })
    }

    /// The path-loss law (mean, inversion, shadowing).
    #[must_use]
    pub fn law(&self) -> &LogDistance {
        &self.law
    }

    /// Sensitivity `S`, dBm.
    #[must_use]
    pub fn sensitivity_dbm(&self) -> f64 {
        self.sensitivity_dbm
    }

    /// The distance at which the mean power equals the sensitivity, `d₀ · 10^((ρ_T − S)/(10 η))`
    /// (m): half the tags at this range are heard, in line of sight and without obstacles.
    #[must_use]
    pub fn median_detection_range_m(&self) -> f64 {
        // d₅₀ = d₀ · 10^((ρ_T − S)/(10 η))
        self.law.reference_distance_m()
            * 10f64.powf((self.law.reference_rssi_dbm() - self.sensitivity_dbm) / (10.0 * self.law.exponent()))
    }
}

/// One reader's report of a tag: which reader (index into the layer's readers) and the RSSI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// Index of the reader in [`ReaderLayer::readers`].
    pub reader: usize,
    /// Received signal strength, dBm (`≥` the sensitivity).
    pub rssi_dbm: f64,
}

/// How an RSSI fix was obtained, from the best case to the crudest fallback.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RssiFixKind {
    /// ≥ 4 readers spanning space: weighted Gauss–Newton started from the linear LS fix.
    Multilateration,
    /// 3 readers, or ≥ 4 nearly coplanar ones: Gauss–Newton started below the readers'
    /// weighted centroid (the tag is worn below the mounting height, which picks the side of
    /// the mirror ambiguity).
    GuidedMultilateration,
    /// 1–2 readers (too few for a 3-D fix): the range-weighted centroid of the readers.
    Centroid,
}

/// An RSSI position fix and how it was obtained.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RssiFix {
    /// Position `[x, y, z]`, m.
    pub position_m: [f64; 3],
    /// The method that produced it.
    pub kind: RssiFixKind,
}

/// The readers of a site and their radio: simulates detections and computes the reader-layer
/// fixes (RSSI multilateration, DV-Hop).
///
/// # Example
/// ```
/// use rand::SeedableRng;
/// use rtls_positioning::pathloss::LogDistance;
/// use rtls_sim::sensors::readers::{Reader, ReaderLayer, ReaderRadio, ReaderStatus};
/// let reader = |name: &str, x: f64, status| Reader { name: name.into(), position_m: [x, 1.8, 1.0], status, obstacle_loss_db: 0.0 };
/// let readers = vec![reader("R1", 0.0, ReaderStatus::Working), reader("R2", 12.0, ReaderStatus::Broken)];
/// let layer = ReaderLayer::new(readers, ReaderRadio::new(LogDistance::new(-50.0, 2.5, 1.0, 4.0)?, -85.0)?)?;
/// let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
/// let heard = layer.detect([11.0, 0.0, 0.0], &[0.0, 0.0], &mut rng)?;
/// assert!(heard.iter().all(|d| d.reader == 0)); // the broken reader hears nothing
/// let far = layer.detect([400.0, 0.0, 0.0], &[0.0, 0.0], &mut rng)?;
/// assert!(far.is_empty()); // out of range: an empty location
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct ReaderLayer {
    readers: Vec<Reader>,
    radio: ReaderRadio,
}

impl ReaderLayer {
    /// A layer of `readers` sharing `radio`.
    ///
    /// # Errors
    /// [`SimError::EmptyInput`] without readers; [`SimError::NonFinite`] for a NaN/∞ position;
    /// [`SimError::InvalidParameter`] (`obstacle_loss_db`) for a negative or non-finite loss.
    pub fn new(readers: Vec<Reader>, radio: ReaderRadio) -> Result<Self> {
        if readers.is_empty() {
            return Err(SimError::EmptyInput { what: "readers" });
        }
        for reader in &readers {
            for c in reader.position_m {
                finite(c, "reader position")?;
            }
            non_negative(
                reader.obstacle_loss_db,
                "obstacle_loss_db",
                "an obstacle attenuates: its loss must be finite and ≥ 0 dB",
            )?;
        }
        Ok(Self { readers, radio })
    }

    /// The readers, in index order.
    #[must_use]
    pub fn readers(&self) -> &[Reader] {
        &self.readers
    }

    /// The radio.
    #[must_use]
    pub fn radio(&self) -> &ReaderRadio {
        &self.radio
    }

    /// Simulates one epoch: each working reader `i` receives
    /// `ρ_i = μ(‖tag − r_i‖) − excess_loss_db[i] − obstacle_i + X_i` and reports it if `ρ_i ≥ S`.
    /// One shadowing draw per working reader, in reader order, so a seeded `rng` reproduces the
    /// epoch exactly.
    ///
    /// # Errors
    /// [`SimError::LengthMismatch`] unless `excess_loss_db` has one entry per reader;
    /// [`SimError::NonFinite`] for a NaN/∞ tag position or loss.
    pub fn detect(&self, tag_m: [f64; 3], excess_loss_db: &[f64], rng: &mut impl Rng) -> Result<Vec<Detection>> {
        if excess_loss_db.len() != self.readers.len() {
            return Err(SimError::LengthMismatch {
                what: "excess losses vs readers",
                expected: self.readers.len(),
                found: excess_loss_db.len(),
            });
        }
        for c in tag_m {
            finite(c, "tag position")?;
        }
        let sigma_db = self.radio.law.shadowing_std_db();
        let mut detections = Vec::new();
        for (i, (reader, &excess_db)) in self.readers.iter().zip(excess_loss_db).enumerate() {
            if reader.status == ReaderStatus::Broken {
                continue;
            }
            finite(excess_db, "excess loss")?;
            // μ = ρ_T − 10 η lg(d/d₀) − L − L_obstacle
            let mean_dbm = self.radio.law.mean_rssi_dbm(distance_m(tag_m, reader.position_m))
                - excess_db
                - reader.obstacle_loss_db;
            // ρ = μ + σ_X n,  n ~ N(0, 1)
            let rssi_dbm = mean_dbm + sigma_db * rng.sample::<f64, _>(StandardNormal);
            // heard only above the sensitivity
            if rssi_dbm >= self.radio.sensitivity_dbm {
                detections.push(Detection { reader: i, rssi_dbm });
            }
        }
        Ok(detections)
    }

    /// The RSSI fix of one epoch (seed 000's range-based baseline), or `None` when no reader
    /// heard the tag (an empty location).
    ///
    /// Ranges are the median (maximum-likelihood) inversions `d̂_i = μ⁻¹(ρ_i)` with variances
    /// `(s d̂_i)²`, `s = σ_X ln 10/(10 η)` (the log-normal range error to first order). Then, by
    /// the number of readers `n`:
    /// - `n ≥ 4`: weighted Gauss–Newton from the weighted linear LS fix
    ///   ([`RssiFixKind::Multilateration`]); if the readers are coplanar or the solver fails,
    ///   as for `n = 3`;
    /// - `n = 3`: Gauss–Newton from the range-weighted centroid lowered by `guess_below_m`
    ///   ([`RssiFixKind::GuidedMultilateration`]); if that fails, as for `n ≤ 2`;
    /// - `n ∈ {1, 2}`: the range-weighted centroid (`w_i = 1/d̂_i`) of the readers
    ///   ([`RssiFixKind::Centroid`]; one reader gives its own position, the cell of origin).
    ///
    /// # Errors
    /// [`SimError::Positioning`] for a detection naming no reader or an RSSI the law cannot
    /// invert; numerical failures of the solvers are not errors (they select the fallback).
    pub fn rssi_fix(
        &self,
        detections: &[Detection],
        guess_below_m: f64,
        options: &GaussNewtonOptions,
    ) -> Result<Option<RssiFix>> {
        if detections.is_empty() {
            return Ok(None);
        }
        let law = &self.radio.law;
        let s = law.log_range_std();
        let mut anchors_m = Vec::with_capacity(detections.len());
        let mut ranges_m = Vec::with_capacity(detections.len());
        let mut variances_m2 = Vec::with_capacity(detections.len());
        for d in detections {
            anchors_m.push(self.reader_position(d.reader)?);
            // d̂ = μ⁻¹(ρ)
            let range_m = law.estimate_distance_m(d.rssi_dbm, DistanceEstimate::Median)?;
            ranges_m.push(range_m);
            // σ_d² = (s d̂)²
            variances_m2.push((s * range_m).powi(2).max(1e-6));
        }
        // range-weighted centroid, w_i = 1/d̂_i
        let centroid = range_weighted_centroid(&anchors_m, &ranges_m, 1.0)?.position;
        if anchors_m.len() >= 4 {
            match gauss_newton(&anchors_m, &ranges_m, &variances_m2, Initial::Linear, options) {
                Ok(solution) => return Ok(Some(fix(solution.fix.position.into(), RssiFixKind::Multilateration))),
                Err(e) if is_numerical(&e) => {}
                Err(e) => return Err(e.into()),
            }
        }
        if anchors_m.len() >= 3 {
            let mut guess = centroid;
            // the tag is worn below the readers: start below their centroid
            guess.z -= guess_below_m;
            match gauss_newton(&anchors_m, &ranges_m, &variances_m2, Initial::Guess(guess), options) {
                Ok(solution) => {
                    return Ok(Some(fix(
                        solution.fix.position.into(),
                        RssiFixKind::GuidedMultilateration,
                    )))
                }
                Err(e) if is_numerical(&e) => {}
                Err(e) => return Err(e.into()),
            }
        }
        Ok(Some(fix(centroid.into(), RssiFixKind::Centroid)))
    }

    fn reader_position(&self, index: usize) -> Result<[f64; 3]> {
        self.readers
            .get(index)
            .map(|r| r.position_m)
            .ok_or(SimError::InvalidParameter {
                name: "detections",
                reason: "a detection names a reader index outside the layer",
            })
    }
}

fn fix(position_m: [f64; 3], kind: RssiFixKind) -> RssiFix {
    RssiFix { position_m, kind }
}

/// Solver failures that select a fallback rather than abort the run.
fn is_numerical(error: &PositioningError) -> bool {
    matches!(
        error,
        PositioningError::DegenerateGeometry { .. }
            | PositioningError::DidNotConverge { .. }
            | PositioningError::Underdetermined { .. }
            | PositioningError::NoConsistentSolution { .. }
            | PositioningError::NodeUnderdetermined { .. }
    )
}

/// DV-Hop over the reader network (seed 000's range-free baseline): the working readers are
/// the anchors, linked when they can talk to each other; each epoch the tag is one more node,
/// linked to the readers that heard it.
///
/// # Example
/// ```
/// use rtls_positioning::pathloss::LogDistance;
/// use rtls_positioning::range_free::DvHopOptions;
/// use rtls_sim::sensors::readers::{Detection, DvHopNetwork, Reader, ReaderLayer, ReaderRadio, ReaderStatus};
/// let at = |x: f64, y: f64, z: f64| Reader { name: String::new(), position_m: [x, y, z], status: ReaderStatus::Working, obstacle_loss_db: 0.0 };
/// let readers = vec![at(0.0, 0.0, 0.0), at(10.0, 0.0, 1.0), at(0.0, 10.0, 2.0), at(10.0, 10.0, 0.5)];
/// let layer = ReaderLayer::new(readers, ReaderRadio::new(LogDistance::new(-50.0, 2.5, 1.0, 4.0)?, -85.0)?)?;
/// let network = DvHopNetwork::new(&layer, &[(0, 1), (1, 3), (3, 2), (2, 0)], DvHopOptions::default())?;
/// let heard = [Detection { reader: 0, rssi_dbm: -70.0 }];
/// assert!(network.locate(&heard)?.is_some());
/// assert_eq!(network.locate(&[])?, None); // nobody heard the tag: an empty location
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
///
/// # References
/// D. Niculescu, B. Nath, "DV based positioning in ad hoc networks", *Telecommunication
/// Systems* 22(1–4), 2003; seed 000 §2 (DV-Hop degrades in irregular, non-isotropic networks).
#[derive(Debug, Clone, PartialEq)]
pub struct DvHopNetwork {
    /// Node positions: the working readers (anchors), then the tag (`None`).
    nodes: Vec<Option<[f64; 3]>>,
    /// Node index of each reader (`None` for broken readers).
    node_of_reader: Vec<Option<usize>>,
    /// Reader–reader links in node indices.
    links: Vec<(usize, usize)>,
    options: DvHopOptions,
}

impl DvHopNetwork {
    /// The network of `layer`'s working readers with links `reader_links` (pairs of reader
    /// indices; links touching a broken reader are dropped), located with `options`.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] (`reader_links`) for an index outside the layer;
    /// [`SimError::Positioning`] if the network cannot run DV-Hop (fewer than 4 working
    /// readers, or a reader linked to no other reader).
    pub fn new(layer: &ReaderLayer, reader_links: &[(usize, usize)], options: DvHopOptions) -> Result<Self> {
        let mut nodes = Vec::new();
        let mut node_of_reader = Vec::with_capacity(layer.readers.len());
        for reader in &layer.readers {
            if reader.status == ReaderStatus::Working {
                node_of_reader.push(Some(nodes.len()));
                nodes.push(Some(reader.position_m));
            } else {
                node_of_reader.push(None);
            }
        }
        // the tag
        nodes.push(None);
        let mut links = Vec::with_capacity(reader_links.len());
        for &(a, b) in reader_links {
            let (Some(na), Some(nb)) = (node_of_reader.get(a), node_of_reader.get(b)) else {
                return Err(SimError::InvalidParameter {
                    name: "reader_links",
                    reason: "a link names a reader index outside the layer",
                });
            };
            if let (Some(na), Some(nb)) = (na, nb) {
                links.push((*na, *nb));
            }
        }
        let network = Self {
            nodes,
            node_of_reader,
            links,
            options,
        };
        // checks the network once (anchors, links, hop sizes)
        DvHop::<3>::new(&network.nodes, &network.links)?;
        Ok(network)
    }

    /// The DV-Hop fix of the tag heard by `detections`, or `None` if no reader heard it (an
    /// empty location) or the solver found no fix (anchors reached are degenerate, no
    /// convergence).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] (`detections`) for a detection by a reader that is not in
    /// the network (broken or out of range).
    pub fn locate(&self, detections: &[Detection]) -> Result<Option<[f64; 3]>> {
        if detections.is_empty() {
            return Ok(None);
        }
        let tag = self.nodes.len() - 1;
        let mut edges = self.links.clone();
        for d in detections {
            let node = self
                .node_of_reader
                .get(d.reader)
                .copied()
                .flatten()
                .ok_or(SimError::InvalidParameter {
                    name: "detections",
                    reason: "a detection names a reader that is broken or outside the network",
                })?;
            // the tag is one hop from every reader that heard it
            edges.push((node, tag));
        }
        let network = DvHop::<3>::new(&self.nodes, &edges)?;
        match network.locate(tag, &self.options) {
            Ok(f) => Ok(Some(f.position.into())),
            Err(e) if is_numerical(&e) => Ok(None),
            Err(e) => Err(e.into()),
        }
    }
}

/// `‖a − b‖` in 3-D, m.
#[must_use]
pub fn distance_m(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn radio() -> ReaderRadio {
        ReaderRadio::new(LogDistance::new(-50.0, 2.5, 1.0, 4.0).unwrap(), -85.0).unwrap()
    }

    fn reader(x: f64, y: f64, z: f64) -> Reader {
        Reader {
            name: format!("R{x}"),
            position_m: [x, y, z],
            status: ReaderStatus::Working,
            obstacle_loss_db: 0.0,
        }
    }

    /// Detection rate at the median range is ½, and an excess loss or an obstacle of `L` dB
    /// shifts the mean RSSI by exactly `−L` (same draws with the same seed).
    #[test]
    fn detection_follows_the_threshold_and_losses_shift_the_rssi() {
        let mut layer = ReaderLayer::new(vec![reader(0.0, 0.0, 0.0)], radio()).unwrap();
        let d50 = layer.radio().median_detection_range_m();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let trials = 20_000;
        let heard = (0..trials)
            .filter(|_| !layer.detect([d50, 0.0, 0.0], &[0.0], &mut rng).unwrap().is_empty())
            .count();
        let rate = heard as f64 / trials as f64;
        assert!((rate - 0.5).abs() < 0.015, "detection rate {rate}");
        // an excess loss and an obstacle shift the same draw by −L
        let near = [3.0, 0.0, 0.0];
        let clear = layer
            .detect(near, &[0.0], &mut rand_chacha::ChaCha8Rng::seed_from_u64(9))
            .unwrap();
        let walled = layer
            .detect(near, &[4.0], &mut rand_chacha::ChaCha8Rng::seed_from_u64(9))
            .unwrap();
        assert!((clear[0].rssi_dbm - walled[0].rssi_dbm - 4.0).abs() < 1e-12);
        layer.readers[0].obstacle_loss_db = 6.0;
        let blocked = layer
            .detect(near, &[0.0], &mut rand_chacha::ChaCha8Rng::seed_from_u64(9))
            .unwrap();
        assert!((clear[0].rssi_dbm - blocked[0].rssi_dbm - 6.0).abs() < 1e-12);
        layer.readers[0].status = ReaderStatus::Broken;
        assert!(layer.detect(near, &[0.0], &mut rng).unwrap().is_empty());
    }

    /// With exact RSSI (mean power, no shadowing) the fixes recover the tag, and the fallback
    /// chain follows the number of readers.
    #[test]
    fn rssi_fix_recovers_the_tag_and_falls_back_with_few_readers() {
        let readers = vec![
            reader(0.0, -1.8, 1.0),
            reader(10.0, 1.8, 1.5),
            reader(20.0, -1.8, 1.5),
            reader(30.0, 1.8, 0.6),
            reader(15.0, 8.0, 3.0),
        ];
        let layer = ReaderLayer::new(readers, radio()).unwrap();
        let tag = [14.0, 0.5, 0.0];
        let exact = |indices: &[usize]| -> Vec<Detection> {
            indices
                .iter()
                .map(|&i| Detection {
                    reader: i,
                    rssi_dbm: layer
                        .radio()
                        .law()
                        .mean_rssi_dbm(distance_m(tag, layer.readers()[i].position_m)),
                })
                .collect()
        };
        let options = GaussNewtonOptions::default();
        let full = layer
            .rssi_fix(&exact(&[0, 1, 2, 3, 4]), 1.0, &options)
            .unwrap()
            .unwrap();
        assert_eq!(full.kind, RssiFixKind::Multilateration);
        assert!(distance_m(full.position_m, tag) < 1e-6, "{:?}", full.position_m);
        let three = layer.rssi_fix(&exact(&[1, 2, 4]), 1.0, &options).unwrap().unwrap();
        assert_eq!(three.kind, RssiFixKind::GuidedMultilateration);
        assert!(distance_m(three.position_m, tag) < 1e-6, "{:?}", three.position_m);
        let one = layer.rssi_fix(&exact(&[2]), 1.0, &options).unwrap().unwrap();
        assert_eq!((one.kind, one.position_m), (RssiFixKind::Centroid, [20.0, -1.8, 1.5]));
        assert_eq!(layer.rssi_fix(&[], 1.0, &options).unwrap(), None);
        let bad = [Detection {
            reader: 9,
            rssi_dbm: -60.0,
        }];
        assert!(layer.rssi_fix(&bad, 1.0, &options).is_err());
    }

    #[test]
    fn dv_hop_network_checks_links_and_detections() {
        let mut readers = vec![
            reader(0.0, 0.0, 0.0),
            reader(10.0, 0.0, 1.0),
            reader(0.0, 10.0, 2.0),
            reader(10.0, 10.0, 0.5),
        ];
        readers.push(Reader {
            status: ReaderStatus::Broken,
            ..reader(20.0, 0.0, 0.0)
        });
        let layer = ReaderLayer::new(readers, radio()).unwrap();
        let links = [(0, 1), (1, 3), (3, 2), (2, 0), (1, 4)];
        let network = DvHopNetwork::new(&layer, &links, DvHopOptions::default()).unwrap();
        let fix = network
            .locate(&[Detection {
                reader: 3,
                rssi_dbm: -60.0,
            }])
            .unwrap()
            .unwrap();
        assert!(fix.iter().all(|c| c.is_finite()));
        assert!(network
            .locate(&[Detection {
                reader: 4,
                rssi_dbm: -60.0
            }])
            .is_err());
        assert!(DvHopNetwork::new(&layer, &[(0, 9)], DvHopOptions::default()).is_err());
        // reader 2 isolated: its hop size is undefined
        assert!(DvHopNetwork::new(&layer, &[(0, 1), (1, 3)], DvHopOptions::default()).is_err());
    }

    #[test]
    fn bad_inputs_are_errors() {
        assert!(ReaderRadio::new(LogDistance::new(-50.0, 2.5, 1.0, 4.0).unwrap(), -40.0).is_err());
        assert!(ReaderRadio::new(LogDistance::new(-50.0, 2.5, 1.0, 4.0).unwrap(), f64::NAN).is_err());
        assert!(ReaderLayer::new(Vec::new(), radio()).is_err());
        let mut bad = reader(0.0, 0.0, 0.0);
        bad.obstacle_loss_db = -1.0;
        assert!(ReaderLayer::new(vec![bad], radio()).is_err());
        let layer = ReaderLayer::new(vec![reader(0.0, 0.0, 0.0)], radio()).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        assert!(layer.detect([0.0; 3], &[], &mut rng).is_err());
        assert!(layer.detect([f64::NAN, 0.0, 0.0], &[0.0], &mut rng).is_err());
    }
}
