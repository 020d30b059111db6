//! A track's estimates of its anchors' range offsets (`[tracker.range_bias]`): the bias vector
//! the tightly coupled range update reads, and the round of readings it learns from
//! ([`rtls_estimation::bias`]).

use nalgebra::DMatrix;
use rtls_estimation::bias::{BiasModel, BiasObservation, BiasPrior, BiasVector};

use crate::error::Result;
use crate::site::{RangeBiasSettings, Site};

/// A reader's largest learnt offset, in multiples of its prior standard deviation, when the
/// site does not bound them (`tracker.range_bias.max_abs_m`).
const MAX_ABS_PRIOR_STDS: f64 = 5.0;

/// The offsets' model: the random walk, and each anchor's prior and bound (`[tracker.range_bias]`
/// with each reader's `radio.range.offset_std_m` and technology). An immutable strategy.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct OffsetModel {
    pub(super) bias: BiasModel,
    /// By anchor index (the site's reader order).
    priors: Vec<BiasPrior>,
}

impl OffsetModel {
    /// Each reader's prior: its own `radio.range.offset_std_m`, else the site's `prior_std_m`,
    /// else its technology's default; bound the site's `max_abs_m`, else 5 σ_b.
    ///
    /// # Errors
    /// [`crate::error::EngineError`] for a prior or bound that is not finite and > 0, or a
    /// negative random walk (the site loader's range checks refuse them first).
    pub(super) fn new(settings: &RangeBiasSettings, site: &Site) -> Result<Self> {
        let prior = |std_m: f64| BiasPrior::new(std_m, settings.max_abs_m.unwrap_or(MAX_ABS_PRIOR_STDS * std_m));
        let priors = site
            .readers
            .iter()
            .map(|reader| {
                let own = reader
                    .radio
                    .as_ref()
                    .and_then(|r| r.range.as_ref())
                    .and_then(|r| r.offset_std_m);
                prior(
                    own.or(settings.prior_std_m)
                        .unwrap_or(reader.technology.range_offset_prior_std_m()),
                )
            })
            .collect::<std::result::Result<Vec<_>, _>>()?;
        // readers outside the site (none today) take UWB's
        let default_std_m = settings
            .prior_std_m
            .unwrap_or(crate::site::Technology::Uwb.range_offset_prior_std_m());
        let default = prior(default_std_m)?;
        Ok(Self {
            bias: BiasModel::new(default.std(), settings.random_walk_m_per_sqrt_s, default.max_abs())?,
            priors,
        })
    }

    /// The prior of `anchor`'s offset.
    pub(super) fn prior(&self, anchor: usize) -> BiasPrior {
        self.priors.get(anchor).copied().unwrap_or(self.bias.prior())
    }
}

/// Readings older than this (behind the newest) leave the round: the position errors the
/// projection removes must be the same for every reading of a round, s.
const ROUND_WINDOW_S: f64 = 2.0;

/// A reading's part in a learning round: what [`BiasObservation`] needs but its variance, which
/// [`RangeBiases`] sets from the time since its last round.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct RoundReading {
    /// `ν = r − b̂ − h(x)`: the offset-corrected range against the track's position, m.
    pub(super) innovation_m: f64,
    /// The reading's own noise variance (one look), m².
    pub(super) noise_variance_m2: f64,
    /// `∂h/∂p` at that position (unused components 0).
    pub(super) gradient: [f64; 3],
}

/// One reading of the open round.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
struct Pending {
    anchor: usize,
    reading: RoundReading,
    time_s: f64,
}

/// What a learning round did to the offsets, for the state's cross-covariance with them
/// ([`super::offset_cross`]).
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Learning {
    /// Nothing was learnt.
    Nothing,
    /// The offsets' covariance went from `prior` (the random walk's prediction) to
    /// `posterior`, both over every slot.
    Learnt {
        prior: DMatrix<f64>,
        posterior: DMatrix<f64>,
    },
    /// A numerical failure: the offsets start again from their prior.
    Forgotten,
}

