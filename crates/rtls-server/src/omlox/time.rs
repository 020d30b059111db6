//! ISO 8601 UTC timestamps (`2019-09-02T22:02:24.355Z`) ↔ seconds since the Unix epoch, the
//! engine's clock when a site runs on Unix time (RFC 3339 via the `time` crate).

use time::format_description::well_known::Rfc3339;
use time::macros::format_description;
use time::OffsetDateTime;

use crate::{Result, ServerError};

/// Formats Unix time as ISO 8601 UTC with millisecond precision (rounded to the nearest ms).
///
/// # Errors
/// [`ServerError::Unrepresentable`] naming `field` when the time is not finite or falls outside
/// the years 0000–9999.
///
/// # Examples
/// ```
/// use rtls_server::omlox::time::format_timestamp;
/// assert_eq!(format_timestamp(1_567_461_744.355, "t").unwrap(), "2019-09-02T22:02:24.355Z");
/// ```
pub fn format_timestamp(unix_s: f64, field: &str) -> Result<String> {
    let bad = |reason: &str| ServerError::Unrepresentable {
        field: field.into(),
        reason: reason.into(),
    };
    if !unix_s.is_finite() {
        return Err(bad("time is not finite"));
    }
    // Years 0000..=9999 span about ±2.6e11 s around the epoch.
    let ms_f = (unix_s * 1000.0).round();
    if !(-62_167_219_200_000.0..=253_402_300_799_999.0).contains(&ms_f) {
        return Err(bad(
            "time is outside the years 0000–9999 (is the site clock Unix seconds?)",
        ));
    }
    #[allow(clippy::cast_possible_truncation)] // range checked above
    let ms = ms_f as i64;
    let time = OffsetDateTime::from_unix_timestamp_nanos(i128::from(ms) * 1_000_000)
        .map_err(|_| bad("time is outside the representable range"))?;
    time.format(format_description!(
        "[year]-[month]-[day]T[hour]:[minute]:[second].[subsecond digits:3]Z"
    ))
    .map_err(|_| bad("time cannot be formatted"))
}

/// Parses an ISO 8601 / RFC 3339 timestamp `YYYY-MM-DDTHH:MM:SS[.fraction](Z|±HH:MM)` into Unix
/// seconds.
///
/// # Errors
/// [`ServerError::Unrepresentable`] naming `field` with the expected form.
///
/// # Examples
/// ```
/// use rtls_server::omlox::time::parse_timestamp;
/// assert_eq!(parse_timestamp("1970-01-02T00:00:01.5Z", "t").unwrap(), 86_401.5);
/// assert_eq!(parse_timestamp("1970-01-01T01:00:00+01:00", "t").unwrap(), 0.0);
/// ```
pub fn parse_timestamp(text: &str, field: &str) -> Result<f64> {
    let time = OffsetDateTime::parse(text, &Rfc3339).map_err(|_| ServerError::Unrepresentable {
        field: field.into(),
        reason: format!("`{text}` is not an ISO 8601 timestamp such as 2019-09-02T22:02:24.355Z"),
    })?;
    #[allow(clippy::cast_precision_loss)] // ns since the epoch, years 0000–9999: exact to < 1 µs
    Ok(time.unix_timestamp_nanos() as f64 / 1e9)
}
