//! What every track shares ([`Shared`]: settings, anchors, models, filters, zones) and what one
//! track owns ([`Track`]: its state, lifecycle and channels), with the small helpers every part
//! of the tracker uses. The lowest file of the tracker: it imports the channels' state types,
//! never their logic.

use std::sync::Arc;

use rtls_estimation::adaptive::corrections::{CorrectionTest, CorrectionWindow};
use rtls_estimation::adaptive::correlation::ErrorCorrelation;
use rtls_estimation::adaptive::AdaptiveNoise;
use rtls_estimation::aided::HeadingModel;
use rtls_estimation::filter::{ExtendedKalmanFilter, KalmanFilter, UnscentedKalmanFilter};
use rtls_estimation::imm::ImmState;
use rtls_estimation::motion::ConstantVelocity;
use rtls_estimation::smoother::InformationStep;
use rtls_estimation::Gaussian;

use super::aided::HeldAcceleration;
use super::anchors::{AnchorReading, Anchors};
use super::bounds::SiteBounds;
use super::constraint_model::{Constraints, Hearing};
use super::gnss_state::GnssTrack;
use super::heading_cross::HeadingCross;
use super::heading_state::HeadingChannel;
use super::jump_state::{Alternation, JumpHypothesis};
use super::modes::Manoeuvres;
use super::noise::NoiseScales;
use super::offset_cross::OffsetCross;
use super::output::{Event, UpdateSource};
use super::range_bias::{OffsetModel, RangeBiases};
use super::schedule::{Scheduling, TrackSchedule};
use crate::lifecycle::{Lifecycle, LifecycleSettings, TrackStatus};
use crate::radio_map::RadioMap;
use crate::record::Measurement;
use crate::site::{AlarmSettings, TrackerSettings};
use crate::zones::Zone;

/// An accelerometer sample drives the prediction (zero-order hold) for at most this long, s.
pub(super) const ACCELERATION_HOLD_S: f64 = 1.0;

/// Everything the tracks share: settings, anchors, models, filters, alarm zones.
#[derive(Debug, Clone)]
pub(crate) struct Shared {
    pub(crate) settings: TrackerSettings,
    pub(crate) alarms: AlarmSettings,
    pub(crate) lifecycle: LifecycleSettings,
    pub(crate) anchors: Anchors,
    pub(crate) radio_map: Option<RadioMap>,
    /// CV with white-acceleration noise `q = σ_a²`.
    pub(crate) motion: ConstantVelocity,
    /// The CV model driven by a measured acceleration `u`, with the residual noise
    /// `tracker.aided_acceleration_noise_std_mps2` (see [`super::aided`]).
    pub(crate) aided_motion: ConstantVelocity,
    pub(crate) kf: KalmanFilter,
    pub(crate) ekf: ExtendedKalmanFilter,
    pub(crate) ukf: UnscentedKalmanFilter,
    /// `χ²` gate thresholds for 1, 2 and 3 degrees of freedom (index = dof − 1).
    pub(crate) gates: [f64; 3],
    /// The thresholds of a run of check fixes, `χ²(k · CHECK_RUN)` quantiles for `k` = 1, 2, 3
    /// position axes at the gate probability ([`super::check::run_disagrees`]).
    pub(crate) check_run_gates: [f64; 3],
    pub(crate) tag_height_m: f64,
    /// Hazard zones and zones without a working reader, checked by the predictive alarm.
    pub(crate) alarm_zones: Vec<Zone>,
    /// Ids of the zones whose listed readers are all broken.
    pub(crate) no_coverage_zones: Vec<String>,
    /// The interacting multiple models of `motion_model = "imm"`.
    pub(crate) manoeuvres: Option<Arc<Manoeuvres>>,
    /// Seed 003's adaptive node scheduling (`[scheduling]`).
    pub(crate) scheduling: Option<Arc<Scheduling>>,
    /// Adaptive measurement noise (`[tracker.adaptive_noise]`); `None` when disabled.
    pub(crate) adaptive: Option<AdaptiveNoise>,
    /// Error correlation measured from innovations (`adaptive_noise.correlation_from_innovations`);
    /// `None` when off.
    pub(crate) error_correlation: Option<ErrorCorrelation>,
    /// The box around the readers that a diverged track's position leaves.
    pub(crate) bounds: SiteBounds,
    /// The heading channel's model (`[tracker.heading]`).
    pub(crate) heading_model: HeadingModel,
    /// Anchors' range offsets as each track learns them (`[tracker.range_bias]`); `None` when
    /// disabled.
    pub(crate) range_bias: Option<OffsetModel>,
    /// The test of each track's consistency from its corrections (`[tracker.consistency]`);
    /// `None` when disabled.
    pub(crate) consistency: Option<CorrectionTest>,
    /// The site frame as ENU about `[frame] origin`; `None` without an origin (pseudoranges
    /// are then refused).
    pub(crate) frame: Option<rtls_positioning::gnss::LocalFrame>,
    /// Negative information, the corridor map and the speed limit; `None` when the site asks
    /// for none of them.
    pub(crate) constraints: Option<Constraints>,
}

