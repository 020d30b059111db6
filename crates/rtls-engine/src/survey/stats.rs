//! Running mean and spread (Welford) and the robust location and scale of a population
//! (median and MAD).

/// Count, mean and spread of a stream of values, updated one value at a time without storing
/// them (Welford's algorithm: no catastrophic cancellation, unlike `Σx² − n x̄²`).
///
/// For each new value `x`: `n ← n + 1`, `δ = x − x̄`, `x̄ ← x̄ + δ / n`,
/// `M₂ ← M₂ + δ (x − x̄)`; the sample variance is `M₂ / (n − 1)`.
///
/// # Units
/// Those of the values pushed (dB for RSSI residuals, m for range residuals).
///
/// # Examples
/// ```
/// use rtls_engine::survey::RunningStats;
///
/// let mut stats = RunningStats::default();
/// assert_eq!(stats.mean(), None);
/// for x in [2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0] {
///     stats.push(x);
/// }
/// assert_eq!(stats.count(), 8);
/// assert_eq!(stats.mean(), Some(5.0));
/// assert!((stats.variance().unwrap() - 32.0 / 7.0).abs() < 1e-12);
/// ```
///
/// # References
/// B. P. Welford, "Note on a method for calculating corrected sums of squares and products",
/// *Technometrics* 4(3), 1962, pp. 419–420.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RunningStats {
    count: usize,
    mean: f64,
    m2: f64,
}

impl RunningStats {
    /// Adds one value.
    pub fn push(&mut self, value: f64) {
        self.count += 1;
        // δ = x − x̄
        let delta = value - self.mean;
        // x̄ ← x̄ + δ / n
        self.mean += delta / self.count as f64;
        // M₂ ← M₂ + δ (x − x̄)
        self.m2 += delta * (value - self.mean);
    }

    /// Number of values pushed.
    #[must_use]
    pub fn count(&self) -> usize {
        self.count
    }

    /// Mean of the values, `None` before the first.
    #[must_use]
    pub fn mean(&self) -> Option<f64> {
        (self.count > 0).then_some(self.mean)
    }

    /// Sample variance `M₂ / (n − 1)` (unit²), `None` with fewer than 2 values.
    #[must_use]
    pub fn variance(&self) -> Option<f64> {
        (self.count > 1).then(|| (self.m2 / (self.count - 1) as f64).max(0.0))
    }

    /// Sample standard deviation `√(M₂ / (n − 1))`, `None` with fewer than 2 values.
    #[must_use]
    pub fn std(&self) -> Option<f64> {
        self.variance().map(f64::sqrt)
    }
}

/// `1 / Φ⁻¹(3/4)`: scales the median absolute deviation to the standard deviation of a normal
/// population.
pub(crate) const MAD_TO_STD: f64 = 1.482_602_218_505_602;

/// Median of `values` (mean of the two middle ones for an even count), sorting them in place;
/// `None` when empty. The values must be finite.
pub(crate) fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    Some(if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    })
}

/// `(median, MAD)` of finite values: `m = median(x)`, `MAD = median(|x − m|)`; `None` when
/// empty.
pub(crate) fn median_and_mad(values: &[f64]) -> Option<(f64, f64)> {
    let mut sorted = values.to_vec();
    let m = median(&mut sorted)?;
    let mut deviations: Vec<f64> = values.iter().map(|x| (x - m).abs()).collect();
    let mad = median(&mut deviations)?;
    Some((m, mad))
}
