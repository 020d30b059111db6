//! The heading channel's per-track state ([`HeadingChannel`]) and its constants; what the
//! records do with it is in the `heading` module.

use rtls_estimation::aided::HeadingState;

/// A speed is turned into a velocity only when the heading's std is at most this, rad (20°):
/// beyond it the linearised velocity covariance no longer describes the error.
pub(super) const MAX_HEADING_STD_RAD: f64 = 0.35;

/// The course over ground's variance is multiplied by this before it updates the heading (the
/// track's velocity already holds the odometry the heading produced).
pub(super) const COURSE_VARIANCE_INFLATION: f64 = 4.0;

/// A held yaw rate is integrated for at most this long after its sample, s; later the heading
/// is a random walk.
pub(super) const RATE_HOLD_S: f64 = 1.0;

/// A course chord spans at least this long, s.
pub(super) const COURSE_MIN_INTERVAL_S: f64 = 1.0;

/// A chord that has not grown long enough within this long starts again, s (slow motion).
pub(super) const COURSE_MAX_INTERVAL_S: f64 = 10.0;

/// Heading references more than this many standard deviations from the channel are not used.
pub(super) const GATE_SIGMAS: f64 = 4.0;

/// Time constant of the gravity estimate (low-passed specific force), s.
pub(super) const GRAVITY_TIME_CONSTANT_S: f64 = 1.0;

/// Standard gravity, m/s².
pub(super) const GRAVITY_MPS2: f64 = 9.806_65;

/// A track's heading channel and what it holds between records.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub(crate) struct HeadingChannel {
    pub(super) state: Option<HeadingState>,
    /// The last yaw rate `(t, ω rad/s, σ_ω² (rad/s)²)`, held until the next.
    pub(super) rate: Option<(f64, f64, f64)>,
    /// Whether that rate is an odometer heading's change over its interval (not a gyro's).
    pub(super) rate_from_odometer: bool,
    /// The chord's start: a position after a position update.
    pub(super) chord_start: Option<CoursePoint>,
    /// The latest position after a position update.
    pub(super) chord_end: Option<CoursePoint>,
    /// `θ`: the heading changes since the channel started, rad — the bias-corrected yaw rate
    /// integrated, or without a recent rate the odometer heading's changes; never corrected by
    /// references.
    pub(super) integrated_rad: f64,
    /// The time θ was last brought up to, s, and its rate then, rad/s (to carry θ to a
    /// position update between heading records).
    pub(super) integrated_time_s: f64,
    pub(super) integrated_rate_radps: f64,
    /// The previous odometer heading `(t, z)`, s and rad.
    pub(super) odometer_heading: Option<(f64, f64)>,
    /// The previous odometer heading's stated std and the smallest one stated so far, rad.
    pub(super) odometer_std_rad: Option<(f64, f64)>,
    /// Low-passed specific force in the sensor's axes `(t, f)`, m/s².
    pub(super) gravity: Option<(f64, [f64; 3])>,
    /// The time of the last speed turned into a velocity, s.
    pub(super) last_speed_s: Option<f64>,
    /// The times of the last two course references the channel took, s (the newest second).
    pub(super) course_times_s: (Option<f64>, Option<f64>),
}

/// A track position after a position update, for the course chord.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub(super) struct CoursePoint {
    pub(super) time_s: f64,
    pub(super) position_m: [f64; 2],
    /// Position covariance `[P_xx, P_xy, P_yy]`, m².
    pub(super) covariance_m2: [f64; 3],
    /// `θ` at that time, rad.
    pub(super) integrated_rad: f64,
}

impl HeadingChannel {
    /// Notes the track's position after a position update (fix or anchor measurement).
    pub(super) fn position_updated(&mut self, time_s: f64, position_m: [f64; 2], covariance_m2: [f64; 3]) {
        // θ(t) = θ + θ̇ (t − t_θ): the heading change up to the update's time
        let since_s = (time_s - self.integrated_time_s).max(0.0);
        let point = CoursePoint {
            time_s,
            position_m,
            covariance_m2,
            integrated_rad: self.integrated_rad + self.integrated_rate_radps * since_s,
        };
        if self
            .chord_start
            .is_none_or(|start| time_s - start.time_s > COURSE_MAX_INTERVAL_S)
        {
            self.chord_start = Some(point);
            self.chord_end = None;
        } else {
            self.chord_end = Some(point);
        }
    }

    /// `(ψ̂, σ_ψ)` when the channel is aligned.
    pub(super) fn heading(&self) -> Option<(f64, f64)> {
        let state = self.state.as_ref()?;
        let std = state.heading_variance_rad2().sqrt();
        (std <= MAX_HEADING_STD_RAD).then(|| (state.heading_rad(), std))
    }

    /// `τ_ψ`, how long the heading's error persists at `time_s`, s: the interval between the
    /// channel's course references (each renews the error), or the time since the last one if
    /// that is longer, at most `longest_s` (and `longest_s` before any reference).
    pub(super) fn error_correlation_s(&self, time_s: f64, longest_s: f64) -> f64 {
        match self.course_times_s {
            (Some(previous_s), Some(last_s)) => (last_s - previous_s).max(time_s - last_s).min(longest_s),
            (None, Some(last_s)) => (time_s - last_s).min(longest_s),
            _ => longest_s,
        }
    }

    /// The channel's state (tests).
    #[cfg(test)]
    pub(super) fn state(&self) -> Option<&HeadingState> {
        self.state.as_ref()
    }
}