impl Shared {
    /// The `χ²` gate for a measurement of `components` values (1–3; more take the 3-dof gate,
    /// none the 1-dof one).
    pub(super) fn gate(&self, components: usize) -> f64 {
        self.gates[components.clamp(1, 3) - 1]
    }
}

/// One tag's track: its state (a value it owns), lifecycle and pending work.
///
/// `repr(C)` keeps the fields in this order: what a record's update and every clock tick read
/// (the state, lifecycle, open epochs, report times, the GNSS epoch) come first, in the first
/// ~520 bytes of the 2.1 kB (2-D), so a tick over 100 000 tracks loads a few adjacent cache lines of
/// each instead of lines spread over the whole track (the compiler's order scattered them).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
#[repr(C)]
pub(crate) struct Track<const N: usize> {
    pub(super) tag: Arc<str>,
    /// The filtered state; `None` until the first fix.
    pub(super) state: Option<Gaussian<N>>,
    pub(super) lifecycle: Option<Lifecycle>,
    /// Under the IMM: the modes the state combines.
    pub(super) modes: Option<ImmState>,
    /// Fix-then-filter: the open epoch's readings; tightly coupled: readings waiting to
    /// initialise the track.
    pub(super) epoch: Vec<(f64, AnchorReading)>,
    /// Fix-then-filter: direct measurements (fixes, velocities, odometry) held while the
    /// epoch is open, applied in time order with its fix (see [`super::direct`]).
    pub(super) deferred: Vec<(f64, Measurement)>,
    pub(super) epoch_start_s: f64,
    pub(super) last_output_s: f64,
    /// Time of the latest update reported (measured or predicted), s: an update at or before
    /// it revises one already out.
    pub(super) last_reported_s: f64,
    /// Running share of gated updates that fell outside the gate (exponential, ~20 updates).
    pub(super) rejection_rate: f64,
    /// Gated updates since the track (re)started.
    pub(super) gated_updates: u32,
    /// An update not yet reported, and what produced it.
    pub(super) unreported: Option<UpdateSource>,
    /// GNSS: the open pseudorange epoch and the receiver clock filter.
    pub(super) gnss: GnssTrack,
    /// Last accelerometer sample.
    pub(super) acceleration: Option<HeldAcceleration>,
    /// The state's error's cross-covariance with the heading channel's, once a speed's
    /// velocity has been taken with the heading's error considered ([`super::consider`]).
    pub(super) heading_cross: Option<HeadingCross<N>>,
    /// Adaptive measurement-noise scales, per measurement class.
    pub(super) noise: NoiseScales,
    /// Heading, gyro bias and odometer offset, for yaw rates, odometry and IMU samples.
    pub(super) heading: HeadingChannel,
    /// Under the IMM: the reported (most probable) mode's index.
    pub(super) mode: usize,
    /// Alarm zones with a raised predictive alarm.
    pub(super) alarmed: Vec<bool>,
    /// The state frozen when the track was lost (its last position is kept and reported).
    /// Boxed, as the jump hypotheses are: rarely held, and a track is loaded on every record
    /// (a 100 000-tag site keeps each out of the cache), so what it seldom needs is not inline.
    pub(super) lost_state: Option<Box<Gaussian<N>>>,
    /// Under `[scheduling]`: the track's task nodes and last reported firing set.
    pub(super) schedule: TrackSchedule,
    /// The anchors' range offsets this track has learnt (tightly coupled).
    pub(super) range_bias: RangeBiases,
    /// The state error's cross-covariance with the offsets' errors, once a range has been
    /// taken with its offset's error considered ([`super::offset_cross`]).
    #[serde(default)]
    pub(super) offset_cross: Option<OffsetCross<N>>,
    /// The open epoch's readers, for negative information and the map at its close.
    pub(super) hearing: Hearing,
    /// Fix-then-filter with `rewind_horizon_s` > 0: the readers of the tag's last epoch. An
    /// epoch holding a reading of each closes at once instead of at its deadline.
    pub(super) expected_readers: Vec<usize>,
    /// Start time of the last epoch closed early, s: a reading of a new reader within its
    /// window re-opens it (the track rewinds and re-solves it with the reading).
    pub(super) early_closed_s: Option<f64>,
    /// Start time of an epoch re-opened for a straggler: it closes at its deadline, not early.
    pub(super) held_open_epoch_s: Option<f64>,
    /// Fix-then-filter with automatic epochs: the tag's readers report one at a time (its last
    /// epoch spanned several time stamps, or held a lone reading), so a lone reading opens an
    /// epoch that collects a round ([`super::epoch::epoch_due`]).
    #[serde(default)]
    pub(super) one_reader_per_time: bool,
    /// Gated-out fixes that agree with each other: where the tag may have jumped to
    /// ([`super::jump`]).
    #[serde(default)]
    pub(super) jump: Option<Box<JumpHypothesis<N>>>,
    /// The jump hypothesis the track's own fixes last dropped, and how often gated-out fixes
    /// came back to it ([`super::jump::Alternation`]).
    #[serde(default)]
    pub(super) alternation: Alternation<N>,
    /// The position corrections of the open consistency window ([`CorrectionTest`]).
    #[serde(default)]
    pub(super) corrections: CorrectionWindow,
    /// Tightly coupled: the readings since the last check fix ([`super::check`]).
    #[serde(default)]
    pub(super) check: Vec<(f64, AnchorReading)>,
    /// Their squared innovations over their stated variances, `Σ νᵢ² / Rᵢ`: when it is within
    /// the gate, no fix of them can fall outside it ([`super::check`]).
    #[serde(default)]
    pub(super) check_cost: f64,
    /// The distances `d²` of the last consecutive check fixes that were solved, newest last
    /// (at most [`super::check::CHECK_RUN`]; [`super::check`]).
    #[serde(default)]
    pub(super) check_distances: Vec<f64>,
    /// The covariance inflation the update being taken asked for, handed from
    /// [`super::step::accept`] to [`super::step::apply_fading`] (which runs once the update's
    /// cross-covariances are carried) within one record's processing; 1 between records, so
    /// not part of a checkpoint.
    #[serde(skip, default = "no_fading")]
    pub(super) fading: f64,
    /// The segment its reported states belong to ([`super::ReportedState::segment`]): the
    /// track's creation number (distinct among its tracker's tracks) in the high 32
    /// bits, how often it has (re)started from a fix in the low ones — so a tag whose track
    /// was deleted and created again never continues the old track's segment.
    #[serde(default)]
    pub(super) segment: u64,
    /// What the updates since the last reported state added (`J = P⁺⁻¹ − P⁻⁻¹`, `j`), kept
    /// only when the output keeps states, for [`super::Smoother`]; handed to the next reported
    /// state, so not part of a checkpoint.
    #[serde(skip)]
    /// (Boxed: a track that is not smoothed pays one pointer for it.)
    pub(super) information: Option<Box<InformationStep<N>>>,
    /// Whether an update since the last reported state told more than its `information`
    /// says: one correlated with states outside the CV layout (the heading's drift, a range
    /// offset), one predicted with an accelerometer's control input, or the IMM's; or a
    /// constraint (silent readers, the corridors, the speed limit) moved the state.
    #[serde(skip)]
    pub(super) information_partial: bool,
}

