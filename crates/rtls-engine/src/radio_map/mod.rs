//! The fingerprint radio map of a site: the CSV file that `[fingerprints]` (format `"csv"`) of
//! the site model references, and WKNN fixes from RSSI scans against it.
//!
//! # File format
//! ```text
//! # optional comment lines (first non-blank character `#`); blank lines are skipped
//! x_m,y_m,floor,AP-1,AP-2,AP-3
//! 0.25,0.25,0,-61.5,,-80
//! 0.75,0.25,0,-63,-90.25,
//! ```
//! - a header `x_m,y_m[,floor],<reader id>,…`: the reference point's position (m, site frame),
//!   an optional integer floor label, then one column per reader;
//! - one row per reference point; a reader cell holds the mean RSSI (dBm) received there, or is
//!   **empty when the reader was not heard** — there is no sentinel value such as −100 or +100;
//! - every row has a position, the floor when the column exists, and at least one heard reader.
//!
//! Cells are trimmed; there is no quoting (reader ids may not contain `,`, `"` or line breaks).
//! [`radio_map_csv`] writes the format, [`RadioMap::from_csv_str`] reads it against a
//! [`Site`]. `docs/FORMATS.md` ("Radio map (fingerprint database) CSV") documents it for users.
//!
//! # Matching
//! [`RadioMap::locate`] runs WKNN (`rtls_positioning::fingerprint::Knn`) with, by default,
//! `k = 3` neighbours in the powed/Sørensen signal space (`ρ_min = −104 dBm`, `β = e`), both
//! fields with builders ([`RadioMap::with_neighbours`], [`RadioMap::with_signal_space`]).
//! Powed/Sørensen is the best space of `docs/FINGERPRINTING.md` on UJIIndoorLoc (6.47 m against
//! 8.42 m for Euclidean distances on dBm). Its best `k = 13` is for a map of the 19 937
//! individual training records (~21 per location): a radio map row is already a location's
//! mean, and on UJIIndoorLoc's 933 averaged locations `k = 3` is best (mean 2-D error 7.91 m,
//! against 8.65 m for `k = 1`, 8.00 m for 5, 9.10 m for 13; leave-one-track-out on the BLE
//! tetam tracks 1.89 m against 2.05 m for `k = 13`), measured by the importers' tests in `rtls-data`.
//!
//! # Covariance
//! The fix covariance is the neighbours' spread plus a floor `σ² I` calibrated on the map when
//! it is loaded, by leave-one-out cross-validation, so that 95 % of the map's own leave-one-out
//! errors lie inside their 95 % ellipse ([`RadioMap::locate`], [`FloorCalibration`]); the
//! site's `[fingerprints] min_std_m` overrides it.
//!
//! # References
//! Seed 002 §1.2 (the offline radio map and WKNN); P. Bahl, V. Padmanabhan, "RADAR",
//! INFOCOM 2000; J. Torres-Sospedra et al., "Comprehensive analysis of distance and similarity
//! measures for Wi-Fi fingerprinting indoor positioning systems", *Expert Systems with
//! Applications* 42(23), 2015 (the powed representation and the Sørensen distance).

mod csv_text;

pub use csv_text::{radio_map_csv, RadioMapRow};

use std::collections::HashMap;

use rtls_positioning::fingerprint::{
    FingerprintDatabase, FingerprintIndex, Knn, LeaveOneOut, SignalRepresentation, SignalSpace, Survey,
};
use rtls_positioning::PositioningError;

use crate::error::{EngineError, Result};
use crate::record::AnchorReading;
use crate::site::Site;

