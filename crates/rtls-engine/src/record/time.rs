//! Plausible time stamps: an absolute bound every record must respect, and a gate that refuses
//! a record whose time jumps far ahead of the stream (a gateway sending milliseconds or
//! nanoseconds, a clock reset), so that the tracker never coasts through a bogus gap.

/// The largest magnitude a record's time may have, s: `1e11` s is about 3 170 years from the
/// clock's origin, so Unix time in seconds (≈ 1.8 × 10⁹ in 2026) and any relative clock fit,
/// while Unix time in milliseconds (≈ 1.8 × 10¹²), microseconds or nanoseconds is refused as a
/// unit error. At this magnitude an `f64` still resolves 16 µs.
pub const MAX_ABS_TIME_S: f64 = 1e11;

/// Records that must agree on a jumped time base, one after the other, before the gate
/// accepts it as a real gap (the ones before the last are refused).
pub const JUMP_CONFIRMATIONS: usize = 3;

/// Why a time stamp is not plausible on its own: non-finite or beyond [`MAX_ABS_TIME_S`]; `None`
/// when it is plausible.
///
/// # Examples
/// ```
/// use rtls_engine::record::implausible_time;
///
/// assert!(implausible_time(1.7e9).is_none());
/// assert!(implausible_time(1.7e18).unwrap().contains("nanoseconds"));
/// assert!(implausible_time(f64::NAN).is_some());
/// ```
#[must_use]
pub fn implausible_time(time_s: f64) -> Option<String> {
    if !time_s.is_finite() {
        return Some(format!("{time_s} is not a finite time"));
    }
    if time_s.abs() > MAX_ABS_TIME_S {
        return Some(format!(
            "{time_s:e} s is beyond ±{MAX_ABS_TIME_S:e} s (about 3 000 years); times are in seconds: \
             is the source sending milliseconds, microseconds or nanoseconds?"
        ));
    }
    None
}

/// Refuses records whose time jumps more than `max_jump_s` ahead of the newest accepted time.
///
/// A refused record is one bad record: the stream's clock does not move. When
/// [`JUMP_CONFIRMATIONS`] records in a row all lie beyond the jump, within `max_jump_s` of the
/// first of them, the gap is taken as real (a site that was quiet over a weekend, a restarted
/// source): the last of them is accepted and the clock moves on; the earlier ones stay refused.
/// A record behind the newest time is not the gate's business (the re-ordering window reports
/// it late). The first record sets the clock.
///
/// # Units
/// All times in seconds.
///
/// # Examples
/// ```
/// use rtls_engine::record::TimeGate;
///
/// let mut gate = TimeGate::new(86_400.0).unwrap();
/// assert!(gate.check(1.0).is_ok());
/// assert!(gate.check(2.0).is_ok());
/// // a gateway that switched to milliseconds since the epoch … refused
/// assert!(gate.check(1.7e9).is_err());
/// assert!(gate.check(3.0).is_ok());
/// assert_eq!(gate.newest_s(), Some(3.0));
/// ```
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TimeGate {
    max_jump_s: f64,
    newest_s: Option<f64>,
    /// The first time of the current run of jumped records and how many there were.
    jumped: Option<(f64, usize)>,
}

impl TimeGate {
    /// Continues from `earlier`'s newest time and run of jumps (a tracker's checkpoint), with
    /// this gate's maximum jump.
    pub(crate) fn resume(&mut self, earlier: TimeGate) {
        self.newest_s = earlier.newest_s;
        self.jumped = earlier.jumped;
    }

    /// A gate allowing jumps of up to `max_jump_s` ahead of the newest accepted record.
    ///
    /// # Errors
    /// [`crate::EngineError::InvalidParameter`] unless `max_jump_s` is finite and > 0.
    ///
    /// # Examples
    /// ```
    /// assert!(rtls_engine::record::TimeGate::new(0.0).is_err());
    /// ```
    pub fn new(max_jump_s: f64) -> crate::Result<Self> {
        if !(max_jump_s.is_finite() && max_jump_s > 0.0) {
            return Err(crate::EngineError::InvalidParameter {
                name: "max_time_jump_s",
                reason: "must be finite and > 0 s",
            });
        }
        Ok(Self {
            max_jump_s,
            newest_s: None,
            jumped: None,
        })
    }

