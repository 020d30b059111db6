//! Compacted track history: one tag's consecutive track states packed into a compressed block.
//!
//! The pipeline stores every reported state as a row of `locations` (with its JSON line, for
//! live queries and a cheap append). The compaction pass ([`super::Store::compact_history`])
//! later packs the rows older than `server.compact_after_s` into `location_blocks`, one block
//! per tag and at most [`MAX_BLOCK_SPAN_S`] / [`MAX_BLOCK_STATES`], and deletes the rows, in
//! one transaction. Queries read both and merge them ([`HistoryCollector`]).
//!
//! # Block format (version 1)
//! A format byte, then DEFLATE of: the state count, the first state's time `t₀` (f64) and
//! server time `r₀` (ms), a string table (sources, statuses, modes), then per state a flag
//! byte and either
//! - *compact* fields, each coded against the previous compact state (zig-zag varints): the
//!   change of the time step `Δ²t` (µs), of the latency `r − t` (ms), the string indexes when
//!   they change; per axis the position's residual against its prediction `x̂ = x₋ + v₋ Δt`
//!   (mm), the velocity's change (mm/s) and the change of `σᵢ = √Pᵢᵢ` on a logarithmic grid
//!   (`σ = 2^(k/256)`, steps of 0.27 %); the changes of the correlations
//!   `ρᵢⱼ = Pᵢⱼ / (σᵢ σⱼ)` (10⁻³). The accuracy (√λmax of the horizontal covariance, as the
//!   pipeline computes it) is derived again when read; or
//! - *verbatim*: the exact time, position and accuracy and the JSON line as it was stored —
//!   for a state whose line is not an ordinary track line, whose numbers do not quantise
//!   (non-finite, out of range) or whose accuracy is not the covariance's.
//!
//! Reading a compact state back rebuilds its JSON line with the same keys, the covariance as
//! `Pᵢᵢ = σᵢ²`, `Pᵢⱼ = ρᵢⱼ σᵢ σⱼ`. So a compacted state keeps its time to 1 µs, its server time
//! exactly, position to 1 mm, velocity to 1 mm/s, standard deviations to 0.14 % and
//! correlations to 5 · 10⁻⁴; nothing else changes. A walking tag at 1 Hz takes about
//! 10–15 bytes a state (docs/SERVER.md, sizing).

use serde::{Deserialize, Serialize};

use super::packing::{deflate, inflate, put_bytes, put_f64, put_signed, put_strings, put_varint, string_at, Reader};
use super::{HistoryQuery, LocationRow};
use crate::convert::accuracy_m;

/// A block covers at most this long (s): a query reads blocks starting up to this long before
/// its range.
pub(crate) const MAX_BLOCK_SPAN_S: f64 = 3600.0;
/// A block holds at most this many states.
pub(crate) const MAX_BLOCK_STATES: usize = 4096;
/// The payload's format byte.
const FORMAT: u8 = 1;

const PREDICTED: u8 = 1;
const REVISED: u8 = 1 << 1;
const THREE_D: u8 = 1 << 2;
const HAS_MODE: u8 = 1 << 3;
const HAS_ACCURACY: u8 = 1 << 4;
/// The accuracy is stored, not derived from the covariance (a row the pipeline did not write).
const EXPLICIT_ACCURACY: u8 = 1 << 5;
/// Source, status or mode differ from the previous compact state's: their indexes follow.
const NEW_STRINGS: u8 = 1 << 6;
const VERBATIM: u8 = 1 << 7;

/// σ grid: `u = round(256 log₂ σ) + SIGMA_OFFSET`, `u = 0` for σ below 2⁻²⁰ m (read as 0).
const SIGMA_OFFSET: i64 = 20 * 256 + 1;
/// Predictions over longer gaps than this (µs) are not used: the position is coded against
/// the previous one.
const MAX_PREDICTION_US: i64 = 10_000_000;

