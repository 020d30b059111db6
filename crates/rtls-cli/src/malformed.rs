//! The records of a measurement file for `rtls track`, `rtls tune` and `rtls survey` (`tune` and
//! `survey` have no event file: their summaries name them), where a record that cannot be used as written — a malformed
//! line, a mistyped or missing field, a reader id the site does not know — costs only itself.
//!
//! A recording from another deployment may hold a few such lines (a gateway's truncated write
//! at a power cut, one payload in nanoseconds). Each is skipped, kept as a `malformed` event
//! `{"type": "malformed", "t", "line", "field", "reason"}` (at the newest record time read so
//! far — the record's own when it parsed —, 0 before any) and counted in the run's summary with the first few named by file,
//! line and field. What is not skipped: a read error (the records after it are unknown), an
//! input of which nothing could be used, and an input whose first [`GIVE_UP_AFTER`] records
//! are all malformed (not a measurement file: the run stops there rather than reading all of
//! it). `--strict` stops at the first malformed record instead.

use std::io::BufRead;

use rtls_engine::record::{CsvRecords, JsonLines, Record};
use rtls_engine::EngineError;
use serde_json::json;

/// Malformed records with no good one before them after which the input is given up.
pub const GIVE_UP_AFTER: usize = 1000;

/// How many malformed records the summary names.
const NAMED: usize = 3;

/// A measurement file in either format.
enum Format<R> {
    Csv(CsvRecords<R>),
    Json(JsonLines<R>),
}

/// The records of one measurement file, the malformed ones skipped (see the module).
pub struct InputRecords<R> {
    format: Format<R>,
    name: String,
    malformed: Malformed,
}

impl<R: BufRead> InputRecords<R> {
    /// Reads `reader`, named `name` in errors and events: CSV when `csv`, else JSON Lines.
    /// `strict`: the first malformed record stops the run.
    ///
    /// # Errors
    /// A CSV file whose header cannot be read.
    pub fn new(reader: R, name: &str, csv: bool, strict: bool) -> anyhow::Result<Self> {
        let format = if csv {
            Format::Csv(CsvRecords::new(reader, name)?)
        } else {
            Format::Json(JsonLines::new(reader, name))
        };
        Ok(Self {
            format,
            name: name.to_string(),
            malformed: Malformed {
                strict,
                ..Malformed::default()
            },
        })
    }

    /// The next record that parses, with its 1-based line; those that do not are skipped on
    /// the way ([`Self::take_events`]).
    ///
    /// # Errors
    /// A read error, `--strict`'s first malformed record, or [`GIVE_UP_AFTER`] malformed
    /// records without a good one, each naming the file, line and field.
    pub fn next_record(&mut self) -> anyhow::Result<Option<(Record, usize)>> {
        loop {
            let (next, line) = match &mut self.format {
                Format::Csv(records) => (records.next(), records.line()),
                Format::Json(records) => (records.next(), records.line()),
            };
            match next {
                None => return Ok(None),
                Some(Ok(record)) => {
                    self.malformed.read(record.time_s);
                    return Ok(Some((record, line)));
                }
                Some(Err(error)) => self.malformed.skip(error)?,
            }
        }
    }

    /// A record [`Self::next_record`] gave that cannot be used (a reader id the site does not
    /// know): skipped like a malformed line.
    ///
    /// # Errors
    /// As [`Self::next_record`].
    pub fn refuse(&mut self, error: EngineError) -> anyhow::Result<()> {
        self.malformed.refused += 1;
        self.malformed.skip(error)
    }

    /// The `malformed` events (JSON lines) of the records skipped since the last call.
    pub fn take_events(&mut self) -> Vec<String> {
        std::mem::take(&mut self.malformed.events)
    }

    /// After the last record: the summary's line when records were skipped.
    ///
    /// # Errors
    /// Records were skipped and none was usable (a run of nothing must not look like a quiet
    /// recording), naming the first.
    pub fn finish(&self) -> anyhow::Result<Option<String>> {
        let malformed = &self.malformed;
        if malformed.good() == 0 && malformed.count > 0 {
            anyhow::bail!(
                "{}: none of its records could be used ({} malformed; the first: {})",
                self.name,
                malformed.count,
                malformed.first.first().map_or("-", String::as_str)
            );
        }
        Ok((malformed.count > 0).then(|| {
            let more = if malformed.count > malformed.first.len() {
                "; …"
            } else {
                ""
            };
            format!(
                "{} malformed record(s) skipped (each a `malformed` event): {}{more}",
                malformed.count,
                malformed.first.join("; ")
            )
        }))
    }
}

/// What was read and skipped so far.
#[derive(Debug, Default)]
struct Malformed {
    strict: bool,
    /// Records that parsed …
    parsed: usize,
    /// … of which refused afterwards.
    refused: usize,
    /// The newest time of a record that parsed (s; −∞ before any).
    newest_s: Option<f64>,
    count: usize,
    /// The first [`NAMED`], as their errors read.
    first: Vec<String>,
    /// `malformed` events not taken yet.
    events: Vec<String>,
}

