//! A track's estimates of its anchors' range offsets (`[tracker.range_bias]`): the bias vector
//! the tightly coupled range update reads, and the round of readings it learns from
//! ([`rtls_estimation::bias`]).

use rtls_estimation::bias::{BiasModel, BiasObservation, BiasVector};

/// Readings older than this (behind the newest) leave the round: the position errors the
/// projection removes must be the same for every reading of a round, s.
const ROUND_WINDOW_S: f64 = 2.0;

/// One reading of the open round.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Pending {
    anchor: usize,
    observation: BiasObservation,
    time_s: f64,
}

/// Each anchor's offset as this track has learnt it, and the readings of the open round.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct RangeBiases {
    biases: BiasVector,
    /// Slot in `biases` of each anchor index; `None` before the anchor's first learning round.
    slots: Vec<Option<usize>>,
    round: Vec<Pending>,
    /// Time of the newest reading of the last round learnt from, s.
    last_learnt_s: Option<f64>,
}

impl RangeBiases {
    /// `(b̂, P_b⁻)` of `anchor` at `time_s`: `(0, σ_b²)` before it has been learnt.
    pub(super) fn offset(&self, model: &BiasModel, anchor: usize, time_s: f64) -> (f64, f64) {
        match self.slots.get(anchor).copied().flatten() {
            Some(slot) => model.predicted(&self.biases, slot, time_s),
            None => (0.0, model.prior_std() * model.prior_std()),
        }
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
        model: &BiasModel,
        anchor: usize,
        observation: BiasObservation,
        time_s: f64,
        dimensions: usize,
        correlation_s: f64,
    ) {
        self.round.retain(|p| time_s - p.time_s <= ROUND_WINDOW_S);
        if self.round.iter().any(|p| p.anchor == anchor) {
            self.learn(model, dimensions, correlation_s);
            self.round.clear();
        }
        if self.wants(time_s, correlation_s) {
            self.round.push(Pending {
                anchor,
                observation,
                time_s,
            });
        }
    }

    /// Learns from one fix-then-filter epoch at once (its readings' residuals against the
    /// epoch's fix, one per anchor), if one is wanted: the open round is replaced by it.
    pub(super) fn learn_epoch(
        &mut self,
        model: &BiasModel,
        readings: &[(usize, BiasObservation)],
        time_s: f64,
        dimensions: usize,
        correlation_s: f64,
    ) {
        self.round.clear();
        if !self.wants(time_s, correlation_s) {
            return;
        }
        self.round = readings
            .iter()
            .map(|&(anchor, observation)| Pending {
                anchor,
                observation,
                time_s,
            })
            .collect();
        self.learn(model, dimensions, correlation_s);
        self.round.clear();
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
    fn learn(&mut self, model: &BiasModel, dimensions: usize, correlation_s: f64) {
        if self.round.len() <= dimensions {
            return;
        }
        let slots: Vec<usize> = self
            .round
            .iter()
            .map(|p| {
                if self.slots.len() <= p.anchor {
                    self.slots.resize(p.anchor + 1, None);
                }
                *self.slots[p.anchor].get_or_insert_with(|| model.add_reader(&mut self.biases))
            })
            .collect();
        let newest_s = self.round.iter().map(|p| p.time_s).fold(f64::NEG_INFINITY, f64::max);
        // c = max(1, 2 τ_c / Δt), Δt since the last round learnt from
        let since_s = self.last_learnt_s.map_or(f64::INFINITY, |t| newest_s - t);
        let inflation = (2.0 * correlation_s / since_s).max(1.0);
        let observations: Vec<BiasObservation> = self
            .round
            .iter()
            .map(|p| BiasObservation {
                variance: inflation * p.observation.noise_variance,
                ..p.observation
            })
            .collect();
        self.last_learnt_s = Some(newest_s);
        let learnt = model
            .predict(&self.biases, newest_s)
            .and_then(|predicted| model.update_observable(&predicted, &slots, &observations, dimensions));
        match learnt {
            Ok(biases) => self.biases = biases,
            Err(_) => *self = Self::default(),
        }
    }

    /// The learnt offsets: anchor index, value and standard deviation.
    pub(crate) fn estimates(&self) -> impl Iterator<Item = (usize, f64, f64)> + '_ {
        self.slots.iter().enumerate().filter_map(|(anchor, slot)| {
            slot.map(|slot| (anchor, self.biases.value(slot), self.biases.variance(slot).sqrt()))
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