/// A parsed radio map, indexed for WKNN queries.
///
/// Holds the reader ids in column order, the reference points (with their floors when the file
/// has a floor column) represented in a signal space, the number of neighbours `k` and the
/// variance floor of the fix covariance, calibrated on the map itself by leave-one-out
/// cross-validation (see [`RadioMap::locate`] and [`RadioMap::calibration`]). Reader positions
/// (`x, y`) come from the site.
///
/// # Examples
/// ```
/// use rtls_engine::radio_map::RadioMap;
/// use rtls_engine::record::AnchorReading;
/// use rtls_engine::site::Site;
///
/// let site = Site::from_toml_str(
///     r#"
///     readers = [
///       { id = "A", position_m = [0.0, 0.0], technology = "ble" },
///       { id = "B", position_m = [10.0, 0.0], technology = "ble" },
///     ]
///     [tracker]
///     pipeline = "fix-then-filter"
///     motion_model = "cv"
///     filter = "kf"
///     acceleration_noise_std_mps2 = 1.0
///     gate_probability = 0.99
///     initiation = { confirm_updates = 1, within_s = 1.0 }
///     coast_timeout_s = 5.0
///     delete_timeout_s = 60.0
///     reorder_window_s = 0.5
///     "#,
///     "site.toml",
/// )?;
/// let csv = "x_m,y_m,A,B\n0,0,-40,-80\n5,0,-60,-60\n10,0,-80,-40\n";
/// let map = RadioMap::from_csv_str(csv, "radio-map.csv", &site)?.with_neighbours(1)?;
/// assert_eq!(map.reference_point_count(), 3);
/// let scan = [
///     AnchorReading { anchor: "A".into(), rssi_dbm: -79.0 },
///     AnchorReading { anchor: "B".into(), rssi_dbm: -41.0 },
/// ];
/// let fix = map.locate(&scan)?;
/// assert_eq!(fix.position_m, [10.0, 0.0]);
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
#[derive(Debug, Clone)]
pub struct RadioMap {
    file: String,
    reader_ids: Vec<String>,
    columns: HashMap<String, usize>,
    /// The parsed survey (kept to rebuild the index in another signal space).
    database: FingerprintDatabase,
    /// 1-based file line of each reference point (for errors found after parsing).
    lines: Vec<usize>,
    index: FingerprintIndex,
    knn: Knn,
    /// `σ₀² = s²/12`, the spacing floor.
    spacing_variance_m2: f64,
    /// The leave-one-out calibration for the present `k` and signal space, when the map has
    /// enough distinct positions.
    calibration: Option<FloorCalibration>,
    /// `[fingerprints] min_std_m` or [`RadioMap::with_min_std_m`].
    min_std_override_m: Option<f64>,
    /// The variance floor in use: the override², else `max(σ_f², σ₀²)`, else `σ₀²`.
    min_variance_m2: f64,
}

/// The leave-one-out calibration of a radio map's fix-noise floor ([`RadioMap::calibration`]):
/// every reference point (or an even subsample of [`RadioMap::loo_queries`]) located by the
/// rest of the map, all rows at its position and
/// floor left out with it (`rtls_positioning::fingerprint::Knn::leave_one_out`).
///
/// # Units
/// m, except the counts and the NEES (dimensionless).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FloorCalibration {
    /// Reference points used as queries.
    pub queried: usize,
    /// Of those, the ones the rest of the map located (the errors below).
    pub located: usize,
    /// `√(Σ |x̂_l − P_l|² / S)` over the located queries, m.
    pub rmse_m: f64,
    /// `σ_f`, m: with `P_l = C_l + σ_f² I` (`C_l` the neighbours' spread), 95 % of the
    /// leave-one-out errors lie inside their 95 % ellipse
    /// (`rtls_positioning::fingerprint::LeaveOneOut::floor_variance_m2`).
    pub fitted_std_m: f64,
    /// Mean NEES `(1/S) Σ e_lᵀ (C_l + σ² I)⁻¹ e_l` of the leave-one-out errors with the
    /// calibrated floor `σ² = max(σ_f², s²/12)` (2 for Gaussian errors; larger when a few
    /// errors are far out).
    pub mean_nees: f64,
}

