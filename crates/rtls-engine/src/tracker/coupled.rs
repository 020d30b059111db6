//! Tightly coupled updates: one range / RSSI / TDOA reading straight into the EKF or UKF
//! (seed 003's one-observation update), with the reader's learnt range offset and the range
//! self-calibration.

use nalgebra::{DVector, SVector};
use rtls_estimation::filter::{consider_update_scalar, Updated};
use rtls_estimation::measurement::MeasurementModel;
use rtls_estimation::{Gaussian, Matrix};

use super::anchors::AnchorReading;
use super::models::{AnchorLaw, AnchorMeasurement};
use super::noise::{NoiseClass, Source};
use super::offset_cross::OffsetCross;
use super::output::{Output, UpdateSource};
use super::range_bias::{Learning, RoundReading};
use super::step::{accept, apply_fading, carry_heading_cross, is_gated, outside_gate, predict, Verdict};
use super::track::{dimensions, rejected, Shared, Track};
use crate::error::Result;
use crate::site::FilterKind;

/// Tightly coupled: one range / RSSI / TDOA straight into the EKF or UKF (seed 003's
/// one-observation update).
pub(super) fn coupled_update<const N: usize>(
    shared: &Shared,
    track: &mut Track<N>,
    time_s: f64,
    reading: AnchorReading,
    kind: &'static str,
    out: &mut Output,
) -> Result<()> {
    let Some(state) = track.state.as_ref() else {
        return Ok(());
    };
    let class = match reading {
        AnchorReading::Range { .. } => NoiseClass::Range,
        AnchorReading::Rssi { .. } => NoiseClass::Rssi,
        AnchorReading::Tdoa { .. } => NoiseClass::Tdoa,
    };
    let anchor = match reading {
        AnchorReading::Range { anchor, .. }
        | AnchorReading::Rssi { anchor, .. }
        | AnchorReading::Tdoa { anchor, .. } => anchor,
    };
    // R ← c R for errors correlated in time (c = max(1, 2τ_c/Δt) per reader), then λ R
    let source = Source { class, anchor };
    let inflation = track.noise.correlation_inflation(
        source,
        time_s,
        class.correlation_s(&shared.settings.adaptive_noise),
        shared.error_correlation.as_ref(),
    );
    let scale = inflation * track.noise.scale(class);
    // the anchor's learnt range offset: z' = r − b⁻, and its error either considered
    // (super::offset_cross) or added to the noise as if fresh, R' = λ c R + P_b⁻
    let bias_prior = match (&shared.range_bias, reading) {
        (Some(model), AnchorReading::Range { anchor, .. }) => Some(track.range_bias.offset(model, anchor, time_s)),
        _ => None,
    };
    let consider_slot = match (&shared.range_bias, reading) {
        (Some(model), AnchorReading::Range { anchor, .. }) if considers_offsets(shared) => {
            Some(track.range_bias.slot(model, anchor))
        }
        _ => None,
    };
    let (model, z, stated_variance) = match reading {
        AnchorReading::Range {
            position_m,
            range_m,
            variance_m2,
            ..
        } => {
            let (offset_m, offset_variance_m2) = bias_prior.unwrap_or((0.0, 0.0));
            let fresh_offset_variance_m2 = if consider_slot.is_some() {
                0.0
            } else {
                offset_variance_m2
            };
            (
                AnchorMeasurement::new(
                    position_m,
                    shared.tag_height_m,
                    AnchorLaw::Range,
                    scale * variance_m2 + fresh_offset_variance_m2,
                ),
                range_m - offset_m,
                variance_m2,
            )
        }
        AnchorReading::Rssi {
            anchor,
            rssi_dbm,
            law: [p0, d0, n, _],
            variance_db2,
        } => {
            let law = AnchorLaw::LogDistance {
                reference_power_dbm: p0,
                reference_distance_m: d0,
                exponent: n,
            };
            (
                AnchorMeasurement::new(
                    shared.anchors.get(anchor).position_m,
                    shared.tag_height_m,
                    law,
                    scale * variance_db2,
                ),
                rssi_dbm,
                variance_db2,
            )
        }
        AnchorReading::Tdoa {
            anchor,
            reference,
            range_difference_m,
            variance_m2,
        } => {
            let law = AnchorLaw::RangeDifference {
                reference_m: shared.anchors.get(reference).position_m,
            };
            (
                AnchorMeasurement::new(
                    shared.anchors.get(anchor).position_m,
                    shared.tag_height_m,
                    law,
                    scale * variance_m2,
                ),
                range_difference_m,
                variance_m2,
            )
        }
    };
    let prior = predict(shared, track, state, time_s)?;
    let measured = z;
    // a considered range: its cross-covariance with the offsets after the update, A = I − K H
    // and H P⁻ Hᵀ
    let mut considered: Option<Considered<N>> = None;
    let result = if let (Some(slot), Some(bias_model)) = (consider_slot, &shared.range_bias) {
        // X_b carried to the range's time in place (F(Δt) composes, so a range that is not
        // taken leaves it right for the next)
        let cross = track.offset_cross.get_or_insert_with(|| OffsetCross::new(time_s));
        cross.predict_to(time_s);
        let column = cross.column(slot);
        let (offset_variance_m2, offset_row) = track.range_bias.covariance_column(bias_model, slot, time_s);
        considered_range(
            &prior.state,
            &model,
            measured,
            slot,
            column,
            offset_variance_m2,
            offset_row,
        )
        .map(|(updated, taken)| {
            considered = Some(taken);
            updated
        })
    } else {
        let z = DVector::from_element(1, z);
        match shared.settings.filter {
            FilterKind::Ukf => shared.ukf.update(&prior.state, &model, &z),
            FilterKind::Ekf | FilterKind::Kf => shared.ekf.update(&prior.state, &model, &z),
        }
    }
    .and_then(|updated| match (&shared.manoeuvres, &prior.modes) {
        // every mode updated by an EKF step in its own layout
        (Some(manoeuvres), Some(modes)) => {
            let posterior = manoeuvres.update_anchor(modes, &model, measured)?;
            let state = manoeuvres.combined(&posterior)?;
            Ok((Updated { state, ..updated }, Some(posterior)))
        }
        _ => Ok((updated, None)),
    });
    match result {
        Ok((updated, modes)) => {
            let mut learning = Learning::Nothing;
            // the check's bound: Σ νᵢ² / Rᵢ with the variance the solver weights the reading by
            let solver_variance = stated_variance + bias_prior.map_or(0.0, |(_, variance_m2)| variance_m2);
            track.check_cost += updated.innovation[0].powi(2) / solver_variance;
            out.innovations
                .record(class, &updated, shared.gates[0], scale / inflation);
            track.noise.observe(
                shared.adaptive.as_ref(),
                class,
                &updated,
                &[inflation * stated_variance],
                shared.gates[0],
            );
            track
                .noise
                .observe_correlation(shared.error_correlation.as_ref(), source, &updated);
            if let (Some(bias_model), Some((_, offset_variance_m2)), AnchorReading::Range { variance_m2, .. }) =
                (&shared.range_bias, bias_prior, reading)
            {
                // learn only from a confirmed track whose prediction error is one the round's
                // projection removes: linear in the range (the projection removes the error along
                // each range, not the second-order part δ_⊥²/(2 d) across it: (tr P⁻ₚₚ − H P⁻ Hᵀ)
                // / (2 d) ≤ ½ σ) and settled (H P⁻ Hᵀ ≤ λ c σ² + P_bᵢᵢ: no reading moves the
                // state by more than half its error along the range, so the round's readings
                // share one error). The offset's variance is in the bound because an offset of
                // metres (Wi-Fi round-trip time) leaves the position that uncertain until it is
                // learnt.
                let reading_variance_m2 = scale * variance_m2;
                let predicted_variance_m2 = considered.as_ref().map_or_else(
                    || updated.innovation_covariance[(0, 0)] - reading_variance_m2 - offset_variance_m2,
                    |considered| considered.prediction_variance_m2,
                );
                let settled = predicted_variance_m2 <= reading_variance_m2 + offset_variance_m2;
                // h(x⁻) = z − ν: the predicted range
                let predicted_range_m = measured - updated.innovation[0];
                let linear = || {
                    second_order_range_error_m(&prior.state, predicted_range_m, predicted_variance_m2)
                        .is_some_and(|error_m| error_m <= 0.5 * variance_m2.sqrt())
                };
                let correlation_s = shared.settings.adaptive_noise.correlation_s;
                if outside_gate(shared, track, &updated) {
                    // the prediction this round is measured against is in doubt
                    track.range_bias.discard_round();
                } else if is_gated(track) && settled && track.range_bias.wants(time_s, correlation_s) && linear() {
                    // the reading's part in its round: ν, λ σ² (one look) and ∂h/∂p at the
                    // prediction
                    if let Ok(jacobian) = MeasurementModel::jacobian(&model, prior.state.mean()) {
                        let mut gradient = [0.0; 3];
                        for (axis, g) in gradient.iter_mut().enumerate().take(dimensions::<N>()) {
                            *g = jacobian[(0, 2 * axis)];
                        }
                        let reading = RoundReading {
                            innovation_m: updated.innovation[0],
                            noise_variance_m2: reading_variance_m2 / inflation,
                            gradient,
                        };
                        learning = track.range_bias.observe(
                            bias_model,
                            anchor,
                            reading,
                            time_s,
                            dimensions::<N>(),
                            correlation_s,
                        );
                    }
                }
            }
            if accept(
                shared,
                track,
                (&prior.state, updated),
                modes,
                kind,
                UpdateSource::Anchors,
                out,
            )? == Verdict::Taken
            {
                match considered {
                    Some(considered) => {
                        // X_b from the considered update; X_h ← A F X_h (P⁺ ≠ A P⁻ here)
                        if let Some(cross) = track.offset_cross.as_mut() {
                            cross.after_considered_range(
                                &considered.a,
                                &considered.gain,
                                &considered.offset_row,
                                considered.slot,
                                considered.column,
                            );
                        }
                        track.heading_cross = track.heading_cross.map(|cross| cross.after_gain(time_s, &considered.a));
                        apply_fading(track)?;
                    }
                    None => carry_heading_cross(track, &prior.state)?,
                }
            }
            // a learning round measured the offsets: X_b ← X_b (P_b⁻)⁻¹ P_b⁺ (super::offset_cross)
            match learning {
                Learning::Nothing => {}
                Learning::Learnt { prior, posterior } => {
                    track.offset_cross = track
                        .offset_cross
                        .as_ref()
                        .and_then(|cross| cross.after_learning(&prior, &posterior));
                }
                Learning::Forgotten => track.offset_cross = None,
            }
            Ok(())
        }
        Err(error) => {
            out.events.push(rejected(
                &track.tag,
                time_s,
                kind,
                format!("filter update failed: {error}"),
            ));
            Ok(())
        }
    }
}