    /// The newest accepted time, s (`None` before the first record).
    #[must_use]
    pub fn newest_s(&self) -> Option<f64> {
        self.newest_s
    }

    /// Checks a record's time and, when it is accepted, moves the clock to it.
    ///
    /// # Errors
    /// The reason the time is refused: not finite or beyond [`MAX_ABS_TIME_S`]
    /// ([`implausible_time`]), or more than `max_jump_s` ahead of the newest accepted time.
    ///
    /// # Examples
    /// See [`TimeGate`].
    pub fn check(&mut self, time_s: f64) -> Result<(), String> {
        if let Some(reason) = implausible_time(time_s) {
            return Err(reason);
        }
        let Some(newest_s) = self.newest_s else {
            self.newest_s = Some(time_s);
            return Ok(());
        };
        let ahead_s = time_s - newest_s;
        if ahead_s <= self.max_jump_s {
            self.jumped = None;
            self.newest_s = Some(newest_s.max(time_s));
            return Ok(());
        }
        let run = match self.jumped {
            Some((first_s, count)) if (time_s - first_s).abs() <= self.max_jump_s => (first_s, count + 1),
            _ => (time_s, 1),
        };
        if run.1 >= JUMP_CONFIRMATIONS {
            self.jumped = None;
            self.newest_s = Some(time_s);
            return Ok(());
        }
        self.jumped = Some(run);
        Err(format!(
            "time jump: t = {time_s} s is {ahead_s:.6e} s after the newest record ({newest_s} s), more than \
             tracker.max_time_jump_s = {} s; refused as a bad time stamp (check the source's clock and unit); \
             {JUMP_CONFIRMATIONS} records in a row on the new time base are taken as a real gap",
            self.max_jump_s
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn absurd_times_are_implausible() {
        for t in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e16, -1e12, 1e308] {
            assert!(implausible_time(t).is_some(), "{t}");
        }
        for t in [0.0, -5.0, 1.7e9, MAX_ABS_TIME_S] {
            assert!(implausible_time(t).is_none(), "{t}");
        }
    }

    #[test]
    fn a_single_jump_is_refused_and_the_clock_stays() {
        let mut gate = TimeGate::new(10.0).unwrap();
        assert!(gate.check(1.0).is_ok());
        let reason = gate.check(1e9).unwrap_err();
        assert!(reason.contains("max_time_jump_s = 10"), "{reason}");
        assert_eq!(gate.newest_s(), Some(1.0));
        assert!(gate.check(11.0).is_ok());
        // behind the clock: not the gate's business
        assert!(gate.check(-100.0).is_ok());
        assert_eq!(gate.newest_s(), Some(11.0));
    }

    #[test]
    fn a_real_gap_is_accepted_after_confirmations() {
        let mut gate = TimeGate::new(10.0).unwrap();
        assert!(gate.check(0.0).is_ok());
        let results: Vec<bool> = [1000.0, 1000.5, 1001.0, 1001.5]
            .iter()
            .map(|&t| gate.check(t).is_ok())
            .collect();
        assert_eq!(results, [false, false, true, true]);
        assert_eq!(gate.newest_s(), Some(1001.5));
    }

    #[test]
    fn interleaved_bad_times_never_move_the_clock() {
        let mut gate = TimeGate::new(10.0).unwrap();
        for k in 0..100 {
            let t = f64::from(k);
            assert!(gate.check(t).is_ok());
            assert!(gate.check(1.7e9 + t).is_err());
        }
        assert_eq!(gate.newest_s(), Some(99.0));
    }
}