/// A WKNN fix from [`RadioMap::locate`].
///
/// # Units
/// `position_m` in m (site frame, `x, y`), `covariance_m2` in m², row-major `[[xx, xy], [yx, yy]]`.
#[derive(Debug, Clone, PartialEq)]
pub struct RadioMapFix {
    /// Estimated position `[x, y]`, m.
    pub position_m: [f64; 2],
    /// Covariance of `position_m`, m² (symmetric positive definite): the neighbours' weighted
    /// spread plus the map's variance floor on the diagonal.
    pub covariance_m2: [[f64; 2]; 2],
    /// Floor voted by the neighbours, when the map has a floor column.
    pub floor: Option<i32>,
    /// Readings of readers that are not columns of the map (not used, counted).
    pub unused_readings: usize,
    /// Readings of map readers weaker than the signal space's floor `ρ_min`, used as "not heard"
    /// (in every representation `ψ(ρ_min) = 0` = not heard, so this is their exact value there).
    pub below_floor_readings: usize,
}

impl RadioMap {
    /// Default number of neighbours `k` (WKNN): the best `k` on UJIIndoorLoc's training set
    /// averaged per location (see the [module docs](self)).
    pub const DEFAULT_NEIGHBOURS: usize = crate::site::FingerprintDatabase::DEFAULT_NEIGHBOURS;

    /// Most reference points queried by the leave-one-out calibration; a larger map is
    /// subsampled evenly ([`RadioMap::loo_queries`]).
    pub const LOO_MAX_QUERIES: usize = 2000;

    /// Fewest reference points queried by the leave-one-out calibration of a map that has
    /// them, however large: 25 errors beyond the 95 % quantile.
    pub const LOO_MIN_QUERIES: usize = 500;

    /// The leave-one-out calibration's budget of signal-space distances (queries × rows),
    /// between the two bounds above: 10⁷ takes ~1.3 s in a release build on UJIIndoorLoc's
    /// 19 861 individual training scans (500 queries), 0.25 s on its 933 averaged locations.
    pub const LOO_DISTANCE_BUDGET: usize = 10_000_000;

    /// The probability of the ellipse the floor is calibrated for: a share `p` of the
    /// leave-one-out errors lies inside the `p` ellipse of the fix covariance.
    pub const FLOOR_COVERAGE: f64 = 0.95;

