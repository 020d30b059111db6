//! The caller's watermark ([`Tracker::set_watermark`], the `clock` module): a sender whose
//! records arrive late is not coasted and rewound by the other senders' newer records, the
//! tracks are those of the records in order, and the ticks never lag the newest record by
//! more than the rewind horizon.

use super::tests_rewind::{assert_same_final_revisions, rewinding, run, three_walkers};
use super::*;

/// How late the slow sender's records (tag `w3`'s) arrive, s: more than the site's output
/// interval (1 s), so its track would coast in the meantime.
const SLOW_SENDER_DELAY_S: f64 = 1.5;

/// The walkers' records in arrival order, each with its arrival time: `w3`'s arrive
/// [`SLOW_SENDER_DELAY_S`] after their time, the others' at it.
fn arriving(seconds: f64) -> Vec<(f64, Record)> {
    let mut arriving: Vec<(f64, Record)> = three_walkers(seconds, 13)
        .into_iter()
        .map(|r| {
            let delay_s = if &*r.tag == "w3" { SLOW_SENDER_DELAY_S } else { 0.0 };
            (r.time_s + delay_s, r)
        })
        .collect();
    // stable: one arrival time keeps the records' order
    arriving.sort_by(|a, b| a.0.total_cmp(&b.0));
    arriving
}

fn run_arriving(mut tracker: Tracker, arriving: Vec<(f64, Record)>, with_watermark: bool) -> Output {
    let mut out = Output::default();
    for (arrival_s, record) in arriving {
        if with_watermark {
            // the caller knows its slowest sender's delay
            tracker.set_watermark(Some(arrival_s - SLOW_SENDER_DELAY_S));
        }
        tracker.push(record, &mut out).unwrap();
    }
    tracker.finish(&mut out).unwrap();
    out
}

fn count(out: &Output, tag: &str, which: impl Fn(&TrackUpdate) -> bool) -> usize {
    out.updates.iter().filter(|u| &*u.tag == tag && which(u)).count()
}

#[test]
fn a_slow_sender_is_neither_coasted_nor_rewound_under_a_watermark() {
    for pipeline in ["tightly-coupled", "fix-then-filter"] {
        let in_order = run(rewinding(pipeline), three_walkers(20.0, 13));
        // without a watermark the prompt senders' records tick w3's track into coasting
        // before each of its records arrives, and each record then rewinds it
        let driven = run_arriving(rewinding(pipeline), arriving(20.0), false);
        let coasted = count(&driven, "w3", |u| u.predicted);
        let revised = count(&driven, "w3", |u| u.revised);
        assert!(
            coasted > 10 && revised > 10,
            "{pipeline}: without a watermark w3 coasted {coasted} times, revised {revised}"
        );
        assert_same_final_revisions(&in_order, &driven, &format!("{pipeline}, without a watermark"));

        let held = run_arriving(rewinding(pipeline), arriving(20.0), true);
        for tag in ["w1", "w2", "w3"] {
            assert_eq!(
                count(&held, tag, |u| u.predicted),
                0,
                "{pipeline}: {tag} coasted under the watermark"
            );
            assert_eq!(
                count(&held, tag, |u| u.revised),
                0,
                "{pipeline}: {tag} revised under the watermark"
            );
        }
        assert_same_final_revisions(&in_order, &held, &format!("{pipeline}, with a watermark"));
    }
}

#[test]
fn ticks_held_at_the_watermark_still_reach_the_newest_record_less_the_horizon() {
    // w3 falls silent at 5 s; the watermark stays at 0 (a sender that never catches up), yet
    // the ticks run to the newest record less the 2 s horizon: w3 coasts and is lost by its
    // 5 s coast timeout, as without a watermark
    let records: Vec<Record> = three_walkers(20.0, 17)
        .into_iter()
        .filter(|r| &*r.tag != "w3" || r.time_s < 5.0)
        .collect();
    let mut tracker = rewinding("fix-then-filter");
    tracker.set_watermark(Some(0.0));
    let out = run(tracker, records);
    let lost_s: Vec<f64> = out
        .events
        .iter()
        .filter_map(|e| match e {
            Event::Lifecycle {
                tag,
                time_s,
                event: LifecycleEvent::Lost,
                ..
            } if &**tag == "w3" => Some(*time_s),
            _ => None,
        })
        .collect();
    assert_eq!(lost_s.len(), 1, "w3 lost once: {lost_s:?}");
    // silent from 4.9 s, lost once silent for more than 5 s, by ticks that lag the newest
    // record (19.9 s) by at most 2 s
    assert!((9.9..=10.5).contains(&lost_s[0]), "lost at {} s", lost_s[0]);
    assert!(count(&out, "w3", |u| u.predicted) > 0, "w3 coasted");
}
