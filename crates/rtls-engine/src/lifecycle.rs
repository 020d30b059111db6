//! Track lifecycle: initiation, confirmation (M updates within a window), coasting when nothing
//! arrives, a lost state after a timeout that keeps the last position, and deletion.
//!
//! The lifecycle is a pure state machine over time stamps: the filter that owns the state
//! estimate asks it what the track's status is after each update and at each output tick, and
//! reports the [`LifecycleEvent`]s it returns.
//!
//! ```text
//!             M updates within window            no update for coast_timeout
//! Tentative ─────────────────────────▶ Confirmed ⇄ Coasting ─────────────────▶ Lost
//!     │  (no M-th update in window)      ▲   update      tick                   │
//!     └──────────▶ Deleted               └──────────── update (Recovered) ───────┤
//!                                                    no update for delete_timeout └──▶ Deleted
//! ```
//!
//! # References
//! Seed 000 §4–§5 (a tag out of reader range keeps being reported from the prediction: PEL → 0);
//! S. Blackman, R. Popoli, *Design and Analysis of Modern Tracking Systems*, Artech House 1999,
//! §3.2 (M-of-N track confirmation and deletion).

use std::collections::VecDeque;

use serde::Deserialize;

use crate::error::{EngineError, Result};

/// Timing of the lifecycle.
///
/// # Units
/// Seconds; counts are numbers of updates.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct LifecycleSettings {
    /// `M`: updates needed to confirm a tentative track.
    pub confirm_updates: u32,
    /// The window (s) in which the `M` updates must fall; a tentative track that cannot reach
    /// `M` within it from its first update is deleted.
    pub confirm_window_s: f64,
    /// Time (s) without any update after which a confirmed track is lost (it keeps its last
    /// position). Before it, the track coasts: its prediction is reported, flagged.
    pub coast_timeout_s: f64,
    /// Time (s) without any update after which a track is deleted (≥ `coast_timeout_s`).
    pub delete_timeout_s: f64,
}

impl Default for LifecycleSettings {
    /// Confirm after 3 updates within 5 s; lost after 30 s of silence, deleted after 10 min:
    /// a miner out of reader range for half a minute is reported as lost, with his last position.
    fn default() -> Self {
        Self {
            confirm_updates: 3,
            confirm_window_s: 5.0,
            coast_timeout_s: 30.0,
            delete_timeout_s: 600.0,
        }
    }
}

impl LifecycleSettings {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] for `confirm_updates = 0`, a negative or non-finite
    /// time, or `delete_timeout_s < coast_timeout_s`.
    ///
    /// # Example
    /// ```
    /// use rtls_engine::lifecycle::LifecycleSettings;
    /// assert!(LifecycleSettings::default().validate().is_ok());
    /// let bad = LifecycleSettings { delete_timeout_s: 1.0, ..LifecycleSettings::default() };
    /// assert!(bad.validate().is_err());
    /// ```
    pub fn validate(&self) -> Result<()> {
        if self.confirm_updates == 0 {
            return Err(EngineError::InvalidParameter {
                name: "confirm_updates",
                reason: "a track needs at least one update to be confirmed",
            });
        }
        for (name, value) in [
            ("confirm_window_s", self.confirm_window_s),
            ("coast_timeout_s", self.coast_timeout_s),
            ("delete_timeout_s", self.delete_timeout_s),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(EngineError::InvalidParameter {
                    name,
                    reason: "a time must be finite and ≥ 0",
                });
            }
        }
        if self.delete_timeout_s < self.coast_timeout_s {
            return Err(EngineError::InvalidParameter {
                name: "delete_timeout_s",
                reason: "a track must be lost before it is deleted: delete_timeout_s ≥ coast_timeout_s",
            });
        }
        Ok(())
    }
}

/// Where a track is in its life.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum TrackStatus {
    /// Started, not yet confirmed.
    Tentative,
    /// Updated at the last tick.
    Confirmed,
    /// Confirmed, but no update at the last tick: the prediction is reported, flagged.
    Coasting,
    /// Silent for longer than the coast timeout: the last position is kept.
    Lost,
    /// Gone: the owner drops the track.
    Deleted,
}