    /// Parses a radio map CSV (format in the [module docs](self)) for `site`.
    ///
    /// Every reader column must be a reader of `site` (its `x, y` become the anchor position of
    /// the fingerprint database); when the site's `[fingerprints].readers` is non-empty, the
    /// reader columns must be exactly those ids in that order. The map starts with the site's
    /// `[fingerprints]` `neighbours` (default [`RadioMap::DEFAULT_NEIGHBOURS`]), the powed/Sørensen
    /// signal space ([`SignalSpace::powed_sorensen`]) with the site's `noise_floor_dbm` (default
    /// −104 dBm), and the variance floor calibrated by leave-one-out cross-validation, or the
    /// site's `min_std_m` when set (see [`RadioMap::locate`]). At most
    /// [`MAX_RADIO_MAP_ROWS`](crate::site::MAX_RADIO_MAP_ROWS) reference points are read; read
    /// the file with [`read_text_file`](crate::site::read_text_file) and
    /// [`MAX_RADIO_MAP_BYTES`](crate::site::MAX_RADIO_MAP_BYTES) to bound its size.
    ///
    /// `file` only names the input in errors.
    ///
    /// # Errors
    /// [`EngineError::Parse`] naming `file`, the 1-based line and the field (the header cell or
    /// the column name of a cell) for: a missing header, a header not starting with
    /// `x_m,y_m`, a reader column that is empty, repeated, reserved (`x_m`, `y_m`, `floor`),
    /// unknown to the site or different from `[fingerprints].readers`; a row with the wrong
    /// number of cells, a position or RSSI that is not a finite number, a floor that is not an
    /// integer, a row where no reader was heard; an RSSI below the signal space's floor
    /// (−104 dBm by default); a file without rows or with more than
    /// [`MAX_RADIO_MAP_ROWS`](crate::site::MAX_RADIO_MAP_ROWS).
    ///
    /// # Examples
    /// See [`RadioMap`]. A reader the site does not know is an error naming its column:
    /// ```
    /// # use rtls_engine::{radio_map::RadioMap, site::Site};
    /// # let site = Site::from_toml_str(
    /// #     "readers = [{ id = \"A\", position_m = [0.0, 0.0], technology = \"ble\" }]\n[tracker]\npipeline = \"fix-then-filter\"\nmotion_model = \"cv\"\nfilter = \"kf\"\nacceleration_noise_std_mps2 = 1.0\ngate_probability = 0.99\ninitiation = { confirm_updates = 1, within_s = 1.0 }\ncoast_timeout_s = 5.0\ndelete_timeout_s = 60.0\nreorder_window_s = 0.5\n",
    /// #     "site.toml",
    /// # )?;
    /// let error = RadioMap::from_csv_str("x_m,y_m,A,Z\n0,0,-50,-60\n", "map.csv", &site).unwrap_err();
    /// assert!(error.to_string().starts_with("map.csv:1: field `Z`"));
    /// # Ok::<(), rtls_engine::EngineError>(())
    /// ```
    pub fn from_csv_str(text: &str, file: &str, site: &Site) -> Result<Self> {
        let parsed = csv_text::parse(text, file, site)?;
        let anchors_m = parsed
            .reader_ids
            .iter()
            .map(|id| {
                site.reader(id).map(|reader| {
                    let [x, y, _] = reader.position_xyz_m();
                    [x, y]
                })
            })
            .collect();
        let database = FingerprintDatabase::from_survey(Survey {
            reference_points_m: parsed.positions_m,
            floors: parsed.floors,
            buildings: None,
            anchor_count: parsed.reader_ids.len(),
            anchors_m: Some(anchors_m),
            readings_dbm: parsed.readings_dbm,
        })?;
        let columns = parsed
            .reader_ids
            .iter()
            .enumerate()
            .map(|(column, id)| (id.clone(), column))
            .collect();
        let mut space = SignalSpace::powed_sorensen();
        let mut neighbours = Self::DEFAULT_NEIGHBOURS;
        if let Some(settings) = &site.fingerprints {
            // the site's [fingerprints] neighbours and noise_floor_dbm (defaults: 3, −104 dBm)
            neighbours = settings.neighbours.max(1);
            if let SignalRepresentation::Powed { floor_dbm, .. } = &mut space.representation {
                *floor_dbm = settings.noise_floor_dbm;
            }
        }
        let index = build_index(&database, space, file, &parsed.lines, &parsed.reader_ids)?;
        let spacing_variance_m2 = spacing_variance_m2(database.reference_points_m());
        let map = Self {
            file: file.to_string(),
            reader_ids: parsed.reader_ids,
            columns,
            database,
            lines: parsed.lines,
            index,
            knn: Knn::wknn(neighbours),
            spacing_variance_m2,
            calibration: None,
            min_std_override_m: None,
            min_variance_m2: spacing_variance_m2,
        }
        .calibrated()?;
        match site.fingerprints.as_ref().and_then(|settings| settings.min_std_m) {
            Some(min_std_m) => map.with_min_std_m(min_std_m),
            None => Ok(map),
        }
    }

    /// The map with its floor recalibrated for the present `k` and signal space: leave-one-out
    /// errors, `σ_f²` by 95 % coverage, floor `max(σ_f², s²/12)` unless overridden.
    fn calibrated(mut self) -> Result<Self> {
        let loo: LeaveOneOut = self.knn.leave_one_out(&self.index, self.loo_queries())?;
        self.calibration = match self.calibration_of(&loo) {
            Ok(calibration) => calibration,
            // errors or spreads beyond f64 (reference coordinates near 1e150 m): no calibration,
            // the spacing floor
            Err(PositioningError::NonFinite { .. }) => None,
            Err(other) => return Err(other.into()),
        };
        self.min_variance_m2 = match (self.min_std_override_m, &self.calibration) {
            (Some(std_m), _) => std_m * std_m,
            (None, Some(calibration)) => {
                (calibration.fitted_std_m * calibration.fitted_std_m).max(self.spacing_variance_m2)
            }
            (None, None) => self.spacing_variance_m2,
        };
        Ok(self)
    }

