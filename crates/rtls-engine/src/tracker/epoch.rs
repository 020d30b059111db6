//! Anchor readings in epochs: buffering, solving an epoch into fixes (fix-then-filter), and
//! initialising a tightly coupled track from its first readings.

use super::anchors::AnchorReading;
use super::check::check_reading;
use super::coupled::coupled_update;
use super::direct::apply_deferred;
use super::gnss::close_due_gnss_epoch;
use super::noise::NoiseClass;
use super::output::{epoch_raw_fix, Output};
use super::range_bias::RoundReading;
use super::readings_fix::{corrected_range, solve, uninformative, FlatFix};
use super::track::{dimensions, rejected, Shared, Track};
use super::update::{fix_update, fix_update_as};
use crate::error::Result;
use crate::site::Pipeline;

/// A range / RSSI / TDOA reading: into the open epoch (fix-then-filter, or a track still
/// initialising) or straight into the filter (tightly coupled).
pub(super) fn anchor_reading<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    reading: AnchorReading,
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
    let coupled = shared.settings.pipeline == Pipeline::TightlyCoupled;
    if coupled && track.state.is_some() && !track.is_lost() {
        coupled_update(shared, track, time_s, reading, kind, out)?;
        return check_reading(shared, track, time_s, reading, out);
    }
    if coupled {
        // (re-)initialising: a lost track's prior is too stale to linearise about, so like a
        // new one it waits for a fix; keep the readings of the confirmation window and try
        expire_initial_readings(shared, track, time_s, kind, out);
        track.epoch.push((time_s, reading));
        let readings: Vec<AnchorReading> = track.epoch.iter().map(|(_, r)| *r).collect();
        if awaits_spanning_anchors(shared, track, &readings, time_s) {
            return Ok(());
        }
        // a failure waits for more readings; its reason is reported if the readings expire
        if let Ok(fixes) = solve::<N>(shared, &readings, None) {
            if awaits_informative_fix(shared, track, &fixes, time_s) {
                return Ok(());
            }
            track.epoch.clear();
            for (position, covariance, method) in fixes {
                out.fixes
                    .push(epoch_raw_fix(&track.tag, time_s, &position, &covariance, method));
                fix_update(shared, track, time_s, &position, &covariance, "epoch", out)?;
            }
        }
        return Ok(());
    }
    if epoch_due(shared, track, time_s, Some(reading.anchor())) {
        close_epoch(shared, track, out)?;
    }
    if track.epoch.is_empty() {
        track.epoch_start_s = time_s;
    }
    track.epoch.push((time_s, reading));
    // rewinding (a straggler re-opens it): the epoch closes once every reader of the last one
    // has reported, not at its deadline
    if shared.settings.rewind_horizon_s > 0.0 && holds_expected_readers(track) {
        let start_s = track.epoch_start_s;
        close_epoch(shared, track, out)?;
        track.early_closed_s = Some(start_s);
    }
    Ok(())
}

/// Automatic epochs (`tracker.epoch_s` absent): the longest a tag's readings are collected
/// into one fix-then-filter epoch, s. A walker moves about a metre in it.
pub const AUTO_EPOCH_MAX_S: f64 = 1.0;

/// Whether the open fix-then-filter epoch closes before a reading at `now_s` (of anchor
/// `next_anchor`; `None` for a tick or a record of another kind).
///
/// - `tracker.epoch_s` set: when `now_s` is more than `epoch_s` after the epoch's first
///   reading.
/// - Automatic (absent): readings with equal time stamps stay together. An epoch whose
///   readings share one time stamp closes at any later time, as with `epoch_s = 0`, unless it
///   is a lone reading of a tag whose readers report one at a time (Wi-Fi RTT, TDMA UWB: every
///   reading its own time stamp; `Track::one_reader_per_time`, learnt from the tag's previous
///   epoch). Such an epoch collects the readings that follow until one comes from an anchor
///   already in it (the next round), or until [`AUTO_EPOCH_MAX_S`] after its first reading.
///
/// A tag's first lone reading therefore closes alone and is refused ("1 distinct anchor
/// position"), as every lone reading was before; the rule changes nothing for a tag whose
/// epochs of equal time stamps name two or more anchors. Learning it from the previous epoch,
/// not from the lone reading itself, keeps a re-filtered late record from merging time
/// stamps: a replay that has taken only some of a late epoch's readings holds a lone reading
/// after a full epoch, and closes it as before.
pub(super) fn epoch_due<const N: usize>(
    shared: &Shared,
    track: &Track<N>,
    now_s: f64,
    next_anchor: Option<usize>,
) -> bool {
    let Some(&(_, first)) = track.epoch.first() else {
        return false;
    };
    let start_s = track.epoch_start_s;
    if let Some(window_s) = shared.settings.epoch_s {
        return now_s - start_s > window_s;
    }
    if now_s <= start_s {
        return false;
    }
    if now_s - start_s > AUTO_EPOCH_MAX_S {
        return true;
    }
    let one_time = track.epoch.iter().all(|(t, _)| *t == start_s);
    let one_anchor = track.epoch.iter().all(|(_, r)| r.anchor() == first.anchor());
    if one_time && !(one_anchor && track.one_reader_per_time) {
        return true;
    }
    next_anchor.is_some_and(|anchor| track.epoch.iter().any(|(_, r)| r.anchor() == anchor))
}

