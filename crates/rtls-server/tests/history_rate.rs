//! `server.history_interval_s` through the pipeline: with an interval a tag's stored track
//! states are that far apart (its status changes kept), while the live outputs count every
//! update; without one every update is stored.

mod common;

use std::sync::Arc;

use rtls_server::metrics::Metrics;
use rtls_server::pipeline::{Pipeline, PipelineConfig};
use rtls_server::store::{HistoryQuery, LocationRow};

use common::{db_path, open_sqlite, site, temp_dir, walk};

/// The rows stored and the track updates published for a 10 s walk (a fix every 0.5 s) at
/// `interval_s`.
async fn stored_and_published(name: &str, interval_s: f64) -> (Vec<LocationRow>, u64) {
    temp_dir(name);
    let path = db_path(name);
    let metrics = Arc::new(Metrics::new());
    let config = PipelineConfig {
        partitions: 1,
        live_clock: false,
        history_interval_s: interval_s,
        ..PipelineConfig::default()
    };
    let pipeline = Pipeline::start(
        &site(),
        open_sqlite(&path),
        open_sqlite(&path),
        config,
        Arc::clone(&metrics),
    )
    .expect("pipeline");
    pipeline
        .submit_lines("test", walk("walker", 1_000.0, 10.0).as_bytes())
        .await
        .expect("stored");
    pipeline.shutdown();
    let rows = open_sqlite(&path)
        .history(&HistoryQuery {
            tag: Some("walker".into()),
            from_s: 0.0,
            to_s: 1e12,
            limit: 10_000,
        })
        .expect("history");
    (rows, metrics.track_updates.get())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_interval_thins_the_stored_history_not_the_live_outputs() {
    let (every, published_every) = stored_and_published("history-rate-0", 0.0).await;
    let (thinned, published_thinned) = stored_and_published("history-rate-1", 1.0).await;
    assert_eq!(published_every, published_thinned, "live outputs see every update");
    assert_eq!(every.len() as u64, published_every, "interval 0 stores every update");
    assert!(
        thinned.len() * 3 < every.len() * 2,
        "{} of {} states stored at 1 s",
        thinned.len(),
        every.len()
    );
    // states of one kind (measured, same accuracy class) are at least 1 s apart
    let measured: Vec<f64> = thinned
        .iter()
        .filter(|row| !row.predicted)
        .map(|row| row.time_s)
        .collect();
    assert!(measured.len() >= 8, "{measured:?}");
    let close = measured
        .windows(2)
        .filter(|pair| pair[1] - pair[0] < 1.0 - 1e-6)
        .count();
    // (a change of status, tentative → confirmed, is stored whatever the interval)
    assert!(close <= 1, "measured states closer than 1 s: {measured:?}");
}