    /// The calibration from leave-one-out errors; `None` when there are too few of them.
    fn calibration_of(&self, loo: &LeaveOneOut) -> std::result::Result<Option<FloorCalibration>, PositioningError> {
        let (Some(fitted_m2), Some(rmse_m)) = (loo.floor_variance_m2(Self::FLOOR_COVERAGE)?, loo.rmse_m()?) else {
            return Ok(None);
        };
        // σ² = max(σ_f², s²/12)
        let floor_m2 = fitted_m2.max(self.spacing_variance_m2);
        if !floor_m2.is_finite() {
            return Err(PositioningError::NonFinite { what: "spacing floor" });
        }
        Ok(Some(FloorCalibration {
            queried: loo.queried(),
            located: loo.samples().len(),
            rmse_m,
            fitted_std_m: fitted_m2.sqrt(),
            mean_nees: loo.mean_nees(floor_m2)?.unwrap_or(0.0),
        }))
    }

    /// The same map with `k` neighbours (WKNN, `w ∝ 1/D`, averaged on the voted floor), its
    /// floor recalibrated for them.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] (`neighbours`) if `k` is 0.
    ///
    /// # Examples
    /// See [`RadioMap`].
    pub fn with_neighbours(mut self, neighbours: usize) -> Result<Self> {
        if neighbours == 0 {
            return Err(EngineError::InvalidParameter {
                name: "neighbours",
                reason: "at least one neighbour must be averaged",
            });
        }
        self.knn = Knn::wknn(neighbours);
        self.calibrated()
    }

    /// The same map represented in another signal space (e.g. `SignalSpace::default()`,
    /// Euclidean on dBm as in seed 002), its floor recalibrated there.
    ///
    /// # Errors
    /// [`EngineError::Positioning`] for invalid representation parameters;
    /// [`EngineError::Parse`] naming the file's line and reader column of a map RSSI below the
    /// new floor.
    pub fn with_signal_space(mut self, space: SignalSpace) -> Result<Self> {
        self.index = build_index(&self.database, space, &self.file, &self.lines, &self.reader_ids)?;
        self.calibrated()
    }

    /// The same map with the variance floor of the fix covariance set to `min_std_m²` in place
    /// of the calibrated one (kept in [`RadioMap::calibration`]); as the site's
    /// `[fingerprints] min_std_m`.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] (`min_std_m`) unless it is finite and positive (the
    /// covariance must stay positive definite).
    pub fn with_min_std_m(mut self, min_std_m: f64) -> Result<Self> {
        if !(min_std_m.is_finite() && min_std_m > 0.0) {
            return Err(EngineError::InvalidParameter {
                name: "min_std_m",
                reason: "the fix's standard deviation floor must be positive and finite",
            });
        }
        self.min_std_override_m = Some(min_std_m);
        self.min_variance_m2 = min_std_m * min_std_m;
        Ok(self)
    }

    /// Reader ids in column order.
    #[must_use]
    pub fn reader_ids(&self) -> &[String] {
        &self.reader_ids
    }

    /// Number of reference points (rows).
    #[must_use]
    pub fn reference_point_count(&self) -> usize {
        self.database.reference_point_count()
    }

    /// The number of neighbours `k`.
    #[must_use]
    pub fn neighbours(&self) -> usize {
        self.knn.neighbours
    }

    /// The signal space of the index.
    #[must_use]
    pub fn signal_space(&self) -> SignalSpace {
        *self.index.space()
    }

    /// The standard deviation floor of the fix (m), `σ` in [`RadioMap::locate`]: the one set by
    /// [`RadioMap::with_min_std_m`] (the site's `min_std_m`), else the calibrated
    /// `max(σ_f, s/√12)` ([`RadioMap::calibration`]), else — on a map with fewer than three
    /// distinct positions — the spacing floor [`RadioMap::spacing_std_m`].
    #[must_use]
    pub fn min_std_m(&self) -> f64 {
        self.min_variance_m2.sqrt()
    }

    /// The spacing floor `√(s²/12)` (m), `s` the median distance from a reference point to its
    /// nearest neighbour at a different position (1 m when all share one position): the lower
    /// bound of the calibrated floor.
    #[must_use]
    pub fn spacing_std_m(&self) -> f64 {
        self.spacing_variance_m2.sqrt()
    }