/// The window within which a straggling reading still belongs to an epoch closed early, s:
/// `tracker.epoch_s`, or [`AUTO_EPOCH_MAX_S`] with automatic epochs.
fn epoch_window_s(shared: &Shared) -> f64 {
    shared.settings.epoch_s.unwrap_or(AUTO_EPOCH_MAX_S)
}

/// A tightly coupled track waits at most this long for readings of anchors off the line of
/// those it has heard before it starts from them, s.
pub(super) const SPANNING_WAIT_S: f64 = 1.0;

/// Whether a tightly coupled track should wait before starting from `readings`: their anchors
/// lie on one line in plan (the first three heard along one wall), so a fix from them may be
/// the mirror image of the tag across it, metres off; the site has anchors off that line; and
/// the first reading is less than [`SPANNING_WAIT_S`] old (a tag that hears only a line of
/// anchors still starts).
fn awaits_spanning_anchors<const N: usize>(
    shared: &Shared,
    track: &Track<N>,
    readings: &[AnchorReading],
    time_s: f64,
) -> bool {
    still_waiting(track, time_s) && tightly_coupled_awaits_line(shared, readings)
}

/// Whether the track's first buffered reading is less than [`SPANNING_WAIT_S`] old at
/// `time_s` (a start may still wait for better readings).
fn still_waiting<const N: usize>(track: &Track<N>, time_s: f64) -> bool {
    let first_s = track.epoch.first().map_or(time_s, |(t, _)| *t);
    time_s - first_s < SPANNING_WAIT_S
}

/// Whether a tightly coupled track should wait for more readings before starting from
/// `fixes`: one is [`uninformative`] and the first reading is less than [`SPANNING_WAIT_S`]
/// old (more readings make the fix better; after that the track starts from what it has).
fn awaits_informative_fix<const N: usize>(shared: &Shared, track: &Track<N>, fixes: &[FlatFix], time_s: f64) -> bool {
    still_waiting(track, time_s) && fixes.iter().any(|fix| uninformative::<N>(shared, fix))
}

/// Whether `readings` come from anchors on one line in plan while the site has anchors off it
/// (a tightly coupled track does not start from them before [`SPANNING_WAIT_S`]).
fn tightly_coupled_awaits_line(shared: &Shared, readings: &[AnchorReading]) -> bool {
    if shared.settings.pipeline != Pipeline::TightlyCoupled || shared.anchors.working_on_a_line() {
        return false;
    }
    let points: Vec<[f64; 2]> = readings.iter().map(|r| shared.anchors.plan_position(r)).collect();
    super::anchors::on_a_line(&points)
}

/// Whether the open epoch holds a reading of every reader of the tag's last epoch.
fn holds_expected_readers<const N: usize>(track: &Track<N>) -> bool {
    track.held_open_epoch_s != Some(track.epoch_start_s)
        && !track.expected_readers.is_empty()
        && track
            .expected_readers
            .iter()
            .all(|&a| track.epoch.iter().any(|(_, r)| r.anchor() == a))
}

/// The start of the epoch closed early whose window `reading` at `time_s` falls in, when it
/// comes from a reader that epoch did not wait for: it belongs to that epoch, which is
/// re-solved with it.
pub(super) fn straggles<const N: usize>(
    shared: &Shared,
    track: &Track<N>,
    time_s: f64,
    reading: &AnchorReading,
) -> Option<f64> {
    track.early_closed_s.filter(|&start_s| {
        time_s >= start_s
            && time_s - start_s <= epoch_window_s(shared)
            && !track.expected_readers.contains(&reading.anchor())
    })
}