/// One block of `location_blocks`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LocationBlock {
    /// The tag of all its states.
    pub tag: String,
    /// The first state's time (s).
    pub from_s: f64,
    /// The last state's time (s).
    pub to_s: f64,
    /// The newest state's server time (ms): retention deletes the block after it.
    pub received_ms: i64,
    /// Its number of states.
    pub count: i64,
    /// Format byte + DEFLATE stream.
    pub payload: Vec<u8>,
}

/// A track-file line's keys, as `rtls_engine`'s `TrackUpdate::to_json_line` writes them (same
/// order); a stored line with any other key is kept verbatim.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct TrackLine {
    cov: Vec<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    mode: Option<String>,
    predicted: bool,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    revised: Option<bool>,
    source: String,
    status: String,
    t: f64,
    tag: String,
    vx: f64,
    vy: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    vz: Option<f64>,
    x: f64,
    y: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    z: Option<f64>,
}

/// `value · scale` rounded to an integer; `None` when not finite or beyond ±2⁵⁰.
fn quantise(value: f64, scale: f64) -> Option<i64> {
    let scaled = (value * scale).round();
    (scaled.is_finite() && scaled.abs() < (1u64 << 50) as f64).then_some(scaled as i64)
}

/// σ (m) on the logarithmic grid (steps of 2^(1/256), 0.27 %).
fn sigma_code(sigma_m: f64) -> Option<i64> {
    if !(sigma_m.is_finite() && sigma_m >= 0.0) {
        return None;
    }
    if sigma_m < (-20.0f64).exp2() {
        return Some(0);
    }
    Some((256.0 * sigma_m.log2()).round() as i64 + SIGMA_OFFSET)
}

/// σ (m) of a grid code: `σ = 2^((u − SIGMA_OFFSET)/256)`.
fn sigma_from_code(code: i64) -> f64 {
    if code <= 0 {
        0.0
    } else {
        ((code - SIGMA_OFFSET) as f64 / 256.0).exp2()
    }
}

/// `v · Δt` in mm for `v` in mm/s and `Δt` in µs, rounded half away from zero; 0 for gaps
/// beyond [`MAX_PREDICTION_US`] (or negative).
fn displacement_mm(velocity_mm_s: i64, dt_us: i64) -> i64 {
    if !(0..=MAX_PREDICTION_US).contains(&dt_us) {
        return 0;
    }
    let product = i128::from(velocity_mm_s) * i128::from(dt_us);
    ((product + product.signum() * 500_000) / 1_000_000) as i64
}

/// A state on the grid: its integers and strings.
struct Quantised {
    flags: u8,
    dimensions: usize,
    strings: [Option<String>; 3],
    position_mm: [i64; 3],
    velocity_mm_s: [i64; 3],
    sigma_codes: [i64; 3],
    /// ρ₀₁, ρ₀₂, ρ₁₂ in 10⁻³.
    correlation_e3: [i64; 3],
    accuracy_tenth_mm: Option<i64>,
}

/// What the coder predicts the next compact state from: the previous one's integers.
#[derive(Default)]
struct Previous {
    t_us: i64,
    dt_us: i64,
    latency_ms: i64,
    strings: Option<[Option<u64>; 3]>,
    position_mm: [i64; 3],
    velocity_mm_s: [i64; 3],
    sigma_codes: [i64; 3],
    correlation_e3: [i64; 3],
}

/// The pairs `(i, j)`, `i < j`, of the correlations of a `d`-dimensional covariance.
fn pairs(d: usize) -> &'static [(usize, usize)] {
    if d == 3 {
        &[(0, 1), (0, 2), (1, 2)]
    } else {
        &[(0, 1)]
    }
}