    /// The leave-one-out calibration of the floor for the present `k` and signal space; `None`
    /// when the map has fewer than three distinct positions or fewer than three reference
    /// points the rest of the map can locate.
    #[must_use]
    pub fn calibration(&self) -> Option<&FloorCalibration> {
        self.calibration.as_ref()
    }

    /// The number of reference points the leave-one-out calibration queries:
    /// `clamp(LOO_DISTANCE_BUDGET / rows, LOO_MIN_QUERIES, LOO_MAX_QUERIES)`, at most all rows.
    #[must_use]
    pub fn loo_queries(&self) -> usize {
        let rows = self.database.reference_point_count();
        // m = clamp(B / n, m_min, m_max)
        let queries = (Self::LOO_DISTANCE_BUDGET / rows.max(1)).clamp(Self::LOO_MIN_QUERIES, Self::LOO_MAX_QUERIES);
        queries.min(rows)
    }

    /// The floor set by [`RadioMap::with_min_std_m`] or the site's `[fingerprints] min_std_m`
    /// (m), if any.
    #[must_use]
    pub fn min_std_override_m(&self) -> Option<f64> {
        self.min_std_override_m
    }

    /// The leave-one-out RMSE of the map's WKNN fixes (m), [`FloorCalibration::rmse_m`].
    #[must_use]
    pub fn loo_rmse_m(&self) -> Option<f64> {
        self.calibration.map(|c| c.rmse_m)
    }

    /// The WKNN fix of a scan.
    ///
    /// Readings of readers that are not map columns are not used and are counted in
    /// [`RadioMapFix::unused_readings`]; readings below the signal space's floor count as not
    /// heard ([`RadioMapFix::below_floor_readings`]). Then `Knn::wknn(k)` on the map:
    /// the `k` reference points nearest in signal space, weights `w ∝ 1/D` (an exact match
    /// takes all the weight), floor by weighted vote, position `x̂ = Σ w_l P_l` over the
    /// neighbours on the voted floor.
    ///
    /// Covariance: `P = C + σ² I`, `C = Σ w_l (P_l − x̂)(P_l − x̂)ᵀ` the neighbours' spread
    /// (zero when one neighbour takes all the weight) and `σ² = max(σ_f², σ₀²)` the floor
    /// ([`RadioMap::min_std_m`]):
    /// - `σ_f²` is calibrated when the map is loaded, by leave-one-out cross-validation: each
    ///   reference point `l` (all of them, or [`RadioMap::loo_queries`] evenly strided) is
    ///   located by the map without every row at its position and floor, giving the error
    ///   `e_l = x̂_l − P_l` and spread `C_l`; `σ_f²` is the smallest variance with which 95 % of
    ///   them lie inside their 95 % ellipse, `e_lᵀ (C_l + σ_f² I)⁻¹ e_l ≤ χ²₂(0.95) = 5.99`
    ///   (per error the root of a quadratic in `σ²`, then the 95 % quantile; for `C = 0`,
    ///   `σ_f = r₉₅ / 2.45` with `r₉₅` the 95 % quantile of `|e_l|`). A coverage fit rather than
    ///   "mean NEES = 2" because fingerprint errors are heavy-tailed and a mean would size
    ///   every ellipse for the few worst errors;
    /// - `σ₀² = s²/12` is the variance of a position uniformly distributed over a square cell of
    ///   side `s`, the map's median reference spacing — the resolution no match can beat — and
    ///   the lower bound, which also keeps `P` positive definite.
    ///
    /// Leave-one-out queries are the map's own rows (averaged scans from the survey devices),
    /// so live scans from other devices, months later, can be worse than `σ_f` says: check the
    /// coverage with `rtls eval --truth`, and set `[fingerprints] min_std_m` from it.
    ///
    /// # Errors
    /// [`EngineError::Positioning`] with [`PositioningError::NoCommonAnchors`] if no usable
    /// reading is a map reader, [`PositioningError::NoFingerprintMatch`] if no reference point
    /// hears any of them; [`EngineError::InvalidParameter`] (`readings`) for a non-finite RSSI
    /// or a map reader listed twice.
    ///
    /// # Examples
    /// See [`RadioMap`].
    pub fn locate(&self, readings: &[AnchorReading]) -> Result<RadioMapFix> {
        let floor_dbm = self.index.space().representation.floor_dbm();
        let mut query = vec![None; self.reader_ids.len()];
        let mut seen = vec![false; self.reader_ids.len()];
        let (mut unused_readings, mut below_floor_readings, mut usable) = (0, 0, 0);
        for reading in readings {
            if !reading.rssi_dbm.is_finite() {
                return Err(EngineError::InvalidParameter {
                    name: "readings",
                    reason: "an rssi reading is not a finite number",
                });
            }
            let Some(&column) = self.columns.get(&reading.anchor) else {
                unused_readings += 1;
                continue;
            };
            if std::mem::replace(&mut seen[column], true) {
                return Err(EngineError::InvalidParameter {
                    name: "readings",
                    reason: "a reader is listed twice in one scan",
                });
            }
            if reading.rssi_dbm < floor_dbm {
                below_floor_readings += 1;
                continue;
            }
            query[column] = Some(reading.rssi_dbm);
            usable += 1;
        }
        if usable == 0 {
            return Err(PositioningError::NoCommonAnchors.into());
        }
        let result = self.knn.locate(&self.index, &query)?;
        let (p, c) = (result.fix.position, result.fix.covariance);
        // P = Σ w (P_l − x̂)(P_l − x̂)ᵀ + σ² I
        let covariance_m2 = [
            [c[(0, 0)] + self.min_variance_m2, c[(0, 1)]],
            [c[(1, 0)], c[(1, 1)] + self.min_variance_m2],
        ];
        Ok(RadioMapFix {
            position_m: [p.x, p.y],
            covariance_m2,
            floor: result.floor,
            unused_readings,
            below_floor_readings,
        })
    }
}