/// Whether a reading at `time_s` opens a new epoch (fix-then-filter). With automatic epochs
/// the reading's anchor is not known here, so an epoch its anchor's repeat closes is missed:
/// the caller then keeps no copy at the epoch's start, and a straggler rewinds further.
pub(super) fn opens_epoch<const N: usize>(shared: &Shared, track: &Track<N>, time_s: f64) -> bool {
    shared.settings.pipeline == Pipeline::FixThenFilter
        && (track.epoch.is_empty() || epoch_due(shared, track, time_s, None))
}

/// Closes the open epoch if `now_s` is past its window (fix-then-filter only), and the open
/// GNSS epoch (either pipeline).
pub(super) fn close_due_epoch<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    now_s: f64,
    out: &mut Output,
) -> Result<()> {
    if shared.settings.pipeline == Pipeline::FixThenFilter && epoch_due(shared, track, now_s, None) {
        close_epoch(shared, track, out)?;
    }
    if shared.settings.pipeline == Pipeline::TightlyCoupled {
        expire_initial_readings(shared, track, now_s, "epoch", out);
    }
    close_due_gnss_epoch(shared, track, now_s, out)
}

/// Tightly coupled, a track (re)initialising: readings older than the confirmation window are
/// dropped from its buffer and reported.
pub(super) fn expire_initial_readings<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    now_s: f64,
    kind: &'static str,
    out: &mut Output,
) {
    let window_s = shared.settings.initiation.within_s;
    // the buffer is in time order
    let expired = track.epoch.iter().take_while(|(t, _)| now_s - t > window_s).count();
    if expired > 0 {
        // why the buffered readings gave no fix (they would have been cleared if they had)
        let readings: Vec<AnchorReading> = track.epoch.iter().map(|(_, r)| *r).collect();
        let why = match solve::<N>(shared, &readings, None) {
            Err(reason) if !reason.is_empty() => format!(": {reason}"),
            Ok(_) if tightly_coupled_awaits_line(shared, &readings) => {
                ": their anchors lie on one line, and a fix from them alone may be the tag's mirror \
                 image across it (the track waits up to 1 s for an anchor off the line)"
                    .to_string()
            }
            Ok(fixes) if fixes.iter().any(|fix| uninformative::<N>(shared, fix)) => {
                ": their fix's standard deviation exceeds the anchors' spread (the track waits up \
                 to 1 s for readings that place it among them)"
                    .to_string()
            }
            _ => String::new(),
        };
        let reason = format!("{expired} reading(s) expired before enough anchors could initialise the track{why}");
        // at the end of input (`now_s` = ∞) the event is dated by the last expired reading:
        // an event always carries a finite time
        let time_s = if now_s.is_finite() {
            now_s
        } else {
            track.epoch[expired - 1].0
        };
        out.events.push(rejected(&track.tag, time_s, kind, reason));
        track.epoch.drain(..expired);
    }
}