/// What a considered range leaves for after its acceptance.
struct Considered<const N: usize> {
    /// The offset's slot `i`.
    slot: usize,
    /// `P_b[i, ·]` before the update (a learning round may change `P_b` before acceptance).
    offset_row: Vec<f64>,
    /// `X_bᵢ` after the update.
    column: SVector<f64, N>,
    /// `K`.
    gain: SVector<f64, N>,
    /// `A = I − K H`.
    a: Matrix<N>,
    /// `H P⁻ Hᵀ`: the prediction's variance along the range, m².
    prediction_variance_m2: f64,
}

/// One range `z' = r − b̂ᵢ = h(x) + eᵢᵀ e_b + w` by the Schmidt–Kalman update
/// ([`consider_update_scalar`]), linearised at the prior (the EKF's `H`), with `column`, the
/// column `i` of `X_b` at the range's time, and `P_bᵢᵢ` (equations in
/// [`super::offset_cross`]); `model` carries `R = λ c σ²` alone; `offset_row` is `P_b[i, ·]`,
/// kept for carrying the other columns once the update is taken.
fn considered_range<const N: usize>(
    prior: &Gaussian<N>,
    model: &AnchorMeasurement,
    range_m: f64,
    slot: usize,
    column: SVector<f64, N>,
    offset_variance_m2: f64,
    offset_row: Vec<f64>,
) -> rtls_estimation::Result<(Updated<N>, Considered<N>)> {
    // H = ∂h/∂x at x⁻,  ν = z' − h(x⁻)
    let jacobian = MeasurementModel::<N>::jacobian(model, prior.mean())?;
    let h = SVector::<f64, N>::from_fn(|col, _| jacobian[(0, col)]);
    let predicted = MeasurementModel::<N>::predict(model, prior.mean())?;
    let r = MeasurementModel::<N>::noise_covariance(model)[(0, 0)];
    let (updated, column, a) =
        consider_update_scalar(prior, &column, offset_variance_m2, &h, r, range_m - predicted[0])?;
    let gain = SVector::<f64, N>::from_fn(|row, _| updated.gain[(row, 0)]);
    // H P⁻ Hᵀ
    let prediction_variance_m2 = h.dot(&(prior.covariance() * h));
    Ok((
        updated,
        Considered {
            slot,
            offset_row,
            column,
            gain,
            a,
            prediction_variance_m2,
        },
    ))
}

