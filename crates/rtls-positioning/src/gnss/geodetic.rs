//! WGS-84 geodetic coordinates, Earth-centred Earth-fixed (ECEF) coordinates and a local
//! east-north-up (ENU) frame about a geodetic origin.

use nalgebra::{Matrix3, Vector3};

use crate::error::{PositioningError, Result};

/// WGS-84 semi-major axis `a`, m.
pub const WGS84_A_M: f64 = 6_378_137.0;

/// WGS-84 flattening `f`.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;

/// Points closer than this to the Earth's centre have no usable geodetic coordinates (the
/// closed form below is valid well outside it), m.
const MIN_GEOCENTRIC_RADIUS_M: f64 = 1.0e5;

/// A WGS-84 geodetic position.
///
/// # Units
/// Latitude and longitude in degrees (north and east positive), height above the ellipsoid in m.
///
/// # Example
/// ```
/// use rtls_positioning::gnss::Geodetic;
/// let paris = Geodetic { latitude_deg: 48.8566, longitude_deg: 2.3522, height_m: 35.0 };
/// let ecef = paris.to_ecef()?;
/// let back = Geodetic::from_ecef(&ecef)?;
/// assert!((back.latitude_deg - paris.latitude_deg).abs() < 1e-9);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// NIMA TR8350.2, *Department of Defense World Geodetic System 1984*, 3rd ed., 2000, §3.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geodetic {
    /// Geodetic latitude, degrees in [−90, 90].
    pub latitude_deg: f64,
    /// Longitude, degrees (any finite value; east positive).
    pub longitude_deg: f64,
    /// Height above the WGS-84 ellipsoid, m.
    pub height_m: f64,
}

/// `e² = f (2 − f)`, the first eccentricity squared.
fn eccentricity_squared() -> f64 {
    WGS84_F * (2.0 - WGS84_F)
}

impl Geodetic {
    /// Checks that the position is finite and the latitude within ±90°.
    ///
    /// # Errors
    /// [`PositioningError::NonFinite`] or [`PositioningError::InvalidParameter`]
    /// (`latitude_deg`).
    pub fn validate(&self) -> Result<()> {
        if !(self.latitude_deg.is_finite() && self.longitude_deg.is_finite() && self.height_m.is_finite()) {
            return Err(PositioningError::NonFinite {
                what: "geodetic position",
            });
        }
        if self.latitude_deg.abs() > 90.0 {
            return Err(PositioningError::InvalidParameter {
                name: "latitude_deg",
                reason: "a latitude lies in [-90, 90] degrees",
            });
        }
        Ok(())
    }

    /// The ECEF position, m.
    ///
    /// ```text
    /// N(φ) = a / √(1 − e² sin²φ)              prime-vertical radius of curvature
    /// X = (N + h) cos φ cos λ
    /// Y = (N + h) cos φ sin λ
    /// Z = (N (1 − e²) + h) sin φ
    /// ```
    ///
    /// # Errors
    /// As [`Geodetic::validate`].
    ///
    /// # References
    /// NIMA TR8350.2, 2000, eq. (4-14).
    pub fn to_ecef(&self) -> Result<Vector3<f64>> {
        self.validate()?;
        let e2 = eccentricity_squared();
        let (sin_lat, cos_lat) = self.latitude_deg.to_radians().sin_cos();
        let (sin_lon, cos_lon) = self.longitude_deg.to_radians().sin_cos();
        // N = a / √(1 − e² sin²φ)
        let n = WGS84_A_M / (1.0 - e2 * sin_lat * sin_lat).sqrt();
        Ok(Vector3::new(
            // X = (N + h) cos φ cos λ
            (n + self.height_m) * cos_lat * cos_lon,
            // Y = (N + h) cos φ sin λ
            (n + self.height_m) * cos_lat * sin_lon,
            // Z = (N (1 − e²) + h) sin φ
            (n * (1.0 - e2) + self.height_m) * sin_lat,
        ))
    }