/// A change of status worth reporting.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LifecycleEvent {
    /// A tentative track reached `M` updates in the window.
    Confirmed,
    /// A confirmed track missed its first tick.
    StartedCoasting,
    /// A coasting track was updated again.
    Resumed,
    /// Silent for longer than the coast timeout.
    Lost,
    /// A lost track was updated again.
    Recovered,
    /// The track is gone (a tentative track that was never confirmed, or the delete timeout).
    Deleted,
    /// Fixes left the track's gate and agreed with each other long enough: the track restarted
    /// where they are (a tag carried or moved farther than its motion model allows; reported
    /// by the tracker, not by [`Lifecycle`]).
    Jumped,
    /// The fixes the track gates out keep returning to one other place while its own fixes
    /// go on: two transmitters sending as one tag id, or a reflection that recurs (reported
    /// by the tracker once per track, at the other place; see `tracker::jump`).
    Alternating,
}

/// The lifecycle of one track.
///
/// # Example
/// ```
/// use rtls_engine::lifecycle::{Lifecycle, LifecycleEvent, LifecycleSettings, TrackStatus};
/// let settings = LifecycleSettings { confirm_updates: 2, confirm_window_s: 3.0, coast_timeout_s: 10.0, delete_timeout_s: 60.0 };
/// let mut track = Lifecycle::start(settings, 0.0)?;
/// assert_eq!(track.status(), TrackStatus::Tentative);
/// assert_eq!(track.update(1.0)?, Some(LifecycleEvent::Confirmed));
/// assert_eq!(track.tick(2.0)?, Some(LifecycleEvent::StartedCoasting)); // nothing at t = 2
/// assert_eq!(track.tick(12.0)?, Some(LifecycleEvent::Lost));
/// assert_eq!(track.update(13.0)?, Some(LifecycleEvent::Recovered));
/// assert_eq!(track.tick(80.0)?, Some(LifecycleEvent::Deleted)); // silent for 67 s > 60 s
/// assert!(track.tick(74.0).is_err()); // time went backwards
/// # Ok::<(), rtls_engine::EngineError>(())
/// ```
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Lifecycle {
    settings: LifecycleSettings,
    status: TrackStatus,
    /// Time of the last update, s.
    last_update_s: f64,
    /// Latest time seen (update or tick), s.
    now_s: f64,
    /// Update times within the confirmation window (tentative tracks only).
    recent_updates_s: VecDeque<f64>,
    /// Time of the first update, s.
    started_s: f64,
}

impl Lifecycle {
    /// A track started by an update at `time_s` (tentative, or confirmed at once when `M = 1`).
    ///
    /// # Errors
    /// The errors of [`LifecycleSettings::validate`]; [`EngineError::InvalidParameter`]
    /// (`time_s`) for a non-finite time.
    pub fn start(settings: LifecycleSettings, time_s: f64) -> Result<Self> {
        settings.validate()?;
        finite_time(time_s)?;
        let status = if settings.confirm_updates == 1 {
            TrackStatus::Confirmed
        } else {
            TrackStatus::Tentative
        };
        Ok(Self {
            settings,
            status,
            last_update_s: time_s,
            now_s: time_s,
            recent_updates_s: VecDeque::from([time_s]),
            started_s: time_s,
        })
    }

    /// A track confirmed from the start at `time_s`: its target is known to exist (a track
    /// handed over from another tracker, or one seeded from a known start position), so no
    /// M-of-N confirmation is needed. It coasts, is lost and deleted like any confirmed track.
    ///
    /// # Errors
    /// The errors of [`LifecycleSettings::validate`]; [`EngineError::InvalidParameter`]
    /// (`time_s`) for a non-finite time.
    ///
    /// # Example
    /// ```
    /// use rtls_engine::lifecycle::{Lifecycle, LifecycleEvent, LifecycleSettings, TrackStatus};
    /// let mut track = Lifecycle::confirmed(LifecycleSettings::default(), 2.0)?;
    /// assert_eq!(track.status(), TrackStatus::Confirmed);
    /// assert_eq!(track.tick(3.0)?, Some(LifecycleEvent::StartedCoasting));
    /// # Ok::<(), rtls_engine::EngineError>(())
    /// ```
    pub fn confirmed(settings: LifecycleSettings, time_s: f64) -> Result<Self> {
        let mut lifecycle = Self::start(settings, time_s)?;
        lifecycle.status = TrackStatus::Confirmed;
        lifecycle.recent_updates_s.clear();
        Ok(lifecycle)
    }