/// Each anchor's offset as this track has learnt it, and the readings of the open round.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct RangeBiases {
    biases: BiasVector,
    /// Slot in `biases` of each anchor index; `None` before the anchor's first considered
    /// range or learning round.
    slots: Vec<Option<usize>>,
    /// Per slot: whether no round has learnt from it yet (its value is the prior's, 0). Slots
    /// beyond its length have been learnt from.
    #[serde(default)]
    prior_only: Vec<bool>,
    round: Vec<Pending>,
    /// Time of the newest reading of the last round learnt from, s.
    last_learnt_s: Option<f64>,
}

impl RangeBiases {
    /// `(b̂, P_b⁻)` of `anchor` at `time_s`: `(0, σ_b²)` before it has been learnt.
    pub(super) fn offset(&self, model: &OffsetModel, anchor: usize, time_s: f64) -> (f64, f64) {
        match self.slots.get(anchor).copied().flatten() {
            Some(slot) => model.bias.predicted(&self.biases, slot, time_s),
            None => (0.0, model.prior(anchor).variance()),
        }
    }

    /// The slot of `anchor`, added with the prior `N(0, σ_b²)` on first use: a considered
    /// range needs its offset's slot before any round has learnt it.
    pub(super) fn slot(&mut self, model: &OffsetModel, anchor: usize) -> usize {
        if self.slots.len() <= anchor {
            self.slots.resize(anchor + 1, None);
        }
        if let Some(slot) = self.slots[anchor] {
            return slot;
        }
        let slot = model.bias.add_reader_with(&mut self.biases, model.prior(anchor));
        self.slots[anchor] = Some(slot);
        self.prior_only.resize(slot + 1, false);
        self.prior_only[slot] = true;
        slot
    }

    /// `(P_bᵢᵢ, P_b[i, ·])` of slot `i` at `time_s`: its variance after the random walk, and its
    /// row (the other entries do not walk; entry `i` is the walked variance too).
    pub(super) fn covariance_column(&self, model: &OffsetModel, slot: usize, time_s: f64) -> (f64, Vec<f64>) {
        let variance = model.bias.predicted(&self.biases, slot, time_s).1;
        // P_b is symmetric: its row i is its column i
        let mut row: Vec<f64> = self.biases.covariance().column(slot).iter().copied().collect();
        row[slot] = variance;
        (variance, row)
    }

    /// Whether a reading at `time_s` is wanted: a round is open, or the last round learnt from
    /// is at least the error correlation time `τ_c` old. Rounds closer together than `τ_c`
    /// would repeat the same errors, so they are not collected at all (the learning's cost on
    /// the hot path is one round per `τ_c`); [`Self::learn`] counts a round's information for the
    /// time since the last one.
    pub(super) fn wants(&self, time_s: f64, correlation_s: f64) -> bool {
        !self.round.is_empty() || self.last_learnt_s.is_none_or(|t| time_s - t >= correlation_s)
    }

    /// Adds a reading (its innovation against the prediction, its one-look variance without the
    /// offset's, its gradient) to the open round. A second reading of an anchor already in the
    /// round closes the round first: its readings teach the offsets (see
    /// [`BiasModel::update_observable`]), and a new round starts if one is wanted.
    pub(super) fn observe(
        &mut self,
        model: &OffsetModel,
        anchor: usize,
        reading: RoundReading,
        time_s: f64,
        dimensions: usize,
        correlation_s: f64,
    ) -> Learning {
        self.round.retain(|p| time_s - p.time_s <= ROUND_WINDOW_S);
        let mut learning = Learning::Nothing;
        if self.round.iter().any(|p| p.anchor == anchor) {
            learning = self.learn(model, dimensions, correlation_s);
            self.round.clear();
        }
        if self.wants(time_s, correlation_s) {
            self.round.push(Pending {
                anchor,
                reading,
                time_s,
            });
        }
        learning
    }