/// The expected second-order error of a range predicted from an uncertain position,
/// `E[δ_⊥²] / (2 d) = (tr P⁻ₚₚ − H P⁻ Hᵀ) / (2 d)` (m), `d` the predicted slant distance
/// (`distance_m`), `P⁻ₚₚ` the position block and `H P⁻ Hᵀ` (`along_m2`) the variance along the
/// range; `None` for a tag on its anchor.
fn second_order_range_error_m<const N: usize>(prior: &Gaussian<N>, distance_m: f64, along_m2: f64) -> Option<f64> {
    // tr P⁻ₚₚ over the position entries (x, y[, z] at 0, 2[, 4])
    let trace_m2: f64 = (0..dimensions::<N>())
        .map(|axis| prior.covariance()[(2 * axis, 2 * axis)])
        .sum();
    (distance_m > 1e-6).then(|| (trace_m2 - along_m2).max(0.0) / (2.0 * distance_m))
}

/// Whether ranges are taken with their offsets' errors considered: `[tracker.range_bias]`
/// enabled with `consider`, an EKF without the IMM.
pub(super) fn considers_offsets(shared: &Shared) -> bool {
    shared.range_bias.is_some()
        && shared.settings.range_bias.consider
        && shared.manoeuvres.is_none()
        && shared.settings.filter != FilterKind::Ukf
}