    /// The current status.
    #[must_use]
    pub fn status(&self) -> TrackStatus {
        self.status
    }

    /// Time of the last update (s).
    #[must_use]
    pub fn last_update_s(&self) -> f64 {
        self.last_update_s
    }

    /// Whether the track's output at the last tick was a prediction (coasting or lost).
    #[must_use]
    pub fn is_predicted(&self) -> bool {
        matches!(self.status, TrackStatus::Coasting | TrackStatus::Lost)
    }

    /// The track was updated by a measurement at `time_s`.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] (`time_s`) for a non-finite time or one before the
    /// latest time seen, and for an update of a deleted track.
    pub fn update(&mut self, time_s: f64) -> Result<Option<LifecycleEvent>> {
        self.advance(time_s)?;
        self.last_update_s = time_s;
        let event = match self.status {
            TrackStatus::Tentative => {
                // keep the updates within the window: t − t_i ≤ window
                self.recent_updates_s.push_back(time_s);
                while self
                    .recent_updates_s
                    .front()
                    .is_some_and(|&t| time_s - t > self.settings.confirm_window_s)
                {
                    self.recent_updates_s.pop_front();
                }
                if self.recent_updates_s.len() >= self.settings.confirm_updates as usize {
                    self.status = TrackStatus::Confirmed;
                    self.recent_updates_s.clear();
                    Some(LifecycleEvent::Confirmed)
                } else {
                    None
                }
            }
            TrackStatus::Confirmed => None,
            TrackStatus::Coasting => {
                self.status = TrackStatus::Confirmed;
                Some(LifecycleEvent::Resumed)
            }
            TrackStatus::Lost => {
                self.status = TrackStatus::Confirmed;
                Some(LifecycleEvent::Recovered)
            }
            TrackStatus::Deleted => {
                return Err(EngineError::InvalidParameter {
                    name: "time_s",
                    reason: "the track was deleted: start a new one",
                })
            }
        };
        Ok(event)
    }

    /// An output tick at `time_s` with no update since the last tick or update at an earlier
    /// time: the status moves on with the silence `time_s − last update`.
    ///
    /// A tick that changes nothing (no event) does not move the lifecycle's clock: an update
    /// older than it but not older than the last update or event is still taken (a record of
    /// a sender running behind another, whose records moved the tracker's clock).
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] (`time_s`) for a non-finite time or one before the
    /// latest update or event.
    pub fn tick(&mut self, time_s: f64) -> Result<Option<LifecycleEvent>> {
        let event = self.tick_status(time_s)?;
        if event.is_some() {
            self.now_s = time_s;
        }
        Ok(event)
    }

    /// Moves the status on for a tick at `time_s`; the event it raises, if any.
    fn tick_status(&mut self, time_s: f64) -> Result<Option<LifecycleEvent>> {
        self.check_order(time_s)?;
        let silence_s = time_s - self.last_update_s;
        let event = match self.status {
            TrackStatus::Tentative if time_s - self.started_s > self.settings.confirm_window_s => {
                self.status = TrackStatus::Deleted;
                Some(LifecycleEvent::Deleted)
            }
            TrackStatus::Tentative | TrackStatus::Deleted => None,
            _ if silence_s > self.settings.delete_timeout_s => {
                self.status = TrackStatus::Deleted;
                Some(LifecycleEvent::Deleted)
            }
            TrackStatus::Lost => None,
            _ if silence_s > self.settings.coast_timeout_s => {
                self.status = TrackStatus::Lost;
                Some(LifecycleEvent::Lost)
            }
            TrackStatus::Confirmed if silence_s > 0.0 => {
                self.status = TrackStatus::Coasting;
                Some(LifecycleEvent::StartedCoasting)
            }
            TrackStatus::Confirmed | TrackStatus::Coasting => None,
        };
        Ok(event)
    }

    fn advance(&mut self, time_s: f64) -> Result<()> {
        self.check_order(time_s)?;
        self.now_s = time_s;
        Ok(())
    }

    /// `time_s` is finite and not before the latest update or event.
    fn check_order(&self, time_s: f64) -> Result<()> {
        finite_time(time_s)?;
        if time_s < self.now_s {
            return Err(EngineError::InvalidParameter {
                name: "time_s",
                reason: "time went backwards: ticks and updates must come in time order",
            });
        }
        Ok(())
    }
}