    /// The geodetic position of an ECEF point, by Heikkinen's closed form (exact to well below
    /// a millimetre from the Earth's surface to beyond GNSS orbits).
    ///
    /// With `b = a (1 − f)`, `e'² = (a² − b²)/b²` and `p = √(X² + Y²)`:
    /// ```text
    /// F = 54 b² Z²,   G = p² + (1 − e²) Z² − e² (a² − b²)
    /// c = e⁴ F p² / G³,   s = ∛(1 + c + √(c² + 2c)),   k = s + 1 + 1/s
    /// P = F / (3 k² G²),   Q = √(1 + 2 e⁴ P)
    /// r₀ = −P e² p / (1 + Q) + √(½ a² (1 + 1/Q) − P (1 − e²) Z² / (Q (1 + Q)) − ½ P p²)
    /// U = √((p − e² r₀)² + Z²),   V = √((p − e² r₀)² + (1 − e²) Z²)
    /// z₀ = b² Z / (a V)
    /// h = U (1 − b² / (a V)),   φ = atan2(Z + e'² z₀, p),   λ = atan2(Y, X)
    /// ```
    ///
    /// # Units
    /// `ecef_m` in m.
    ///
    /// # Errors
    /// [`PositioningError::NonFinite`] for a NaN/∞ coordinate;
    /// [`PositioningError::InvalidParameter`] (`ecef_m`) within 100 km of the Earth's centre,
    /// where geodetic coordinates are ill-defined (usually a position left at zero).
    ///
    /// # Example
    /// ```
    /// use nalgebra::Vector3;
    /// use rtls_positioning::gnss::Geodetic;
    /// let equator = Geodetic::from_ecef(&Vector3::new(6_378_137.0, 0.0, 0.0))?;
    /// assert!(equator.latitude_deg.abs() < 1e-12 && equator.height_m.abs() < 1e-6);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    ///
    /// # References
    /// M. Heikkinen, "Geschlossene Formeln zur Berechnung räumlicher geodätischer Koordinaten
    /// aus rechtwinkligen Koordinaten", *Z. Vermess.* 107, 1982; J. Zhu, "Conversion of
    /// Earth-centered Earth-fixed coordinates to geodetic coordinates", *IEEE Trans. AES* 30(3),
    /// 1994 (the form above).
    pub fn from_ecef(ecef_m: &Vector3<f64>) -> Result<Self> {
        if !ecef_m.iter().all(|v| v.is_finite()) {
            return Err(PositioningError::NonFinite { what: "ECEF position" });
        }
        if ecef_m.norm() < MIN_GEOCENTRIC_RADIUS_M {
            return Err(PositioningError::InvalidParameter {
                name: "ecef_m",
                reason: "the point lies within 100 km of the Earth's centre, where geodetic coordinates are \
                         ill-defined; is the position left at zero?",
            });
        }
        let (x, y, z) = (ecef_m[0], ecef_m[1], ecef_m[2]);
        let a = WGS84_A_M;
        let b = a * (1.0 - WGS84_F);
        let e2 = eccentricity_squared();
        let ep2 = (a * a - b * b) / (b * b);
        let p = x.hypot(y);
        // F = 54 b² Z²,  G = p² + (1 − e²) Z² − e² (a² − b²)
        let f = 54.0 * b * b * z * z;
        let g = p * p + (1.0 - e2) * z * z - e2 * (a * a - b * b);
        // c = e⁴ F p² / G³,  s = ∛(1 + c + √(c² + 2c)),  k = s + 1 + 1/s
        let c = e2 * e2 * f * p * p / (g * g * g);
        let s = (1.0 + c + (c * c + 2.0 * c).sqrt()).cbrt();
        let k = s + 1.0 + 1.0 / s;
        // P = F / (3 k² G²),  Q = √(1 + 2 e⁴ P)
        let big_p = f / (3.0 * k * k * g * g);
        let q = (1.0 + 2.0 * e2 * e2 * big_p).sqrt();
        // r₀ = −P e² p/(1 + Q) + √(½a²(1 + 1/Q) − P(1 − e²)Z²/(Q(1 + Q)) − ½ P p²)
        let radicand =
            0.5 * a * a * (1.0 + 1.0 / q) - big_p * (1.0 - e2) * z * z / (q * (1.0 + q)) - 0.5 * big_p * p * p;
        let r0 = -big_p * e2 * p / (1.0 + q) + radicand.max(0.0).sqrt();
        // U = √((p − e² r₀)² + Z²),  V = √((p − e² r₀)² + (1 − e²) Z²)
        let u = (p - e2 * r0).hypot(z);
        let v = ((p - e2 * r0).powi(2) + (1.0 - e2) * z * z).sqrt();
        // z₀ = b² Z / (a V)
        let z0 = b * b * z / (a * v);
        let geodetic = Self {
            // φ = atan2(Z + e'² z₀, p)
            latitude_deg: (z + ep2 * z0).atan2(p).to_degrees(),
            // λ = atan2(Y, X)
            longitude_deg: y.atan2(x).to_degrees(),
            // h = U (1 − b²/(a V))
            height_m: u * (1.0 - b * b / (a * v)),
        };
        geodetic.validate()?;
        Ok(geodetic)
    }
}

