//! `rtls track`'s run summary: what a run produced and refused, by tag and by reason, the range
//! offsets the tracks learnt, and the tags that had records but no track (exit status
//! [`super::EXIT_UNTRACKED`]).

use std::collections::BTreeMap;

use rtls_engine::tracker::{Event, ANONYMOUS_TAG};

/// The run finished, but tags with records got no track output (exit status
/// [`super::EXIT_UNTRACKED`]).
#[derive(Debug)]
pub struct UntrackedTags(pub usize);

impl std::fmt::Display for UntrackedTags {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} tag(s) had records but no track output (listed above)", self.0)
    }
}

impl std::error::Error for UntrackedTags {}

/// Rejected (or late) records by `(kind, reason category)`.
pub(super) type Rejections = BTreeMap<(&'static str, String), usize>;

/// What a run produced, for the summary.
#[derive(Debug, Default)]
pub(super) struct Counts {
    pub(super) records: usize,
    pub(super) updates: usize,
    pub(super) predicted: usize,
    pub(super) fixes: usize,
    pub(super) events: BTreeMap<&'static str, usize>,
    pub(super) rejected: Rejections,
    pub(super) tags: BTreeMap<String, TagCounts>,
    /// Tags whose gated-out fixes kept returning to one other place (`alternating`), with it.
    pub(super) alternating: BTreeMap<String, [f64; 3]>,
}

/// One tag's records, track updates and rejected or late records.
#[derive(Debug, Default)]
pub(super) struct TagCounts {
    pub(super) records: usize,
    pub(super) updates: usize,
    pub(super) rejected: Rejections,
}

/// A reason without its numbers (each run of digits, with its decimal point, becomes `#`) and
/// without the detail after its first `: `, so that reasons of one cause count together:
/// `outside the χ²(2) validation gate: NIS 14.1 > 13.8` → `outside the χ²(#) validation gate`.
pub(super) fn reason_category(reason: &str) -> String {
    let head = reason.split(": ").next().unwrap_or(reason);
    let mut category = String::with_capacity(head.len());
    let mut in_number = false;
    for c in head.chars() {
        let numeric = c.is_ascii_digit() || (in_number && c == '.');
        if numeric && !in_number {
            category.push('#');
        } else if !numeric {
            category.push(c);
        }
        in_number = numeric;
    }
    category
}

/// `count kind: category` items, most frequent first.
pub(super) fn rejections_line(rejected: &Rejections) -> String {
    let mut items: Vec<(&(&'static str, String), &usize)> = rejected.iter().collect();
    items.sort_by(|a, b| b.1.cmp(a.1).then_with(|| a.0.cmp(b.0)));
    items
        .iter()
        .map(|((kind, category), count)| format!("{count} {kind}: {category}"))
        .collect::<Vec<_>>()
        .join("; ")
}

pub(super) fn event_type(event: &Event) -> &'static str {
    match event {
        Event::Zone(_) => "zone",
        Event::Lifecycle { .. } => "lifecycle",
        Event::HazardPredicted { .. } => "hazard-predicted",
        Event::HazardCleared { .. } => "hazard-cleared",
        Event::NoCoverage { .. } => "no-coverage",
        Event::ModelSwitch { .. } => "model-switch",
        Event::Schedule { .. } => "schedule",
        Event::Late { .. } => "late",
        Event::Rejected { .. } => "rejected",
    }
}

/// The range offsets the tracks learnt (`[tracker.range_bias]`), per anchor: `A1 +0.123 ± 0.010 m`
/// when one tag learnt it, `A1 +0.123 m over 12 tags (+0.05…+0.20), ± 0.010 m` when several
/// did (one line, whatever the number of tags).
pub(super) fn range_offsets_line(offsets: &[rtls_engine::tracker::RangeOffset]) -> String {
    let anchors: Vec<String> = rtls_engine::tracker::AnchorOffsetSummary::by_anchor(offsets)
        .iter()
        .map(|s| match s.tags {
            1 => format!("{} {:+.3} ± {:.3} m", s.anchor, s.mean_m, s.mean_std_m),
            n => format!(
                "{} {:+.3} m over {n} tags ({:+.3}…{:+.3}), ± {:.3} m",
                s.anchor, s.mean_m, s.min_m, s.max_m, s.mean_std_m
            ),
        })
        .collect();
    format!(
        "range offsets learnt (beyond the site's bias_m): {}",
        anchors.join(", ")
    )
}

/// Names every tag that had records but no track output, with its rejected and late records
/// by reason. Anonymous detections (tag `*`) are tracked under ids of their own and are not
/// checked.
///
/// # Errors
/// [`UntrackedTags`] when there is such a tag.
pub(super) fn untracked_tags(counts: &Counts) -> anyhow::Result<()> {
    let untracked: Vec<(&String, &TagCounts)> = counts
        .tags
        .iter()
        .filter(|(tag, c)| tag.as_str() != ANONYMOUS_TAG && c.records > 0 && c.updates == 0)
        .collect();
    if untracked.is_empty() {
        return Ok(());
    }
    for (tag, c) in &untracked {
        let rejected = if c.rejected.is_empty() {
            "none rejected".to_string()
        } else {
            format!("rejected {}", rejections_line(&c.rejected))
        };
        eprintln!("no track for tag {tag}: {} records, {rejected}", c.records);
    }
    Err(UntrackedTags(untracked.len()).into())
}