impl Malformed {
    /// Usable records so far.
    fn good(&self) -> usize {
        self.parsed - self.refused
    }

    /// Notes a record that parsed, of time `time_s` (s).
    fn read(&mut self, time_s: f64) {
        self.parsed += 1;
        if time_s.is_finite() {
            self.newest_s = Some(self.newest_s.map_or(time_s, |newest_s| newest_s.max(time_s)));
        }
    }

    /// Skips the record of `error`, keeping its event, or stops the run (see the module).
    fn skip(&mut self, error: EngineError) -> anyhow::Result<()> {
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
            "t": self.newest_s.unwrap_or(0.0),
            "line": line,
            "field": field,
            "reason": reason,
        })
        .to_string();
        if self.strict {
            return Err(anyhow::Error::from(error).context("--strict: the first malformed record stops the run"));
        }
        self.count += 1;
        if self.good() == 0 && self.count >= GIVE_UP_AFTER {
            return Err(anyhow::Error::from(error).context(format!(
                "{file}: the first {GIVE_UP_AFTER} records are all malformed: is it a measurement \
                 file (docs/FORMATS.md)? The last of them"
            )));
        }
        if self.first.len() < NAMED {
            self.first.push(message);
        }
        self.events.push(event);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn records(text: &str, strict: bool) -> InputRecords<&[u8]> {
        InputRecords::new(text.as_bytes(), "in.jsonl", false, strict).unwrap()
    }

    const GOOD: &str =
        r#"{"t": 20.9, "tag": "w", "kind": "fix", "position_m": [1.0, 2.0], "covariance_m2": [1.0, 0.0, 0.0, 1.0]}"#;

    #[test]
    fn a_malformed_record_is_an_event_and_counted() {
        // a time in nanoseconds on line 2
        let text = format!("{GOOD}\n{}\n{GOOD}\n", GOOD.replace("20.9", "1e16"));
        let mut input = records(&text, false);
        assert_eq!(input.next_record().unwrap().unwrap().1, 1);
        // line 2 is skipped on the way to line 3
        assert_eq!(input.next_record().unwrap().unwrap().1, 3);
        assert!(input.next_record().unwrap().is_none());
        let events = input.take_events();
        assert_eq!(events.len(), 1);
        let event: serde_json::Value = serde_json::from_str(&events[0]).unwrap();
        assert_eq!(event["type"], "malformed");
        assert_eq!(event["t"], 20.9);
        assert_eq!(event["line"], 2);
        assert_eq!(event["field"], "t");
        assert!(input.take_events().is_empty());
        let summary = input.finish().unwrap().unwrap();
        assert!(summary.starts_with("1 malformed record(s) skipped"), "{summary}");
        assert!(summary.contains("in.jsonl:2: field `t`"), "{summary}");
        // before any record the event is at 0; a refused record is skipped the same way
        let text = format!("not json\n{GOOD}\n");
        let mut input = records(&text, false);
        let (_, line) = input.next_record().unwrap().unwrap();
        let unknown = EngineError::Parse {
            file: "in.jsonl".into(),
            line,
            field: "anchor".into(),
            reason: "not a reader".into(),
        };
        input.refuse(unknown).unwrap();
        let events = input.take_events();
        assert!(events[0].contains("\"t\":0.0"), "{events:?}");
        assert!(events[1].contains("\"field\":\"anchor\""), "{events:?}");
        // nothing usable: an error, not an empty run
        let err = input.finish().unwrap_err().to_string();
        assert!(err.contains("none of its records"), "{err}");
    }

    #[test]
    fn strict_a_read_error_and_a_foreign_file_stop_the_run() {
        let text = format!("{GOOD}\nnot json\n");
        let mut strict = records(&text, true);
        assert!(strict.next_record().unwrap().is_some());
        assert!(strict.next_record().is_err());
        let mut read = Malformed::default();
        let error = EngineError::Read {
            file: "in.jsonl".into(),
            line: 9,
            reason: "disk".into(),
        };
        assert!(read.skip(error).is_err());
        // a file of garbage is given up after GIVE_UP_AFTER lines, not read to its end
        let garbage = "x\n".repeat(GIVE_UP_AFTER + 5);
        let err = records(&garbage, false).next_record().unwrap_err();
        assert!(
            format!("{err:#}").contains(&format!("in.jsonl:{GIVE_UP_AFTER}:")),
            "{err:#}"
        );
        // with a good record before them, malformed records never stop it
        let mixed = format!("{GOOD}\n{garbage}");
        let mut input = records(&mixed, false);
        while input.next_record().unwrap().is_some() {}
        assert_eq!(input.take_events().len(), GIVE_UP_AFTER + 5);
    }
}