/// A local east-north-up frame about a geodetic origin: `x` east, `y` north, `z` up (along the
/// ellipsoid normal at the origin), origin at the given height.
///
/// ```text
///        ⎡ −sin λ          cos λ          0     ⎤
/// R    = ⎢ −sin φ cos λ   −sin φ sin λ    cos φ ⎥     (rows: east, north, up in ECEF)
///        ⎣  cos φ cos λ    cos φ sin λ    sin φ ⎦
/// enu  = R (ecef − ecef₀),   ecef = ecef₀ + Rᵀ enu
/// ```
///
/// # Example
/// ```
/// use rtls_positioning::gnss::{Geodetic, LocalFrame};
/// let frame = LocalFrame::new(Geodetic { latitude_deg: 52.0, longitude_deg: 4.4, height_m: 0.0 })?;
/// let up = frame.ecef_from_enu(&nalgebra::Vector3::new(0.0, 0.0, 100.0));
/// assert!((frame.geodetic_of_enu(&frame.enu_from_ecef(&up))?.height_m - 100.0).abs() < 1e-6);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// J. Farrell, *Aided Navigation*, 2008, §2.5 (geodetic, ECEF and local tangent frames);
/// NIMA TR8350.2, 2000.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalFrame {
    origin: Geodetic,
    origin_ecef_m: Vector3<f64>,
    /// `R`: ECEF → ENU rotation.
    rotation: Matrix3<f64>,
}

impl LocalFrame {
    /// The ENU frame about `origin`.
    ///
    /// # Errors
    /// As [`Geodetic::validate`].
    pub fn new(origin: Geodetic) -> Result<Self> {
        let origin_ecef_m = origin.to_ecef()?;
        Ok(Self {
            origin,
            origin_ecef_m,
            rotation: enu_rotation(&origin),
        })
    }

    /// A local frame about `origin` whose `x` axis points along the compass bearing
    /// `x_axis_bearing_deg` (degrees clockwise from north; 90 gives [`LocalFrame::new`]'s ENU),
    /// `y` 90° counter-clockwise from it and `z` up: a site drawn on a plan that is not aligned
    /// with north.
    ///
    /// ```text
    /// x̂ = ( sin β,  cos β, 0)       in ENU, β = x_axis_bearing_deg
    /// ŷ = (−cos β,  sin β, 0)
    /// R_site = [x̂; ŷ; û] R(φ, λ)    ECEF → site
    /// ```
    ///
    /// # Errors
    /// As [`Geodetic::validate`]; [`PositioningError::InvalidParameter`] for a non-finite bearing.
    ///
    /// # Example
    /// ```
    /// use rtls_positioning::gnss::{Geodetic, LocalFrame};
    /// let origin = Geodetic { latitude_deg: 52.0, longitude_deg: 4.4, height_m: 0.0 };
    /// // x along north: 100 m along x is 100 m north
    /// let site = LocalFrame::with_x_axis_bearing(origin, 0.0)?;
    /// let enu = LocalFrame::new(origin)?;
    /// let north = enu.enu_from_ecef(&site.ecef_from_enu(&nalgebra::Vector3::new(100.0, 0.0, 0.0)));
    /// assert!((north - nalgebra::Vector3::new(0.0, 100.0, 0.0)).norm() < 1e-6);
    /// # Ok::<(), rtls_positioning::PositioningError>(())
    /// ```
    pub fn with_x_axis_bearing(origin: Geodetic, x_axis_bearing_deg: f64) -> Result<Self> {
        if !x_axis_bearing_deg.is_finite() {
            return Err(PositioningError::InvalidParameter {
                name: "x_axis_bearing_deg",
                reason: "a bearing is a finite angle in degrees",
            });
        }
        let enu = Self::new(origin)?;
        let (sin_b, cos_b) = x_axis_bearing_deg.to_radians().sin_cos();
        // Q: rows x̂, ŷ, û of the site axes in ENU
        let site_from_enu = Matrix3::new(sin_b, cos_b, 0.0, -cos_b, sin_b, 0.0, 0.0, 0.0, 1.0);
        Ok(Self {
            rotation: site_from_enu * enu.rotation,
            ..enu
        })
    }

