//! Seeded, parallel, deterministic Monte Carlo.
//!
//! Run `i` of an experiment with base seed `s` draws all its randomness from
//! [`run_seed`]`(s, i)`, a SplitMix64 mix of the two, so a run's result depends on `(s, i)`
//! only — not on the thread that ran it, nor on how many threads there are. [`monte_carlo`]
//! runs the closures on rayon's pool and returns the results in run order, so every
//! aggregate computed from them (sums in order) is bit-identical for any thread count.

use rayon::prelude::*;

use crate::error::{Result, SimError};

/// Reports finished work units (one per Monte Carlo run) to a progress display.
///
/// # Example
/// ```
/// use std::sync::atomic::{AtomicU64, Ordering};
/// let done = AtomicU64::new(0);
/// let tick = |n: u64| { done.fetch_add(n, Ordering::Relaxed); };
/// let progress = rtls_sim::montecarlo::Progress::new(&tick);
/// progress.advance(3);
/// assert_eq!(done.load(Ordering::Relaxed), 3);
/// rtls_sim::montecarlo::Progress::none().advance(1); // discards
/// ```
#[derive(Clone, Copy)]
pub struct Progress<'a> {
    tick: Option<&'a (dyn Fn(u64) + Sync)>,
}

impl std::fmt::Debug for Progress<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Progress")
            .field("reporting", &self.tick.is_some())
            .finish()
    }
}

impl<'a> Progress<'a> {
    /// Calls `tick(n)` when `n` more units are done (from any thread).
    #[must_use]
    pub fn new(tick: &'a (dyn Fn(u64) + Sync)) -> Self {
        Self { tick: Some(tick) }
    }

    /// Reports nowhere.
    #[must_use]
    pub fn none() -> Self {
        Self { tick: None }
    }

    /// `n` more units are done.
    pub fn advance(&self, n: u64) {
        if let Some(tick) = self.tick {
            tick(n);
        }
    }
}

/// The seed of run `run` of an experiment with base seed `base_seed`: SplitMix64 of
/// `base_seed + (run + 1) · γ`, `γ = 0x9E37_79B9_7F4A_7C15` (the golden-ratio increment).
///
/// # Example
/// ```
/// use rtls_sim::montecarlo::run_seed;
/// assert_eq!(run_seed(7, 0), run_seed(7, 0));
/// assert_ne!(run_seed(7, 0), run_seed(7, 1));
/// assert_ne!(run_seed(7, 0), run_seed(8, 0));
/// ```
///
/// # References
/// G. L. Steele, D. Lea, C. H. Flood, "Fast splittable pseudorandom number generators",
/// OOPSLA 2014 (SplitMix64).
#[must_use]
pub fn run_seed(base_seed: u64, run: usize) -> u64 {
    const GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;
    // z = s + (i + 1) γ
    let mut z = base_seed.wrapping_add(GAMMA.wrapping_mul(run as u64 + 1));
    // SplitMix64 finaliser
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Runs `run(seed_i)` for `i = 0 … runs − 1` in parallel with `seed_i = run_seed(base_seed, i)`,
/// advancing `progress` by one per finished run, and returns the results in run order.
///
/// # Errors
/// [`SimError::InvalidParameter`] (`runs`) for zero runs; otherwise the error of the first
/// failing run (in run order).
///
/// # Example
/// ```
/// use rtls_sim::montecarlo::{monte_carlo, run_seed, Progress};
/// let seeds = monte_carlo(4, 42, Progress::none(), |seed| Ok(seed))?;
/// assert_eq!(seeds, (0..4).map(|i| run_seed(42, i)).collect::<Vec<_>>());
/// # Ok::<(), rtls_sim::SimError>(())
/// ```
pub fn monte_carlo<T, F>(runs: usize, base_seed: u64, progress: Progress<'_>, run: F) -> Result<Vec<T>>
where
    T: Send,
    F: Fn(u64) -> Result<T> + Sync,
{
    if runs == 0 {
        return Err(SimError::InvalidParameter {
            name: "runs",
            reason: "a Monte Carlo experiment needs at least one run",
        });
    }
    (0..runs)
        .into_par_iter()
        .map(|i| {
            let result = run(run_seed(base_seed, i));
            progress.advance(1);
            result
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn draws(threads: usize) -> Vec<f64> {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            monte_carlo(64, 5, Progress::none(), |seed| {
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
                Ok((0..100).map(|_| rng.gen::<f64>()).sum::<f64>())
            })
        })
        .unwrap()
    }

    #[test]
    fn results_do_not_depend_on_the_thread_count() {
        let one = draws(1);
        assert_eq!(one, draws(2));
        assert_eq!(one, draws(5));
        // and the runs differ from each other
        assert!(one.windows(2).all(|w| w[0] != w[1]));
    }

    #[test]
    fn the_first_error_in_run_order_is_returned() {
        let result = monte_carlo(10, 1, Progress::none(), |seed| {
            if seed == run_seed(1, 3) || seed == run_seed(1, 7) {
                Err(SimError::EmptyInput { what: "run" })
            } else {
                Ok(seed)
            }
        });
        assert_eq!(result, Err(SimError::EmptyInput { what: "run" }));
        assert!(monte_carlo(0, 1, Progress::none(), Ok).is_err());
    }

    #[test]
    fn progress_counts_every_run() {
        let done = std::sync::atomic::AtomicU64::new(0);
        let tick = |n: u64| {
            done.fetch_add(n, std::sync::atomic::Ordering::Relaxed);
        };
        monte_carlo(17, 0, Progress::new(&tick), Ok).unwrap();
        assert_eq!(done.into_inner(), 17);
    }
}
