//! The coordinate reference systems the hub takes in a `crs` field or parameter.

/// omlox's `local` (the site's metres, or a zone's frame) or `EPSG:4326` (WGS-84 longitude and
/// latitude in degrees, height in metres above the ellipsoid).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Crs {
    /// `local`.
    Local,
    /// `EPSG:4326` (also written `wgs84`).
    Wgs84,
}

impl Crs {
    /// The CRS `crs` names, case-insensitively; `None` is `local`.
    ///
    /// # Errors
    /// The reason, naming the two it takes, for any other.
    ///
    /// # Examples
    /// ```
    /// use rtls_server::omlox::crs::Crs;
    /// assert_eq!(Crs::parse(None), Ok(Crs::Local));
    /// assert_eq!(Crs::parse(Some("epsg:4326")), Ok(Crs::Wgs84));
    /// assert!(Crs::parse(Some("EPSG:3857")).unwrap_err().contains("EPSG:3857"));
    /// ```
    pub fn parse(crs: Option<&str>) -> Result<Self, String> {
        match crs {
            None => Ok(Self::Local),
            Some(text) if text.eq_ignore_ascii_case("local") => Ok(Self::Local),
            Some(text) if text.eq_ignore_ascii_case("EPSG:4326") || text.eq_ignore_ascii_case("wgs84") => {
                Ok(Self::Wgs84)
            }
            Some(other) => Err(format!("`{other}` is not one of local, EPSG:4326")),
        }
    }
}