    /// The frame's origin.
    #[must_use]
    pub fn origin(&self) -> Geodetic {
        self.origin
    }

    /// The origin in ECEF, m.
    #[must_use]
    pub fn origin_ecef_m(&self) -> Vector3<f64> {
        self.origin_ecef_m
    }

    /// `R`, the rotation of ECEF vectors into ENU.
    #[must_use]
    pub fn rotation(&self) -> Matrix3<f64> {
        self.rotation
    }

    /// ENU of an ECEF point: `R (ecef − ecef₀)`, m.
    #[must_use]
    pub fn enu_from_ecef(&self, ecef_m: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * (ecef_m - self.origin_ecef_m)
    }

    /// ECEF of an ENU point: `ecef₀ + Rᵀ enu`, m.
    #[must_use]
    pub fn ecef_from_enu(&self, enu_m: &Vector3<f64>) -> Vector3<f64> {
        self.origin_ecef_m + self.rotation.transpose() * enu_m
    }

    /// The geodetic position of an ENU point.
    ///
    /// # Errors
    /// As [`Geodetic::from_ecef`].
    pub fn geodetic_of_enu(&self, enu_m: &Vector3<f64>) -> Result<Geodetic> {
        Geodetic::from_ecef(&self.ecef_from_enu(enu_m))
    }
}

/// `R(φ, λ)`: the rows are the east, north and up unit vectors at `at`, in ECEF.
fn enu_rotation(at: &Geodetic) -> Matrix3<f64> {
    let (sin_lat, cos_lat) = at.latitude_deg.to_radians().sin_cos();
    let (sin_lon, cos_lon) = at.longitude_deg.to_radians().sin_cos();
    Matrix3::new(
        -sin_lon,
        cos_lon,
        0.0,
        -sin_lat * cos_lon,
        -sin_lat * sin_lon,
        cos_lat,
        cos_lat * cos_lon,
        cos_lat * sin_lon,
        sin_lat,
    )
}

/// The elevation of a satellite seen from a receiver, rad in [−π/2, π/2]: the angle of the
/// line of sight above the receiver's local horizon (the plane normal to the ellipsoid normal).
///
/// ```text
/// u = R(φ_r, λ_r) (s − r) / ‖s − r‖        line of sight in the receiver's ENU
/// el = asin(u_up)
/// ```
///
/// # Units
/// Positions in m (ECEF), the result in rad.
///
/// # Errors
/// As [`Geodetic::from_ecef`] for the receiver; [`PositioningError::NonFinite`] for a NaN/∞
/// satellite; [`PositioningError::DegenerateGeometry`] when the satellite is at the receiver.
///
/// # Example
/// ```
/// use rtls_positioning::gnss::{elevation_rad, Geodetic};
/// let receiver = Geodetic { latitude_deg: 0.0, longitude_deg: 0.0, height_m: 0.0 }.to_ecef()?;
/// let overhead = receiver * (26_560e3 / 6_378_137.0);
/// assert!((elevation_rad(&receiver, &overhead)? - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
/// # Ok::<(), rtls_positioning::PositioningError>(())
/// ```
///
/// # References
/// E. D. Kaplan, C. J. Hegarty, *Understanding GPS/GNSS*, 3rd ed., 2017, §2.2 (local frames,
/// elevation and azimuth).
pub fn elevation_rad(receiver_ecef_m: &Vector3<f64>, satellite_ecef_m: &Vector3<f64>) -> Result<f64> {
    let receiver = Geodetic::from_ecef(receiver_ecef_m)?;
    if !satellite_ecef_m.iter().all(|v| v.is_finite()) {
        return Err(PositioningError::NonFinite {
            what: "satellite position",
        });
    }
    let line = satellite_ecef_m - receiver_ecef_m;
    let distance = line.norm();
    if distance <= 0.0 {
        return Err(PositioningError::DegenerateGeometry {
            reason: "the satellite is at the receiver, so it has no elevation",
        });
    }
    // u = R (s − r)/‖s − r‖,  el = asin(u_up)
    let up = (enu_rotation(&receiver) * line / distance)[2];
    Ok(up.clamp(-1.0, 1.0).asin())
}
