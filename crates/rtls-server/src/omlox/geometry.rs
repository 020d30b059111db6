//! GeoJSON geometries of the omlox objects: [`Point`], [`Polygon`] and a fence's [`Region`],
//! each position checked to have two or three numbers (the schema's `minItems` 2, `maxItems` 3).

use serde::{Deserialize, Serialize};

/// A GeoJSON Point: `{"type": "Point", "coordinates": [x, y(, z)]}`, interpreted in the owning
/// object's `crs` (`local`: metres in the site frame).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename = "Point", try_from = "Tagged<Vec<f64>>")]
pub struct Point {
    /// `[x, y]` or `[x, y, z]` (or longitude, latitude, elevation under EPSG:4326).
    pub coordinates: Vec<f64>,
}

/// A GeoJSON Polygon: `{"type": "Polygon", "coordinates": [ring, …]}`, each ring closed (its
/// first position repeated at the end), the first ring the outer boundary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename = "Polygon", try_from = "Tagged<Vec<Vec<Vec<f64>>>>")]
pub struct Polygon {
    /// Rings of positions `[x, y(, z)]`.
    pub coordinates: Vec<Vec<Vec<f64>>>,
}

/// A GeoJSON geometry as read: its `type` and coordinates, before [`Point`] or [`Polygon`]
/// checks the type is theirs (serde's internal tag alone does not, for a struct).
#[derive(Deserialize)]
struct Tagged<C> {
    #[serde(rename = "type")]
    kind: String,
    coordinates: C,
}

impl TryFrom<Tagged<Vec<f64>>> for Point {
    type Error = String;

    fn try_from(tagged: Tagged<Vec<f64>>) -> std::result::Result<Self, String> {
        if tagged.kind != "Point" {
            return Err(format!("type `{}`: a Point is expected", tagged.kind));
        }
        check_position(&tagged.coordinates)?;
        Ok(Self {
            coordinates: tagged.coordinates,
        })
    }
}

impl TryFrom<Tagged<Vec<Vec<Vec<f64>>>>> for Polygon {
    type Error = String;

    fn try_from(tagged: Tagged<Vec<Vec<Vec<f64>>>>) -> std::result::Result<Self, String> {
        if tagged.kind != "Polygon" {
            return Err(format!("type `{}`: a Polygon is expected", tagged.kind));
        }
        tagged
            .coordinates
            .iter()
            .flatten()
            .try_for_each(|p| check_position(p))?;
        Ok(Self {
            coordinates: tagged.coordinates,
        })
    }
}

/// A GeoJSON position has two or three numbers (the schema's `minItems` 2, `maxItems` 3).
fn check_position(position: &[f64]) -> std::result::Result<(), String> {
    if (2..=3).contains(&position.len()) {
        Ok(())
    } else {
        Err(format!("a position has 2 or 3 coordinates, not {}", position.len()))
    }
}

/// A GeoJSON position: two or three numbers (the schema's `minItems` 2, `maxItems` 3).
fn position<'de, D: serde::Deserializer<'de>>(deserializer: D) -> std::result::Result<Vec<f64>, D::Error> {
    let position = Vec::<f64>::deserialize(deserializer)?;
    check_position(&position).map_err(serde::de::Error::custom)?;
    Ok(position)
}

/// Polygon rings whose every position has two or three numbers.
fn rings<'de, D: serde::Deserializer<'de>>(deserializer: D) -> std::result::Result<Vec<Vec<Vec<f64>>>, D::Error> {
    let rings = Vec::<Vec<Vec<f64>>>::deserialize(deserializer)?;
    rings
        .iter()
        .flatten()
        .try_for_each(|p| check_position(p))
        .map_err(serde::de::Error::custom)?;
    Ok(rings)
}

/// A fence's region: a Point (with the fence's `radius`) or a Polygon. Members other than
/// `type` and `coordinates` are ignored (RFC 7946 §6.1's foreign members; the spec's Point and
/// Polygon schemas do not close their objects).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type")]
pub enum Region {
    /// A circle around a point (radius in the fence's `radius`, m).
    Point {
        /// `[x, y(, z)]`.
        #[serde(deserialize_with = "position")]
        coordinates: Vec<f64>,
    },
    /// A polygon.
    Polygon {
        /// Closed rings.
        #[serde(deserialize_with = "rings")]
        coordinates: Vec<Vec<Vec<f64>>>,
    },
}

impl Region {
    /// The same region with every position replaced by `f(position, field)`, `field` the
    /// position's JSON path (`region.coordinates`, `region.coordinates[r][i]`) for an error
    /// to name; the first error stops the mapping.
    ///
    /// # Errors
    /// The first error of `f`.
    pub fn try_map_positions<E>(&self, mut f: impl FnMut(&[f64], String) -> Result<Vec<f64>, E>) -> Result<Self, E> {
        Ok(match self {
            Self::Point { coordinates } => Self::Point {
                coordinates: f(coordinates, "region.coordinates".into())?,
            },
            Self::Polygon { coordinates } => Self::Polygon {
                coordinates: coordinates
                    .iter()
                    .enumerate()
                    .map(|(r, ring)| {
                        ring.iter()
                            .enumerate()
                            .map(|(i, p)| f(p, format!("region.coordinates[{r}][{i}]")))
                            .collect::<Result<Vec<_>, E>>()
                    })
                    .collect::<Result<Vec<_>, E>>()?,
            },
        })
    }
}
