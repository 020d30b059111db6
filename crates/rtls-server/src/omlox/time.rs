//! ISO 8601 UTC timestamps (`2019-09-02T22:02:24.355Z`) ↔ seconds since the Unix epoch, the
//! engine's clock when a site runs on Unix time.
//!
//! # References
//! - H. Hinnant, "chrono-Compatible Low-Level Date Algorithms" (`days_from_civil`,
//!   `civil_from_days`), proleptic Gregorian calendar.

use crate::{Result, ServerError};

fn days_from_civil(year: i64, month: i64, day: i64) -> i64 {
    let y = if month <= 2 { year - 1 } else { year };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (month + 9) % 12;
    let doy = (153 * mp + 2) / 5 + day - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

fn civil_from_days(days: i64) -> (i64, i64, i64) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    (year, month, day)
}

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
    let days = ms.div_euclid(86_400_000);
    let rem = ms.rem_euclid(86_400_000);
    let (year, month, day) = civil_from_days(days);
    let (h, m, s, milli) = (rem / 3_600_000, rem / 60_000 % 60, rem / 1000 % 60, rem % 1000);
    Ok(format!(
        "{year:04}-{month:02}-{day:02}T{h:02}:{m:02}:{s:02}.{milli:03}Z"
    ))
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
    let bad = || ServerError::Unrepresentable {
        field: field.into(),
        reason: format!("`{text}` is not an ISO 8601 timestamp such as 2019-09-02T22:02:24.355Z"),
    };
    let b = text.as_bytes();
    if b.len() < 20 || b[4] != b'-' || b[7] != b'-' || !matches!(b[10], b'T' | b't') || b[13] != b':' || b[16] != b':' {
        return Err(bad());
    }
    let num = |range: std::ops::Range<usize>| -> Result<i64> {
        let s = text.get(range).ok_or_else(bad)?;
        if !s.bytes().all(|c| c.is_ascii_digit()) {
            return Err(bad());
        }
        s.parse::<i64>().map_err(|_| bad())
    };
    let (year, month, day) = (num(0..4)?, num(5..7)?, num(8..10)?);
    let (h, m, s) = (num(11..13)?, num(14..16)?, num(17..19)?);
    if !(1..=12).contains(&month) || !(1..=31).contains(&day) || h > 23 || m > 59 || s > 60 {
        return Err(bad());
    }
    let mut rest = &text[19..];
    let mut fraction = 0.0;
    if let Some(after) = rest.strip_prefix('.') {
        let digits = after.bytes().take_while(u8::is_ascii_digit).count();
        if digits == 0 {
            return Err(bad());
        }
        fraction = format!("0.{}", &after[..digits]).parse::<f64>().map_err(|_| bad())?;
        rest = &after[digits..];
    }
    let offset_s = match rest {
        "Z" | "z" => 0,
        _ if rest.len() == 6 && rest.as_bytes()[3] == b':' => {
            let sign = match rest.as_bytes()[0] {
                b'+' => 1,
                b'-' => -1,
                _ => return Err(bad()),
            };
            let oh = num(text.len() - 5..text.len() - 3)?;
            let om = num(text.len() - 2..text.len())?;
            sign * (oh * 3600 + om * 60)
        }
        _ => return Err(bad()),
    };
    let whole = days_from_civil(year, month, day) * 86_400 + h * 3600 + m * 60 + s - offset_s;
    #[allow(clippy::cast_precision_loss)] // |whole| < 2^53
    Ok(whole as f64 + fraction)
}