fn no_fading() -> f64 {
    1.0
}

impl<const N: usize> Track<N> {
    /// A track of `tag` without a state, with `alarm_zones` alarm flags clear; `creation`
    /// (distinct for each track its tracker creates) numbers its segments.
    pub(super) fn new(tag: Arc<str>, alarm_zones: usize, creation: u64) -> Self {
        Self {
            tag,
            state: None,
            lifecycle: None,
            epoch: Vec::new(),
            epoch_start_s: f64::NEG_INFINITY,
            deferred: Vec::new(),
            acceleration: None,
            unreported: None,
            last_output_s: f64::NEG_INFINITY,
            last_reported_s: f64::NEG_INFINITY,
            alarmed: vec![false; alarm_zones],
            lost_state: None,
            modes: None,
            mode: 0,
            schedule: TrackSchedule::default(),
            noise: NoiseScales::default(),
            rejection_rate: 0.0,
            gated_updates: 0,
            heading: HeadingChannel::default(),
            heading_cross: None,
            range_bias: RangeBiases::default(),
            offset_cross: None,
            gnss: GnssTrack::default(),
            hearing: Hearing::default(),
            expected_readers: Vec::new(),
            early_closed_s: None,
            held_open_epoch_s: None,
            one_reader_per_time: false,
            jump: None,
            alternation: Alternation::default(),
            corrections: CorrectionWindow::default(),
            check: Vec::new(),
            check_cost: 0.0,
            check_distances: Vec::new(),
            fading: 1.0,
            segment: creation << 32,
            information: None,
            information_partial: false,
        }
    }