fn finite_time(time_s: f64) -> Result<()> {
    if time_s.is_finite() {
        Ok(())
    } else {
        Err(EngineError::InvalidParameter {
            name: "time_s",
            reason: "a time stamp must be finite",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> LifecycleSettings {
        LifecycleSettings {
            confirm_updates: 3,
            confirm_window_s: 2.0,
            coast_timeout_s: 5.0,
            delete_timeout_s: 20.0,
        }
    }

    #[test]
    fn confirmation_needs_m_updates_within_the_window() {
        let mut slow = Lifecycle::start(settings(), 0.0).unwrap();
        assert_eq!(slow.update(1.5).unwrap(), None);
        // the update at 0 has left the window [1.6, 3.6]: two in the window, not three
        assert_eq!(slow.update(3.6).unwrap(), None);
        assert_eq!(slow.status(), TrackStatus::Tentative);
        // a tentative track that could not confirm within the window from its start is deleted
        assert_eq!(slow.tick(3.7).unwrap(), Some(LifecycleEvent::Deleted));
        assert!(slow.update(3.8).is_err());

        let mut fast = Lifecycle::start(settings(), 0.0).unwrap();
        fast.update(0.5).unwrap();
        assert_eq!(fast.update(1.0).unwrap(), Some(LifecycleEvent::Confirmed));
        assert!(!fast.is_predicted());
        assert_eq!(
            Lifecycle::start(
                LifecycleSettings {
                    confirm_updates: 1,
                    ..settings()
                },
                0.0
            )
            .unwrap()
            .status(),
            TrackStatus::Confirmed
        );
    }

    #[test]
    fn coasting_lost_recovered_deleted() {
        let mut track = Lifecycle::start(
            LifecycleSettings {
                confirm_updates: 1,
                ..settings()
            },
            0.0,
        )
        .unwrap();
        // a tick right at the update time is not a gap
        assert_eq!(track.tick(0.0).unwrap(), None);
        assert_eq!(track.tick(1.0).unwrap(), Some(LifecycleEvent::StartedCoasting));
        assert!(track.is_predicted());
        assert_eq!(track.tick(2.0).unwrap(), None);
        assert_eq!(track.update(2.5).unwrap(), Some(LifecycleEvent::Resumed));
        assert_eq!(track.tick(3.0).unwrap(), Some(LifecycleEvent::StartedCoasting));
        // exactly at the timeout still coasting, beyond it lost
        assert_eq!(track.tick(7.5).unwrap(), None);
        assert_eq!(track.tick(7.6).unwrap(), Some(LifecycleEvent::Lost));
        assert_eq!(track.status(), TrackStatus::Lost);
        assert!(track.is_predicted());
        assert_eq!(track.update(9.0).unwrap(), Some(LifecycleEvent::Recovered));
        assert_eq!(track.tick(30.0).unwrap(), Some(LifecycleEvent::Deleted));
        assert_eq!(track.tick(31.0).unwrap(), None);
    }

    #[test]
    fn bad_times_and_settings_are_errors() {
        let mut track = Lifecycle::start(settings(), 5.0).unwrap();
        assert!(track.update(4.0).is_err());
        assert!(track.tick(f64::NAN).is_err());
        assert!(Lifecycle::start(settings(), f64::INFINITY).is_err());
        for bad in [
            LifecycleSettings {
                confirm_updates: 0,
                ..settings()
            },
            LifecycleSettings {
                confirm_window_s: -1.0,
                ..settings()
            },
            LifecycleSettings {
                coast_timeout_s: f64::NAN,
                ..settings()
            },
            LifecycleSettings {
                delete_timeout_s: 1.0,
                ..settings()
            },
        ] {
            assert!(Lifecycle::start(bad, 0.0).is_err(), "{bad:?}");
        }
    }
}