/// Represents `database` in `space`, naming the file line and reader column of a value below
/// the floor.
fn build_index(
    database: &FingerprintDatabase,
    space: SignalSpace,
    file: &str,
    lines: &[usize],
    reader_ids: &[String],
) -> Result<FingerprintIndex> {
    FingerprintIndex::new(database.clone(), space).map_err(|error| match error {
        PositioningError::RssiBelowFloor {
            row,
            column,
            rssi_dbm,
            floor_dbm,
            ..
        } => EngineError::Parse {
            file: file.to_string(),
            line: lines.get(row).copied().unwrap_or(0),
            field: reader_ids.get(column).cloned().unwrap_or_default(),
            reason: format!(
                "rssi {rssi_dbm} dBm is below the signal space's floor {floor_dbm} dBm; \
                 lower the floor (RadioMap::with_signal_space) or check the value"
            ),
        },
        other => other.into(),
    })
}

/// `s²/12` with `s` the median distance from a reference point to its nearest neighbour at a
/// different position (points at one position on several floors are one place); 1 m² when
/// every reference point is at one position (no spacing to measure).
fn spacing_variance_m2(points: &[[f64; 2]]) -> f64 {
    let mut sorted: Vec<[f64; 2]> = points.to_vec();
    sorted.sort_unstable_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    sorted.dedup();
    if sorted.len() < 2 {
        return 1.0;
    }
    // sweep along x: for each point, only neighbours with |Δx| < the best distance so far count
    let mut nearest: Vec<f64> = Vec::with_capacity(sorted.len());
    for (i, p) in sorted.iter().enumerate() {
        let mut best = f64::INFINITY;
        for q in sorted[i + 1..].iter() {
            if q[0] - p[0] >= best {
                break;
            }
            best = best.min((q[0] - p[0]).hypot(q[1] - p[1]));
        }
        for q in sorted[..i].iter().rev() {
            if p[0] - q[0] >= best {
                break;
            }
            best = best.min((q[0] - p[0]).hypot(q[1] - p[1]));
        }
        nearest.push(best);
    }
    nearest.sort_unstable_by(f64::total_cmp);
    let s = nearest[nearest.len() / 2];
    // σ₀² = s²/12 (uniform over a cell of side s)
    s * s / 12.0
}

#[cfg(test)]
mod tests;