    /// A (re)start from a fix: the next segment (the restarts count in the low 32 bits of
    /// [`Self::segment`], the creation number stays), with no information kept from before.
    pub(super) fn start_segment(&mut self) {
        self.segment = (self.segment & !0xffff_ffff) | u64::from((self.segment as u32).wrapping_add(1));
        self.information = None;
        self.information_partial = false;
    }

    /// What the updates since the last reported state added, and whether it is partial; both
    /// reset.
    pub(super) fn take_information(&mut self) -> (Option<InformationStep<N>>, bool) {
        (
            self.information.take().map(|step| *step),
            std::mem::take(&mut self.information_partial),
        )
    }

    pub(super) fn status(&self) -> Option<TrackStatus> {
        self.lifecycle.as_ref().map(Lifecycle::status)
    }

    pub(super) fn is_lost(&self) -> bool {
        self.status() == Some(TrackStatus::Lost)
    }
}

/// Tracked dimensions of a CV state of size `N`.
pub(super) const fn dimensions<const N: usize>() -> usize {
    N / 2
}

pub(super) fn rejected(tag: &Arc<str>, time_s: f64, kind: &'static str, reason: String) -> Event {
    Event::Rejected {
        tag: Arc::clone(tag),
        time_s,
        kind,
        reason,
    }
}

/// The state a fix starts a track at: `x₀ = [p, 0]`, `P₀ = diag(Σ_fix, σ_v² I)` (`σ_v` the
/// site's `initial_speed_std_mps`); an axis the fix does not give (a 2-D fingerprint fix in a
/// 3-D track) at the tag height with a 10 m standard deviation.
///
/// # Errors
/// A covariance that is not finite and positive definite.
pub(super) fn state_from_fix<const N: usize>(
    shared: &Shared,
    time_s: f64,
    position: &[f64],
    covariance: &[f64],
) -> rtls_estimation::Result<Gaussian<N>> {
    let k = position.len();
    let mut mean = rtls_estimation::Vector::<N>::zeros();
    let mut p0 = rtls_estimation::Matrix::<N>::zeros();
    let speed_variance = shared.settings.initial_speed_std_mps.powi(2);
    for i in 0..dimensions::<N>() {
        p0[(2 * i + 1, 2 * i + 1)] = speed_variance;
        if i < k {
            mean[2 * i] = position[i];
            for j in 0..k {
                p0[(2 * i, 2 * j)] = covariance[i * k + j];
            }
        } else {
            mean[2 * i] = shared.tag_height_m;
            p0[(2 * i, 2 * i)] = 100.0;
        }
    }
    Gaussian::new(mean, p0, time_s)
}
