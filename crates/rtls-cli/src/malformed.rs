//! Records of an input file that cannot be used as they are written — a malformed line, a
//! mistyped or missing field, a reader id the site does not know — for `rtls track` and
//! `rtls tune` (which has no event file: its summary names them).
//!
//! A recording from another deployment may hold a few such lines (a gateway's truncated write
//! at a power cut, one payload in nanoseconds). Each costs only itself: it is skipped, written
//! to the events as `{"type": "malformed", "t", "line", "field", "reason"}` (at the newest
//! record time read before it, 0 before any) and counted in the run's summary with the first
//! few named by file, line and field. What is not skipped: a read error (the records after it
//! are unknown), an input of which nothing could be read, and an input whose first
//! [`GIVE_UP_AFTER`] records are all malformed (not a measurement file: the run stops there
//! rather than reading all of it). `--strict` stops at the first malformed record instead.

use rtls_engine::EngineError;
use serde_json::json;

/// Malformed records with no good one before them after which the input is given up.
pub const GIVE_UP_AFTER: usize = 1000;

/// How many malformed records the summary names.
const NAMED: usize = 3;

/// The malformed records of one input (see the module).
#[derive(Debug, Default)]
pub struct Malformed {
    strict: bool,
    count: usize,
    /// The first [`NAMED`], as their errors read.
    first: Vec<String>,
}

impl Malformed {
    /// `strict`: stop at the first malformed record.
    pub fn new(strict: bool) -> Self {
        Self {
            strict,
            ..Self::default()
        }
    }

    /// Takes the error of a record that could not be used, after `good` usable records whose
    /// newest time is `newest_s` (s): the `malformed` event's JSON line to write, or the error
    /// that stops the run (a read error, `--strict`, or [`GIVE_UP_AFTER`] malformed records
    /// without a good one).
    ///
    /// # Errors
    /// As above, each naming the file, line and field.
    pub fn skip(&mut self, error: EngineError, good: usize, newest_s: f64) -> anyhow::Result<String> {
        let EngineError::Parse {
            file,
            line,
            field,
            reason,
        } = &error
        else {
            return Err(error.into());
        };
        let (message, file) = (error.to_string(), file.clone());
        let event = json!({
            "type": "malformed",
            "t": if newest_s.is_finite() { newest_s } else { 0.0 },
            "line": line,
            "field": field,
            "reason": reason,
        })
        .to_string();
        if self.strict {
            return Err(anyhow::Error::from(error).context("--strict: the first malformed record stops the run"));
        }
        self.count += 1;
        if good == 0 && self.count >= GIVE_UP_AFTER {
            return Err(anyhow::Error::from(error).context(format!(
                "{file}: the first {GIVE_UP_AFTER} records are all malformed: is it a measurement \
                 file (docs/FORMATS.md)? The last of them"
            )));
        }
        if self.first.len() < NAMED {
            self.first.push(message);
        }
        Ok(event)
    }

    /// How many records were skipped.
    #[cfg(test)]
    fn count(&self) -> usize {
        self.count
    }

    /// The summary's line, when records were skipped.
    pub fn summary(&self) -> Option<String> {
        (self.count > 0).then(|| {
            let more = if self.count > self.first.len() { "; …" } else { "" };
            format!(
                "{} malformed record(s) skipped (each a `malformed` event): {}{more}",
                self.count,
                self.first.join("; ")
            )
        })
    }

    /// After the input: an error when records were skipped and none was usable (a run of
    /// nothing must not look like a quiet recording).
    ///
    /// # Errors
    /// As above, naming the first malformed record.
    pub fn check_some_usable(&self, good: usize, input: &str) -> anyhow::Result<()> {
        if good == 0 && self.count > 0 {
            anyhow::bail!(
                "{input}: none of its records could be used ({} malformed; the first: {})",
                self.count,
                self.first.first().map_or("-", String::as_str)
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_error(line: usize) -> EngineError {
        EngineError::Parse {
            file: "in.jsonl".into(),
            line,
            field: "t".into(),
            reason: "1e16 s is beyond ±1e11 s".into(),
        }
    }

    #[test]
    fn a_malformed_record_is_an_event_and_counted() {
        let mut malformed = Malformed::new(false);
        let event = malformed.skip(parse_error(801), 800, 20.9).unwrap();
        let event: serde_json::Value = serde_json::from_str(&event).unwrap();
        assert_eq!(event["type"], "malformed");
        assert_eq!(event["t"], 20.9);
        assert_eq!(event["line"], 801);
        assert_eq!(event["field"], "t");
        assert_eq!(malformed.count(), 1);
        let summary = malformed.summary().unwrap();
        assert!(summary.contains("in.jsonl:801: field `t`"), "{summary}");
        malformed.check_some_usable(800, "in.jsonl").unwrap();
        // no record before it: the event is at 0
        let mut first = Malformed::new(false);
        let event = first.skip(parse_error(1), 0, f64::NEG_INFINITY).unwrap();
        assert!(event.contains("\"t\":0.0"), "{event}");
    }

    #[test]
    fn strict_a_read_error_nothing_usable_and_a_foreign_file_stop_the_run() {
        assert!(Malformed::new(true).skip(parse_error(3), 2, 1.0).is_err());
        let read = EngineError::Read {
            file: "in.jsonl".into(),
            line: 9,
            reason: "disk".into(),
        };
        assert!(Malformed::new(false).skip(read, 9, 1.0).is_err());
        let mut malformed = Malformed::new(false);
        malformed.skip(parse_error(1), 0, 0.0).unwrap();
        let err = malformed.check_some_usable(0, "in.jsonl").unwrap_err().to_string();
        assert!(err.contains("none of its records"), "{err}");
        // a file of garbage is given up after GIVE_UP_AFTER lines, not read to its end
        let mut garbage = Malformed::new(false);
        let stopped = (1..=GIVE_UP_AFTER + 5).position(|line| garbage.skip(parse_error(line), 0, 0.0).is_err());
        assert_eq!(stopped, Some(GIVE_UP_AFTER - 1));
        // with a good record before them, malformed records never stop it
        let mut mixed = Malformed::new(false);
        assert!((1..=GIVE_UP_AFTER + 5).all(|line| mixed.skip(parse_error(line), 1, 0.0).is_ok()));
    }
}
