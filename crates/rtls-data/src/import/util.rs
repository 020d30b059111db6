//! Small helpers shared by the importers: reading a text file, parse errors naming file /
//! line / field, and robust statistics.

use std::path::Path;

use crate::{DataError, Result};

/// Reads a whole text file.
///
/// # Errors
/// [`DataError::Io`] naming the file.
pub(in crate::import) fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|source| DataError::Io {
        file: path.to_path_buf(),
        source,
    })
}

/// A [`DataError::Parse`] for `file`, 1-based `line`, `field`.
pub(in crate::import) fn parse_error(
    file: &Path,
    line: u64,
    field: impl Into<String>,
    reason: impl Into<String>,
) -> DataError {
    DataError::Parse {
        file: file.to_path_buf(),
        line,
        field: field.into(),
        reason: reason.into(),
    }
}

/// A [`DataError::Content`] for `file`.
pub(in crate::import) fn content_error(file: &Path, reason: impl Into<String>) -> DataError {
    DataError::Content {
        file: file.to_path_buf(),
        reason: reason.into(),
    }
}

/// Parses a finite number.
///
/// # Errors
/// [`DataError::Parse`] naming `file`, `line` and `field`, with the offending text.
pub(in crate::import) fn parse_finite(file: &Path, line: u64, field: &str, text: &str) -> Result<f64> {
    let trimmed = text.trim();
    match trimmed.parse::<f64>() {
        Ok(value) if value.is_finite() => Ok(value),
        Ok(_) => Err(parse_error(
            file,
            line,
            field,
            format!("`{trimmed}` is not a finite number"),
        )),
        Err(_) => Err(parse_error(file, line, field, format!("`{trimmed}` is not a number"))),
    }
}

/// Median of `values` (mean of the two middle values for an even count); `None` when empty.
/// NaN-free input is assumed (every caller feeds parsed finite numbers).
pub(in crate::import) fn median(values: &[f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mut v = values.to_vec();
    let n = v.len();
    // O(n) selection: v[n/2] is the upper middle, everything before it is ≤ it
    let (lower, upper, _) = v.select_nth_unstable_by(n / 2, f64::total_cmp);
    let upper = *upper;
    Some(if n % 2 == 1 {
        upper
    } else {
        0.5 * (lower.iter().copied().fold(f64::NEG_INFINITY, f64::max) + upper)
    })
}

/// Mean and sample standard deviation (`n − 1`); `None` for fewer than two values.
pub(in crate::import) fn mean_std(values: &[f64]) -> Option<(f64, f64)> {
    if values.len() < 2 {
        return None;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    // s² = Σ (x − x̄)² / (n − 1)
    let variance = values.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    Some((mean, variance.sqrt()))
}

/// Root mean square; `None` when empty.
pub(in crate::import) fn rms(values: &[f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    Some((values.iter().map(|x| x * x).sum::<f64>() / values.len() as f64).sqrt())
}

/// Pearson correlation of two equally long samples; `None` when shorter than 2 or constant.
pub(in crate::import) fn pearson(a: &[f64], b: &[f64]) -> Option<f64> {
    if a.len() != b.len() || a.len() < 2 {
        return None;
    }
    let n = a.len() as f64;
    let (mean_a, mean_b) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        // r = Σ(a−ā)(b−b̄) / √(Σ(a−ā)² Σ(b−b̄)²)
        sab += (x - mean_a) * (y - mean_b);
        saa += (x - mean_a).powi(2);
        sbb += (y - mean_b).powi(2);
    }
    (saa > 0.0 && sbb > 0.0).then(|| sab / (saa * sbb).sqrt())
}

/// Index of the last element of the non-decreasing `times` that is ≤ `t` and the next one, for
/// linear interpolation; `None` outside `[times[0], times[last]]`.
pub(in crate::import) fn bracket(times: &[f64], t: f64) -> Option<(usize, usize)> {
    let (first, last) = (*times.first()?, *times.last()?);
    if !(first..=last).contains(&t) {
        return None;
    }
    // first index with times[j] > t
    let j = times.partition_point(|&x| x <= t);
    if j == times.len() {
        let i = times.len() - 1;
        return Some((i, i));
    }
    Some((j.saturating_sub(1), j))
}

/// Interpolation weight of `t` between `t0` and `t1` (0 when they coincide).
pub(in crate::import) fn weight(t0: f64, t1: f64, t: f64) -> f64 {
    if t1 > t0 {
        (t - t0) / (t1 - t0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statistics_match_hand_computation() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median(&[]), None);
        let (mean, std) = mean_std(&[1.0, 2.0, 3.0, 4.0]).unwrap();
        assert!((mean - 2.5).abs() < 1e-15);
        // Σ(x−2.5)² = 5, /3
        assert!((std - (5.0_f64 / 3.0).sqrt()).abs() < 1e-15);
        assert!((rms(&[3.0, 4.0]).unwrap() - 12.5_f64.sqrt()).abs() < 1e-15);
        assert!((pearson(&[1.0, 2.0, 3.0], &[2.0, 4.0, 6.0]).unwrap() - 1.0).abs() < 1e-12);
        assert!((pearson(&[1.0, 2.0, 3.0], &[3.0, 2.0, 1.0]).unwrap() + 1.0).abs() < 1e-12);
        assert_eq!(pearson(&[1.0, 1.0], &[1.0, 2.0]), None);
    }

    #[test]
    fn bracket_finds_neighbours_and_handles_duplicates() {
        let times = [0.0, 1.0, 1.0, 2.0];
        assert_eq!(bracket(&times, 0.5), Some((0, 1)));
        // duplicate time stamps: the later of the equal pair brackets forward
        assert_eq!(bracket(&times, 1.0), Some((2, 3)));
        assert_eq!(bracket(&times, 2.0), Some((3, 3)));
        assert_eq!(bracket(&times, 2.5), None);
        assert_eq!(bracket(&times, -0.1), None);
        assert!((weight(1.0, 3.0, 2.5) - 0.75).abs() < 1e-15);
        assert_eq!(weight(1.0, 1.0, 1.0), 0.0);
    }

    #[test]
    fn parse_finite_names_the_field() {
        let error = parse_finite(Path::new("f.csv"), 7, "x", "abc").unwrap_err().to_string();
        assert_eq!(error, "f.csv:7: field `x`: `abc` is not a number");
        let error = parse_finite(Path::new("f.csv"), 2, "y", "inf").unwrap_err().to_string();
        assert!(error.contains("f.csv:2: field `y`"), "{error}");
    }
}