fn quantised(row: &LocationRow, tag: &str) -> Option<Quantised> {
    let line: TrackLine = serde_json::from_str(&row.json).ok()?;
    let d = if line.z.is_some() { 3 } else { 2 };
    // the row's columns must be the line's own numbers, and the line the row's tag and time
    let same_columns = row.x_m.to_bits() == line.x.to_bits()
        && row.y_m.to_bits() == line.y.to_bits()
        && row.z_m.map(f64::to_bits) == line.z.map(f64::to_bits)
        && row.time_s.to_bits() == line.t.to_bits()
        && row.predicted == line.predicted
        && line.tag == tag
        && line.vz.is_some() == (d == 3)
        && line.revised != Some(false)
        && line.cov.len() == d * d;
    if !same_columns {
        return None;
    }
    let (mut position_mm, mut velocity_mm_s, mut sigma_codes) = ([0; 3], [0; 3], [0; 3]);
    let position = [line.x, line.y, line.z.unwrap_or(0.0)];
    let velocity = [line.vx, line.vy, line.vz.unwrap_or(0.0)];
    // σᵢ = √Pᵢᵢ, ρᵢⱼ = Pᵢⱼ / (σᵢ σⱼ) (0 when a σ is 0)
    let sigma_m = [0, 1, 2].map(|i| if i < d { line.cov[i * d + i].sqrt() } else { 0.0 });
    for axis in 0..d {
        position_mm[axis] = quantise(position[axis], 1e3)?;
        velocity_mm_s[axis] = quantise(velocity[axis], 1e3)?;
        sigma_codes[axis] = sigma_code(sigma_m[axis])?;
    }
    let mut correlation_e3 = [0; 3];
    for (k, &(i, j)) in pairs(d).iter().enumerate() {
        let product = sigma_m[i] * sigma_m[j];
        let rho = if product > 0.0 {
            line.cov[i * d + j] / product
        } else {
            0.0
        };
        // |ρ| ≤ 1 up to rounding; NaN fails too
        if rho.is_nan() || rho.abs() > 1.0 + 1e-9 {
            return None;
        }
        correlation_e3[k] = quantise(rho.clamp(-1.0, 1.0), 1e3)?;
    }
    let mut flags = 0;
    // the pipeline's accuracy is √λmax of the line's covariance: derived again when read
    let accuracy_tenth_mm = match row.accuracy_m {
        Some(accuracy) if accuracy.to_bits() != accuracy_m(&line.cov, d).to_bits() => {
            flags |= EXPLICIT_ACCURACY;
            Some(quantise(accuracy, 1e4)?)
        }
        _ => None,
    };
    for (set, flag) in [
        (line.predicted, PREDICTED),
        (line.revised == Some(true), REVISED),
        (d == 3, THREE_D),
        (line.mode.is_some(), HAS_MODE),
        (row.accuracy_m.is_some(), HAS_ACCURACY),
    ] {
        if set {
            flags |= flag;
        }
    }
    Some(Quantised {
        flags,
        dimensions: d,
        strings: [Some(line.source), Some(line.status), line.mode],
        position_mm,
        velocity_mm_s,
        sigma_codes,
        correlation_e3,
        accuracy_tenth_mm,
    })
}