    /// Learns from one fix-then-filter epoch at once (its readings' residuals against the
    /// epoch's fix, one per anchor), if one is wanted: the open round is replaced by it.
    pub(super) fn learn_epoch(
        &mut self,
        model: &OffsetModel,
        readings: &[(usize, RoundReading)],
        time_s: f64,
        dimensions: usize,
        correlation_s: f64,
    ) -> Learning {
        self.round.clear();
        if !self.wants(time_s, correlation_s) {
            return Learning::Nothing;
        }
        self.round = readings
            .iter()
            .map(|&(anchor, reading)| Pending {
                anchor,
                reading,
                time_s,
            })
            .collect();
        let learning = self.learn(model, dimensions, correlation_s);
        self.round.clear();
        learning
    }

    /// Drops the open round: a reading of it fell outside the gate, so the prediction its
    /// innovations are measured against is not to be trusted.
    pub(super) fn discard_round(&mut self) {
        self.round.clear();
    }

    /// Learns from the open round; a numerical failure forgets what was learnt (the offsets
    /// start again from their prior) rather than keep a broken vector.
    ///
    /// A round `Δt` after the last one counts as `1 / max(1, 2 τ_c / Δt)` of independent looks
    /// (each reading's variance `c σ²`, the filter's rule for correlated errors).
    fn learn(&mut self, model: &OffsetModel, dimensions: usize, correlation_s: f64) -> Learning {
        if self.round.len() <= dimensions {
            return Learning::Nothing;
        }
        let anchors: Vec<usize> = self.round.iter().map(|p| p.anchor).collect();
        let slots: Vec<usize> = anchors.into_iter().map(|anchor| self.slot(model, anchor)).collect();
        let newest_s = self.round.iter().map(|p| p.time_s).fold(f64::NEG_INFINITY, f64::max);
        // c = max(1, 2 τ_c / Δt), Δt since the last round learnt from
        let since_s = self.last_learnt_s.map_or(f64::INFINITY, |t| newest_s - t);
        let inflation = (2.0 * correlation_s / since_s).max(1.0);
        let observations: Vec<BiasObservation> = self
            .round
            .iter()
            .map(|p| BiasObservation {
                innovation: p.reading.innovation_m,
                variance: inflation * p.reading.noise_variance_m2,
                noise_variance: p.reading.noise_variance_m2,
                gradient: p.reading.gradient,
            })
            .collect();
        self.last_learnt_s = Some(newest_s);
        let learnt = model.bias.predict(&self.biases, newest_s).and_then(|predicted| {
            let posterior = model
                .bias
                .update_observable(&predicted, &slots, &observations, dimensions)?;
            Ok((predicted, posterior))
        });
        match learnt {
            Ok((predicted, biases)) => {
                for &slot in &slots {
                    if let Some(flag) = self.prior_only.get_mut(slot) {
                        *flag = false;
                    }
                }
                let learning = Learning::Learnt {
                    prior: predicted.covariance().clone(),
                    posterior: biases.covariance().clone(),
                };
                self.biases = biases;
                learning
            }
            Err(_) => {
                *self = Self::default();
                Learning::Forgotten
            }
        }
    }

    /// The learnt offsets: anchor index, value and standard deviation (anchors no round has
    /// learnt from yet are left out).
    pub(crate) fn estimates(&self) -> impl Iterator<Item = (usize, f64, f64)> + '_ {
        self.slots.iter().enumerate().filter_map(|(anchor, slot)| {
            slot.filter(|&slot| !self.prior_only.get(slot).copied().unwrap_or(false))
                .map(|slot| (anchor, self.biases.value(slot), self.biases.variance(slot).sqrt()))
        })
    }
}

/// One learnt offset, as [`crate::tracker::Tracker::range_offsets`] reports it.
#[derive(Debug, Clone, PartialEq)]
pub struct RangeOffset {
    /// The tag whose track learnt it.
    pub tag: String,
    /// The anchor's id.
    pub anchor: String,
    /// The offset beyond the site's `bias_m`, m (the range is this much too long).
    pub offset_m: f64,
    /// Its standard deviation, m.
    pub std_m: f64,
}