/// Solves the epoch into fixes and applies them at its readings' mean time.
pub(super) fn close_epoch<const N: usize>(shared: &Shared, track: &mut Track<N>, out: &mut Output) -> Result<()> {
    let epoch = std::mem::take(&mut track.epoch);
    if epoch.is_empty() {
        return Ok(());
    }
    // the fix is dated at the mean time of the readings it is solved from: a least-squares
    // fix from readings spread over an epoch is where the moving tag was about then, not at
    // the last reading (dated there, a walker's fixes lagged ~v Δt/2 behind it). The track's
    // lifecycle has not been ticked past the epoch's first reading
    // (`tick::holds_earlier_readings`). The mean is taken as an offset from the first reading,
    // so readings with one time stamp keep it exactly.
    let first_s = epoch[0].0;
    let time_s = first_s + epoch.iter().map(|(t, _)| t - first_s).sum::<f64>() / epoch.len() as f64;
    // automatic epochs: a tag whose epoch spanned time stamps, or was a lone reading, reports
    // one reader at a time; one with several readers at one time stamp does not
    let first_anchor = epoch[0].1.anchor();
    track.one_reader_per_time =
        epoch.iter().any(|(t, _)| *t != first_s) || epoch.iter().all(|(_, r)| r.anchor() == first_anchor);
    // the readers the next epoch waits for (an early close sets its start after this)
    track.early_closed_s = None;
    track.expected_readers.clear();
    for (_, reading) in &epoch {
        if !track.expected_readers.contains(&reading.anchor()) {
            track.expected_readers.push(reading.anchor());
        }
    }
    // direct measurements held while the epoch was open: those before its fix come first
    apply_deferred(shared, track, time_s, out)?;
    // ranges with the track's learnt offsets removed (r − b̂, σ² + P_b)
    let stated: Vec<AnchorReading> = epoch.iter().map(|(_, r)| *r).collect();
    let readings: Vec<AnchorReading> = stated
        .iter()
        .map(|r| corrected_range(shared, track, *r, time_s))
        .collect();
    // a lost track's state is too stale to start the solver from
    let guess = track.state.as_ref().filter(|_| !track.is_lost());
    // a fix solved from RSSI alone carries shadowing errors, correlated over seconds
    let class = if readings.iter().all(|r| matches!(r, AnchorReading::Rssi { .. })) {
        NoiseClass::RssiFix
    } else {
        NoiseClass::Fix
    };
    match solve::<N>(shared, &readings, guess) {
        Ok(fixes) => {
            let single = fixes.len() == 1;
            for (position, covariance, method) in fixes {
                out.fixes
                    .push(epoch_raw_fix(&track.tag, time_s, &position, &covariance, method));
                let confirmed_before = is_confirmed(track);
                let accepted = fix_update_as(shared, track, (time_s, &position, &covariance), "epoch", class, out)?;
                if single && confirmed_before && accepted {
                    learn_offsets(shared, track, &stated, &readings, &position, time_s);
                }
            }
        }
        Err(reason) => out.events.push(rejected(&track.tag, time_s, "epoch", reason)),
    }
    // and those at or after it
    apply_deferred(shared, track, f64::INFINITY, out)
}

/// Whether the track is confirmed (its fixes are gated; a new or re-initialising track's are
/// not, and its offsets are not learnt from them).
fn is_confirmed<const N: usize>(track: &Track<N>) -> bool {
    matches!(track.status(), Some(crate::lifecycle::TrackStatus::Confirmed))
}

/// Fix-then-filter: the epoch's ranges (`corrected`: offset-corrected; `stated`: as read, for
/// their noise) against its accepted fix teach the
/// track's offsets — one reading per anchor, residual `rᵢ − b̂ᵢ − ‖p − aᵢ‖`, gradient
/// `(p − aᵢ)/‖p − aᵢ‖` (slant, at the tag's height in 2-D). The residuals of a least-squares
/// fix are already the part no position error explains; [`rtls_estimation::bias::BiasObservation`]'s projection and
/// parity test apply as in the tightly coupled pipeline.
fn learn_offsets<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    stated: &[AnchorReading],
    corrected: &[AnchorReading],
    position: &[f64],
    time_s: f64,
) {
    let Some(model) = &shared.range_bias else {
        return;
    };
    let correlation_s = shared.settings.adaptive_noise.correlation_s;
    if !track.range_bias.wants(time_s, correlation_s) {
        return;
    }
    let dims = dimensions::<N>();
    let tag = [
        position[0],
        position[1],
        if dims == 3 { position[2] } else { shared.tag_height_m },
    ];
    let mut round: Vec<(usize, RoundReading)> = Vec::new();
    for (stated, corrected) in stated.iter().zip(corrected) {
        let (
            AnchorReading::Range {
                anchor,
                position_m,
                variance_m2,
                ..
            },
            AnchorReading::Range { range_m, .. },
        ) = (*stated, *corrected)
        else {
            continue;
        };
        if round.iter().any(|(a, _)| *a == anchor) {
            continue;
        }
        let delta = [tag[0] - position_m[0], tag[1] - position_m[1], tag[2] - position_m[2]];
        let distance_m = (delta[0] * delta[0] + delta[1] * delta[1] + delta[2] * delta[2]).sqrt();
        if distance_m < 1e-6 {
            continue;
        }
        let mut gradient = [0.0; 3];
        for axis in 0..dims {
            gradient[axis] = delta[axis] / distance_m;
        }
        // the stated noise (the corrected reading's also holds the offset's variance)
        round.push((
            anchor,
            RoundReading {
                innovation_m: range_m - distance_m,
                noise_variance_m2: variance_m2,
                gradient,
            },
        ));
    }
    track.range_bias.learn_epoch(model, &round, time_s, dims, correlation_s);
}