/// Packs one tag's states (in time order, all of `tag`) into a block.
pub(crate) fn encode_block(tag: &str, rows: &[LocationRow]) -> LocationBlock {
    let t0_s = rows.first().map_or(0.0, |row| row.time_s);
    let r0_ms = rows.first().map_or(0, |row| row.received_ms);
    let states: Vec<Option<Quantised>> = rows.iter().map(|row| quantised(row, tag)).collect();
    let mut strings: Vec<String> = Vec::new();
    for text in states.iter().flatten().flat_map(|state| state.strings.iter().flatten()) {
        if !strings.contains(text) {
            strings.push(text.clone());
        }
    }
    let index = |text: &Option<String>| {
        text.as_ref()
            .map(|text| strings.iter().position(|s| s == text).unwrap_or(0) as u64)
    };

    let mut fields = Vec::with_capacity(rows.len() * 16);
    put_varint(&mut fields, rows.len() as u64);
    put_f64(&mut fields, t0_s);
    put_signed(&mut fields, r0_ms);
    put_strings(&mut fields, &strings);
    let mut previous = Previous::default();
    for (row, state) in rows.iter().zip(&states) {
        let t_us = quantise(row.time_s - t0_s, 1e6);
        let (Some(state), Some(t_us)) = (state, t_us) else {
            let mut flags = VERBATIM;
            for (set, flag) in [
                (row.z_m.is_some(), THREE_D),
                (row.accuracy_m.is_some(), HAS_ACCURACY),
                (row.predicted, PREDICTED),
            ] {
                if set {
                    flags |= flag;
                }
            }
            fields.push(flags);
            put_signed(&mut fields, row.received_ms - r0_ms);
            put_f64(&mut fields, row.time_s);
            put_f64(&mut fields, row.x_m);
            put_f64(&mut fields, row.y_m);
            if let Some(z_m) = row.z_m {
                put_f64(&mut fields, z_m);
            }
            if let Some(accuracy_m) = row.accuracy_m {
                put_f64(&mut fields, accuracy_m);
            }
            put_bytes(&mut fields, row.json.as_bytes());
            continue;
        };
        let indexes = state.strings.each_ref().map(index);
        let new_strings = previous.strings != Some(indexes);
        fields.push(state.flags | if new_strings { NEW_STRINGS } else { 0 });
        // Δ²t: the change of the interval (µs); the latency's change (ms)
        let dt_us = t_us - previous.t_us;
        put_signed(&mut fields, dt_us - previous.dt_us);
        let latency_ms = (row.received_ms - r0_ms) - t_us.div_euclid(1000);
        put_signed(&mut fields, latency_ms - previous.latency_ms);
        if new_strings {
            for index in indexes.iter().flatten() {
                put_varint(&mut fields, *index);
            }
        }
        let d = state.dimensions;
        for axis in 0..d {
            // position against its prediction x̂ = x₋ + v₋ Δt (mm)
            let predicted_mm = previous.position_mm[axis] + displacement_mm(previous.velocity_mm_s[axis], dt_us);
            put_signed(&mut fields, state.position_mm[axis] - predicted_mm);
            put_signed(&mut fields, state.velocity_mm_s[axis] - previous.velocity_mm_s[axis]);
            put_signed(&mut fields, state.sigma_codes[axis] - previous.sigma_codes[axis]);
        }
        for k in 0..pairs(d).len() {
            put_signed(&mut fields, state.correlation_e3[k] - previous.correlation_e3[k]);
        }
        if let Some(accuracy) = state.accuracy_tenth_mm {
            put_signed(&mut fields, accuracy);
        }
        previous = Previous {
            t_us,
            dt_us,
            latency_ms,
            strings: Some(indexes),
            position_mm: state.position_mm,
            velocity_mm_s: state.velocity_mm_s,
            sigma_codes: state.sigma_codes,
            correlation_e3: state.correlation_e3,
        };
    }
    LocationBlock {
        tag: tag.to_owned(),
        from_s: t0_s,
        to_s: rows.iter().map(|row| row.time_s).fold(t0_s, f64::max),
        received_ms: rows.iter().map(|row| row.received_ms).max().unwrap_or(r0_ms),
        count: rows.len() as i64,
        payload: deflate(FORMAT, &fields),
    }
}