/// What the tracks have learnt of one anchor's range offset, over the tags whose track learnt
/// one. The offset a track learns is the anchor's and its tag's delays together, so the spread
/// over tags is the tags' part and the mean the anchor's best estimate. Summaries of disjoint
/// sets of tags (the server's partitions) combine with [`Self::merge`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct AnchorOffsetSummary {
    /// The anchor's id (the key the summary is filed under; not in its JSON).
    #[serde(skip)]
    pub anchor: String,
    /// Tags whose track learnt an offset for it.
    pub tags: usize,
    /// Their mean, m: about what `radio.range.bias_m` needs on top of the site's value.
    pub mean_m: f64,
    /// The smallest, m.
    pub min_m: f64,
    /// The largest, m.
    pub max_m: f64,
    /// The mean of the tracks' standard deviations of their offsets, m.
    pub mean_std_m: f64,
}

impl AnchorOffsetSummary {
    /// One summary per anchor of `offsets` (as [`crate::tracker::Tracker::range_offsets`]
    /// gives them), in anchor id order.
    #[must_use]
    pub fn by_anchor(offsets: &[RangeOffset]) -> Vec<Self> {
        let mut summaries: std::collections::BTreeMap<&str, Self> = std::collections::BTreeMap::new();
        for offset in offsets {
            let one = Self {
                anchor: offset.anchor.clone(),
                tags: 1,
                mean_m: offset.offset_m,
                min_m: offset.offset_m,
                max_m: offset.offset_m,
                mean_std_m: offset.std_m,
            };
            match summaries.get_mut(offset.anchor.as_str()) {
                Some(summary) => summary.merge(&one),
                None => {
                    summaries.insert(&offset.anchor, one);
                }
            }
        }
        summaries.into_values().collect()
    }

    /// Adds the tags `other` summarises (of the same anchor, none of them already counted).
    pub fn merge(&mut self, other: &Self) {
        let total = (self.tags + other.tags) as f64;
        // x̄ = (n₁ x̄₁ + n₂ x̄₂) / (n₁ + n₂)
        let weigh = |a: f64, b: f64| (self.tags as f64 * a + other.tags as f64 * b) / total;
        self.mean_m = weigh(self.mean_m, other.mean_m);
        self.mean_std_m = weigh(self.mean_std_m, other.mean_std_m);
        self.min_m = self.min_m.min(other.min_m);
        self.max_m = self.max_m.max(other.max_m);
        self.tags += other.tags;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn offset(tag: &str, anchor: &str, offset_m: f64, std_m: f64) -> RangeOffset {
        RangeOffset {
            tag: tag.into(),
            anchor: anchor.into(),
            offset_m,
            std_m,
        }
    }

    #[test]
    fn offsets_summarise_per_anchor_and_partitions_merge_to_the_whole() {
        let all = [
            offset("t1", "A", 0.1, 0.02),
            offset("t2", "A", 0.3, 0.04),
            offset("t3", "A", 0.2, 0.03),
            offset("t1", "B", -0.1, 0.05),
        ];
        let whole = AnchorOffsetSummary::by_anchor(&all);
        assert_eq!(whole.len(), 2);
        let a = &whole[0];
        assert_eq!((a.anchor.as_str(), a.tags, a.min_m, a.max_m), ("A", 3, 0.1, 0.3));
        assert!(
            (a.mean_m - 0.2).abs() < 1e-12 && (a.mean_std_m - 0.03).abs() < 1e-12,
            "{a:?}"
        );
        // two partitions' summaries merged give the whole's
        let mut merged = AnchorOffsetSummary::by_anchor(&all[..1]).remove(0);
        merged.merge(&AnchorOffsetSummary::by_anchor(&all[1..3])[0]);
        assert_eq!(merged.tags, 3);
        assert!((merged.mean_m - a.mean_m).abs() < 1e-12 && (merged.mean_std_m - a.mean_std_m).abs() < 1e-12);
        assert_eq!((merged.min_m, merged.max_m), (a.min_m, a.max_m));
    }
}
