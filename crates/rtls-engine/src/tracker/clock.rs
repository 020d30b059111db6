//! The tracker's clock: the ticks on their grid, the caller's clock ([`Tracker::advance_to`])
//! and the caller's watermark ([`Tracker::set_watermark`]).
//!
//! # The watermark
//! Without one, the records drive the ticks: a record at `t` first runs the ticks due before
//! `t`, so the tracker's clock is the newest record of any sender. When senders deliver with
//! different delays (two gateways, one with a slower backhaul; publishers whose queues drift
//! apart under a backlog) the slower sender's tags fall silent in the clock's eyes: their
//! tracks coast, and each of their records then arrives behind those ticks, rewinds its track
//! and re-filters it, publishing revised updates — work that grows exactly when the server is
//! behind (the 6 000-tag soak of 2026-11-28, docs/SERVER.md).
//!
//! A live caller that knows its senders' delays sets a watermark `W`: the record time up to
//! which it holds every record to have arrived. The ticks — coasting outputs, lost and deleted
//! tracks, epoch deadlines — then run no further than
//!
//! ```text
//! τ_max = max(W, t_newest − rewind_horizon_s)
//! ```
//!
//! (never further behind the newest record than a rewind reaches: a record older than that is
//! late anyway), while every record is still applied at once and its update reported at once.
//! A tick skips a track whose inputs already reach past it (see `Core::tick`), so a track
//! running ahead of the watermark is not ticked behind its own time.
//!
//! The watermark is used only with `rewind_horizon_s` > 0 (without a rewind, the ticks before
//! a record must run before it) and without an `[anonymous]` section (its detections are
//! tracked in arrival order).

use super::output::Output;
use super::{TicksDue, Tracker, Tracks, MAX_CATCH_UP_TICKS};
use crate::error::{EngineError, Result};

impl Tracker {
    /// Sets the watermark (s): the record time up to which the caller holds every record to
    /// have arrived, or `None` (the records drive the ticks). See the module's *The
    /// watermark*: clock ticks, whether records or [`Tracker::advance_to`] drive them, run no
    /// further than it (nor further than `rewind_horizon_s` behind the newest record). A
    /// non-finite value is `None`. Ignored without a rewind horizon and with an
    /// `[anonymous]` section.
    ///
    /// # Example
    /// A server whose slowest active sender's records are 1.5 s old sets
    /// `tracker.set_watermark(Some(wall_s − 1.5))` before pushing a batch: that sender's
    /// tracks are not coasted (and then rewound) by the other senders' newer records.
    pub fn set_watermark(&mut self, watermark_s: Option<f64>) {
        self.watermark_s = watermark_s.filter(|w| w.is_finite());
    }

    /// How far a clock at `time_s` may run the ticks: `time_s` itself, or the watermark's
    /// `τ_max` when that is earlier (then every tick through it is due: the records up to it
    /// are in).
    pub(super) fn tick_limit(&self, time_s: f64, due: TicksDue) -> (f64, TicksDue) {
        let held = self.rewind_horizon_s > 0.0 && self.anonymous.is_none();
        match self.watermark_s {
            Some(watermark_s) if held => {
                // τ_max = max(W, t_newest − horizon)
                let limit_s = watermark_s.max(self.now_s - self.rewind_horizon_s);
                if limit_s < time_s {
                    (limit_s, TicksDue::Through)
                } else {
                    (time_s, due)
                }
            }
            _ => (time_s, due),
        }
    }

    /// Runs the ticks due before `time_s` ([`TicksDue::Before`]) or by it
    /// ([`TicksDue::Through`]), held at the watermark ([`Self::tick_limit`]). Ticks lie on a
    /// grid of half the output interval from the first record, so a coasting output is at
    /// most half an interval late; after a silence longer than [`MAX_CATCH_UP_TICKS`] ticks
    /// the grid restarts at `time_s`.
    pub(super) fn run_ticks(&mut self, time_s: f64, due: TicksDue, out: &mut Output) -> Result<()> {
        let (time_s, due) = self.tick_limit(time_s, due);
        let period_s = self.output_interval_s / 2.0;
        let mut next_s = *self.next_tick_s.get_or_insert(time_s);
        if (time_s - next_s) / period_s > MAX_CATCH_UP_TICKS {
            next_s = time_s;
        }
        let mut ticks = 0.0;
        while next_s < time_s || (due == TicksDue::Through && next_s == time_s) {
            match &mut self.tracks {
                Tracks::Planar(core) => core.tick(next_s, out)?,
                Tracks::Spatial(core) => core.tick(next_s, out)?,
            }
            if let Some(front) = &mut self.anonymous {
                let mark = (out.updates.len(), out.events.len());
                front.tick(next_s, self.output_interval_s, out)?;
                super::anonymous_zones(&mut self.tracks, out, mark)?;
            }
            ticks += 1.0;
            let after_s = next_s + period_s;
            if after_s <= next_s || ticks > MAX_CATCH_UP_TICKS {
                // bounded work: a step lost in rounding (|t| ≫ the period) cannot loop forever
                next_s = if next_s < time_s { time_s } else { time_s.next_up() };
                continue;
            }
            next_s = after_s;
        }
        self.next_tick_s = Some(next_s);
        Ok(())
    }

    /// Advances the tracker's clock to `time_s` without a record (a live server calls this
    /// with its clock): records held in the re-ordering window at or before
    /// `time_s − reorder_window_s` are applied, and the ticks due by then run (held at the
    /// watermark, [`Self::set_watermark`]), so coasting tracks are predicted, lost and
    /// deleted. A record older than that arriving later is reported [`super::Event::Late`]
    /// (or, with a rewind horizon, re-filtered).
    ///
    /// # Errors
    /// A non-finite `time_s`.
    pub fn advance_to(&mut self, time_s: f64, out: &mut Output) -> Result<()> {
        if !time_s.is_finite() {
            return Err(EngineError::InvalidParameter {
                name: "time_s",
                reason: "must be finite",
            });
        }
        // records the clock says can no longer be overtaken leave the re-ordering window, and
        // the ticks run up to the window's far edge only: a record still inside the window
        // can be applied after them
        for emitted in self.reorderer.release_until(time_s) {
            self.emitted(emitted, out)?;
        }
        let clock_s = time_s - self.reorderer.window_s();
        if clock_s > self.now_s {
            self.now_s = clock_s;
            self.run_ticks(clock_s, TicksDue::Through, out)?;
        }
        Ok(())
    }
}