/// Unpacks a block's states, oldest first.
///
/// # Errors
/// A message naming what is corrupt (the block is unreadable, not the database).
pub(crate) fn decode_block(tag: &str, payload: &[u8]) -> Result<Vec<LocationRow>, String> {
    let (format, fields) = inflate(payload)?;
    if format != FORMAT {
        return Err(format!("location block format {format} is not known to this build (1)"));
    }
    let mut reader = Reader::new(&fields);
    let count = usize::try_from(reader.varint()?).map_err(|_| "state count too large")?;
    if count > MAX_BLOCK_STATES * 16 {
        return Err(format!("{count} states in one block"));
    }
    let t0_s = reader.f64()?;
    let r0_ms = reader.signed()?;
    let strings = reader.strings()?;
    let string = |index: u64| string_at(&strings, index).map(str::to_owned);
    let mut previous = Previous::default();
    let mut rows = Vec::with_capacity(count);
    for _ in 0..count {
        let flags = reader.byte()?;
        let d = if flags & THREE_D != 0 { 3 } else { 2 };
        if flags & VERBATIM != 0 {
            let received_ms = r0_ms + reader.signed()?;
            let time_s = reader.f64()?;
            let (x_m, y_m) = (reader.f64()?, reader.f64()?);
            let z_m = if d == 3 { Some(reader.f64()?) } else { None };
            let accuracy_m = if flags & HAS_ACCURACY != 0 {
                Some(reader.f64()?)
            } else {
                None
            };
            let json = reader.text()?.to_owned();
            rows.push(LocationRow {
                received_ms,
                time_s,
                tag: tag.to_owned(),
                x_m,
                y_m,
                z_m,
                accuracy_m,
                predicted: flags & PREDICTED != 0,
                json,
            });
            continue;
        }
        let dt_us = previous.dt_us + reader.signed()?;
        let t_us = previous.t_us + dt_us;
        let latency_ms = previous.latency_ms + reader.signed()?;
        let strings_here = if flags & NEW_STRINGS != 0 {
            let mode = flags & HAS_MODE != 0;
            [
                Some(reader.varint()?),
                Some(reader.varint()?),
                if mode { Some(reader.varint()?) } else { None },
            ]
        } else {
            previous.strings.ok_or("a state reuses strings before any were given")?
        };
        let mut state = Previous {
            t_us,
            dt_us,
            latency_ms,
            strings: Some(strings_here),
            ..Previous::default()
        };
        for axis in 0..d {
            let predicted_mm = previous.position_mm[axis] + displacement_mm(previous.velocity_mm_s[axis], dt_us);
            state.position_mm[axis] = predicted_mm + reader.signed()?;
            state.velocity_mm_s[axis] = previous.velocity_mm_s[axis] + reader.signed()?;
            state.sigma_codes[axis] = previous.sigma_codes[axis] + reader.signed()?;
        }
        for k in 0..pairs(d).len() {
            state.correlation_e3[k] = previous.correlation_e3[k] + reader.signed()?;
        }
        let explicit_accuracy = if flags & EXPLICIT_ACCURACY != 0 {
            Some(reader.signed()? as f64 / 1e4)
        } else {
            None
        };
        // Pᵢᵢ = σᵢ², Pᵢⱼ = Pⱼᵢ = ρᵢⱼ σᵢ σⱼ
        let sigma_m = state.sigma_codes.map(sigma_from_code);
        let mut cov = vec![0.0; d * d];
        for i in 0..d {
            cov[i * d + i] = sigma_m[i] * sigma_m[i];
        }
        for (k, &(i, j)) in pairs(d).iter().enumerate() {
            cov[i * d + j] = state.correlation_e3[k] as f64 / 1e3 * sigma_m[i] * sigma_m[j];
            cov[j * d + i] = cov[i * d + j];
        }
        let accuracy_m = (flags & HAS_ACCURACY != 0).then(|| explicit_accuracy.unwrap_or_else(|| accuracy_m(&cov, d)));
        let position_m = state.position_mm.map(|mm| mm as f64 / 1e3);
        let velocity_mps = state.velocity_mm_s.map(|mm_s| mm_s as f64 / 1e3);
        let time_s = t0_s + t_us as f64 / 1e6;
        let predicted = flags & PREDICTED != 0;
        let [source, status, mode] = strings_here;
        let line = TrackLine {
            cov,
            mode: mode.map(string).transpose()?,
            predicted,
            revised: (flags & REVISED != 0).then_some(true),
            source: string(source.unwrap_or(u64::MAX))?,
            status: string(status.unwrap_or(u64::MAX))?,
            t: time_s,
            tag: tag.to_owned(),
            vx: velocity_mps[0],
            vy: velocity_mps[1],
            vz: (d == 3).then_some(velocity_mps[2]),
            x: position_m[0],
            y: position_m[1],
            z: (d == 3).then_some(position_m[2]),
        };
        let json = serde_json::to_string(&line).map_err(|e| format!("state not serialisable: {e}"))?;
        rows.push(LocationRow {
            received_ms: r0_ms + latency_ms + t_us.div_euclid(1000),
            time_s,
            tag: tag.to_owned(),
            x_m: position_m[0],
            y_m: position_m[1],
            z_m: (d == 3).then_some(position_m[2]),
            accuracy_m,
            predicted,
            json,
        });
        previous = state;
    }
    if !reader.is_empty() {
        return Err("bytes left after the last state".into());
    }
    Ok(rows)
}

