//! Which track states are stored: every one, or a tag's states at least
//! `server.history_interval_s` apart.
//!
//! A 10 Hz site stores ten rows per tag per second; a control room's history (replay,
//! audits, exports) rarely needs more than one. Live outputs (WebSocket, MQTT), zones and
//! alarms see every state whatever is stored. A state is stored when
//!
//! ```text
//! interval = 0                                   (every state), or
//! no state of the tag is stored yet, or
//! t ≥ t_stored + interval                        (the rate), or
//! status ≠ status_stored  or  predicted ≠ predicted_stored   (what changed is never thinned), or
//! revised  and  t = t_stored                     (a correction of the newest stored state)
//! ```

use std::collections::HashMap;

use rtls_engine::lifecycle::TrackStatus;

/// The newest stored state of a tag.
#[derive(Debug, Clone, Copy)]
struct Stored {
    time_s: f64,
    status: TrackStatus,
    predicted: bool,
}

/// The stored-history rate of one partition's tags.
#[derive(Debug, Default)]
pub(super) struct HistoryRate {
    interval_s: f64,
    stored: HashMap<String, Stored>,
}

/// What the rate looks at in a track update.
#[derive(Debug, Clone, Copy)]
pub(super) struct StateKind {
    /// The state's time, s.
    pub time_s: f64,
    /// The track's status.
    pub status: TrackStatus,
    /// A prediction (coasting), not a measured update.
    pub predicted: bool,
    /// A revision of a state already published.
    pub revised: bool,
}

impl HistoryRate {
    /// A rate of one state per `interval_s` per tag (0: every state).
    pub(super) fn new(interval_s: f64) -> Self {
        Self {
            interval_s: if interval_s.is_finite() {
                interval_s.max(0.0)
            } else {
                0.0
            },
            stored: HashMap::new(),
        }
    }

    /// Whether `tag`'s state `state` is stored (the module's rule); notes it when it is.
    pub(super) fn keep(&mut self, tag: &str, state: StateKind) -> bool {
        if self.interval_s <= 0.0 {
            return true;
        }
        let Some(stored) = self.stored.get_mut(tag) else {
            self.stored.insert(tag.to_string(), Stored::from(state));
            return true;
        };
        // (a hair under the interval: stamps of a 10 Hz tag are 0.1 s apart in decimal)
        let keep = state.time_s >= stored.time_s + self.interval_s - 1e-6
            || state.status != stored.status
            || state.predicted != stored.predicted
            || (state.revised && state.time_s == stored.time_s);
        if keep && state.time_s >= stored.time_s {
            *stored = Stored::from(state);
        }
        keep
    }

    /// Forgets a deleted tag.
    pub(super) fn forget(&mut self, tag: &str) {
        self.stored.remove(tag);
    }

    /// Forgets every tag (the partition was reset).
    pub(super) fn clear(&mut self) {
        self.stored.clear();
    }
}

impl From<StateKind> for Stored {
    fn from(state: StateKind) -> Self {
        Self {
            time_s: state.time_s,
            status: state.status,
            predicted: state.predicted,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(time_s: f64) -> StateKind {
        StateKind {
            time_s,
            status: TrackStatus::Confirmed,
            predicted: false,
            revised: false,
        }
    }

    #[test]
    fn zero_keeps_every_state() {
        let mut rate = HistoryRate::new(0.0);
        assert!((0..20).all(|k| rate.keep("a", at(k as f64 * 0.1))));
    }

    #[test]
    fn a_10_hz_tag_is_stored_once_a_second() {
        let mut rate = HistoryRate::new(1.0);
        let kept: Vec<usize> = (0..35)
            .filter(|&k| rate.keep("a", at(100.0 + k as f64 * 0.1)))
            .collect();
        assert_eq!(kept, vec![0, 10, 20, 30]);
        // another tag has its own rate
        assert!(rate.keep("b", at(100.05)));
    }

    #[test]
    fn a_change_of_status_or_prediction_and_a_revision_of_the_stored_state_are_kept() {
        let mut rate = HistoryRate::new(1.0);
        assert!(rate.keep("a", at(10.0)));
        assert!(!rate.keep("a", at(10.1)));
        let coasting = |time_s, revised| StateKind {
            time_s,
            status: TrackStatus::Coasting,
            predicted: true,
            revised,
        };
        assert!(rate.keep("a", coasting(10.2, false)), "a change of status");
        assert!(!rate.keep("a", coasting(10.4, false)));
        assert!(
            rate.keep("a", coasting(10.2, true)),
            "a revision of the newest stored state"
        );
        assert!(
            !rate.keep("a", coasting(10.1, true)),
            "a revision of a state not stored"
        );
        rate.forget("a");
        assert!(rate.keep("a", at(10.5)), "a deleted tag starts again");
    }
}
