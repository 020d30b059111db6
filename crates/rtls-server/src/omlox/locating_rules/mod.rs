//! A trackable's `locating_rules` (`#/components/schemas/RuleSet`): which of its providers'
//! locations the trackable takes.
//!
//! # The expression language
//! The spec gives the properties (accuracy, provider_id, type, source, floor, speed,
//! timestamp_diff) and one example (`type = 'uwb' AND accuracy < 5`); the rest is ours:
//!
//! ```text
//! expression := or
//! or         := and ( OR and )*
//! and        := not ( AND not )*
//! not        := NOT not | '(' or ')' | comparison
//! comparison := property op literal
//! op         := = | == | != | <> | < | <= | > | >=
//! literal    := number | 'text' | "text"        (a quote inside doubled: 'o''clock')
//! ```
//!
//! `AND` binds tighter than `OR`; `NOT` applies to what follows it (a comparison or a
//! parenthesised expression). Keywords and property names are case-insensitive; text
//! comparisons are exact. Numbers are decimal (`-1`, `0.5`, `1e3`).
//!
//! | property | the location's | compared with |
//! | --- | --- | --- |
//! | `accuracy` | `accuracy`, m | a number |
//! | `floor` | `floor` | a number |
//! | `speed` | `speed`, m/s | a number |
//! | `timestamp_diff` | age, ms: the evaluation time minus the location's time | a number |
//! | `provider_id` | `provider_id` | text, `=` / `!=` |
//! | `source` | `source` | text, `=` / `!=` |
//! | `type` | `provider_type` | one of the spec's provider types (`uwb`, `gps`, `wifi`, `rfid`, `ibeacon`, `virtual`, `unknown`), `=` / `!=` |
//!
//! A rule that does not parse, compares a number property with text (or the reverse), orders
//! text (`<` on `source`) or names a provider type the spec does not have is refused when the
//! trackable is written ([`RuleSet::compile`]), with the character position of the fault.
//!
//! A comparison of a property the location does not carry (`accuracy`, `floor` or `speed`
//! absent) is false, so `NOT accuracy > 5` holds for a location without an accuracy; write
//! `accuracy <= 5` to require one.
//!
//! # The evaluation time (`timestamp_diff`)
//! The records' clock, not the server's: a trackable's candidates are judged at the time of
//! the newest of them (the update being published, live). So the trackable's location read
//! over REST is the one its last motion carried, a replay (`--data-clock`) judges as live did,
//! and a rule such as `timestamp_diff < 2000` drops a provider that has fallen two seconds
//! behind the trackable's other providers. A trackable all of whose providers fell silent keeps
//! the location it had (as a provider keeps its latest location).
//!
//! # Selection
//! [`RuleSet::select`]: each candidate (the latest location of each of the trackable's
//! providers) scores the highest priority among the rules it matches; the highest score wins,
//! ties going to the most recent location, then the best (smallest) accuracy, then the
//! earlier candidate. A candidate matching no rule is never taken: with rules, a trackable
//! whose providers all fail them has no location. An empty rule set selects as the hub does
//! without rules (see [`crate::pipeline::trackable_location`]).

use std::fmt;

pub use expr::{Expr, Literal, Op, ParseError, Property, Subject};

use crate::omlox::{LocatingRule, Location, Trackable};

mod expr;

/// A trackable's rules, parsed, highest priority first.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RuleSet {
    rules: Vec<(f64, Expr)>,
}

/// A rule of a rule set that does not parse: its index and the parser's error.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RuleError {
    /// Index in `locating_rules`.
    pub index: usize,
    /// The rule's expression as given.
    pub expression: String,
    /// Why.
    pub error: ParseError,
}

impl fmt::Display for RuleError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "rule `{}` does not parse {}", self.expression, self.error)
    }
}

/// A location the selection may take, and its time (s, the records' clock).
#[derive(Debug, Clone, Copy)]
pub struct Candidate<'a> {
    /// Its time, s.
    pub time_s: f64,
    /// The location.
    pub location: &'a Location,
}

impl RuleSet {
    /// Parses every rule.
    ///
    /// # Errors
    /// The first rule that does not parse.
    pub fn compile(rules: &[LocatingRule]) -> Result<Self, RuleError> {
        let mut parsed = rules
            .iter()
            .enumerate()
            .map(|(index, rule)| {
                Expr::parse(&rule.expression)
                    .map(|expr| (rule.priority, expr))
                    .map_err(|error| RuleError {
                        index,
                        expression: rule.expression.clone(),
                        error,
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        // stable: rules of equal priority keep their order
        parsed.sort_by(|a, b| b.0.total_cmp(&a.0));
        Ok(Self { rules: parsed })
    }

    /// A stored trackable's rules: those that parse (a rule set stored before rules were
    /// checked may hold others, which are logged and left out).
    #[must_use]
    pub fn of_stored(trackable: &Trackable) -> Self {
        let trackable_id = &trackable.id;
        let mut kept = Vec::new();
        for (index, rule) in trackable.locating_rules.iter().flatten().enumerate() {
            match Self::compile(std::slice::from_ref(rule)) {
                Ok(one) => kept.extend(one.rules),
                Err(e) => {
                    tracing::warn!(trackable = %trackable_id, rule = index, error = %e, "locating rule left out");
                }
            }
        }
        kept.sort_by(|a, b| b.0.total_cmp(&a.0));
        Self { rules: kept }
    }

    /// Whether there are no rules.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.rules.is_empty()
    }

    /// The highest priority among the rules `subject` matches; `None` when it matches none.
    #[must_use]
    pub fn priority(&self, subject: &Subject<'_>) -> Option<f64> {
        // highest first: the first match is the best
        self.rules
            .iter()
            .find(|(_, expr)| expr.matches(subject))
            .map(|(priority, _)| *priority)
    }

    /// The index of the candidate the trackable takes (module documentation); `None` when no
    /// candidate matches a rule, or there are none. Judged at the newest candidate's time.
    #[must_use]
    pub fn select(&self, candidates: &[Candidate<'_>]) -> Option<usize> {
        let now_s = candidates.iter().map(|c| c.time_s).fold(f64::NEG_INFINITY, f64::max);
        let mut best: Option<(usize, f64)> = None;
        for (index, candidate) in candidates.iter().enumerate() {
            let subject = Subject {
                location: candidate.location,
                age_ms: (now_s - candidate.time_s) * 1000.0,
            };
            let Some(priority) = self.priority(&subject) else {
                continue;
            };
            let better = match best {
                None => true,
                Some((held, held_priority)) => {
                    let held = &candidates[held];
                    priority
                        .total_cmp(&held_priority)
                        .then(candidate.time_s.total_cmp(&held.time_s))
                        // smaller accuracy is better; absent is worst
                        .then(
                            held.location
                                .accuracy
                                .unwrap_or(f64::INFINITY)
                                .total_cmp(&candidate.location.accuracy.unwrap_or(f64::INFINITY)),
                        )
                        .is_gt()
                }
            };
            if better {
                best = Some((index, priority));
            }
        }
        best.map(|(index, _)| index)
    }
}

#[cfg(test)]
mod tests;