/// Groups rows `(id, row)` into blocks: by tag, in time order, cut at [`MAX_BLOCK_SPAN_S`] and
/// [`MAX_BLOCK_STATES`]. `rows` come in the order they were stored, which states of one tag at
/// one time keep.
pub(crate) fn pack(mut rows: Vec<LocationRow>) -> Vec<LocationBlock> {
    // stable: ties keep the stored order
    rows.sort_by(|a, b| a.tag.cmp(&b.tag).then(a.time_s.total_cmp(&b.time_s)));
    let mut blocks = Vec::new();
    let mut start = 0;
    while start < rows.len() {
        let first = &rows[start];
        let mut end = start + 1;
        while end < rows.len()
            && end - start < MAX_BLOCK_STATES
            && rows[end].tag == first.tag
            && rows[end].time_s - first.time_s <= MAX_BLOCK_SPAN_S
        {
            end += 1;
        }
        blocks.push(encode_block(&first.tag, &rows[start..end]));
        start = end;
    }
    blocks
}

/// Merges a history query's rows (at most `limit` of them, oldest first) from the row table
/// and from blocks read in order of their first state's time.
pub(crate) struct HistoryCollector<'q> {
    query: &'q HistoryQuery,
    states: Vec<LocationRow>,
    /// The `limit`-th earliest time when last sorted: no later block can enter once it starts
    /// after it (it only falls as states are added, so a stale one reads more, never less).
    bound_s: Option<f64>,
}

impl<'q> HistoryCollector<'q> {
    /// Starts with the query's rows from `locations` (the first `limit` in time order).
    pub(crate) fn new(query: &'q HistoryQuery, rows: Vec<LocationRow>) -> Self {
        Self {
            query,
            states: rows,
            bound_s: None,
        }
    }

    /// The earliest first-state time a block may start at and still hold a state in range.
    pub(crate) fn earliest_block_start_s(&self) -> f64 {
        self.query.from_s - MAX_BLOCK_SPAN_S
    }

    /// Whether a block starting at `from_s` (blocks come in order of it) can still enter the
    /// first `limit` states; `false`: stop reading blocks.
    pub(crate) fn wants_block_from(&mut self, from_s: f64) -> bool {
        let limit = self.query.limit;
        if limit == 0 {
            return false;
        }
        // sorted when the limit is first reached, then only when twice as many are held
        let full = self.states.len() >= limit;
        if (full && self.bound_s.is_none()) || self.states.len() >= 2 * limit {
            self.sort_and_truncate();
            self.bound_s = self.states.last().map(|last| last.time_s);
        }
        self.bound_s.is_none_or(|bound| bound >= from_s)
    }

    /// Adds a block's states that are in the query's range.
    ///
    /// # Errors
    /// The block does not decode.
    pub(crate) fn add_block(&mut self, tag: &str, payload: &[u8]) -> Result<(), String> {
        let (from_s, to_s) = (self.query.from_s, self.query.to_s);
        let rows = decode_block(tag, payload)?;
        self.states.extend(
            rows.into_iter()
                .filter(|row| row.time_s >= from_s && row.time_s <= to_s),
        );
        Ok(())
    }

    fn sort_and_truncate(&mut self) {
        // stable: states at the same time keep their order (the rows first, then the blocks')
        self.states.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        self.states.truncate(self.query.limit);
    }

    /// The first `limit` states, oldest first.
    pub(crate) fn finish(mut self) -> Vec<LocationRow> {
        self.sort_and_truncate();
        self.states
    }
}

#[cfg(test)]
#[path = "history_blocks_tests.rs"]
mod tests;
