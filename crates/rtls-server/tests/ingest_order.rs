//! Order and time of what is tracked: one sender's payloads are queued in the order they
//! arrived however their futures are polled (`rtls_server::sink::IngestOrder`: an MQTT
//! connection keeps many payloads in flight, and a tag's records queued out of order would
//! each make its track re-filter), and the wall clock does not run ahead of a stream of
//! records that keeps coming behind it.

mod common;

use std::time::Duration;

use axum::http::Method;
use bytes::Bytes;
use common::{call, eventually, metric_value, state, state_on, READ};
use rtls_server::pipeline::PipelineConfig;
use rtls_server::sink::{IngestOrder, MeasurementSink};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn payloads_of_one_sender_are_logged_in_arrival_order_whatever_the_polling_order() {
    let state = state("ingest-order");
    let sink: &dyn MeasurementSink = &state.pipeline;
    let mut order = IngestOrder::default();
    let payloads = 40;
    let futures: Vec<_> = (0..payloads)
        .map(|k| {
            let line = format!(
                r#"{{"t": {}, "tag": "T1", "kind": "fix", "position_m": [1.0, 2.0], "covariance_m2": [0.04, 0.0, 0.0, 0.04]}}"#,
                100.0 + 0.1 * k as f64
            );
            sink.ingest("mqtt:rtls/v1/measurements/r1", Bytes::from(line), &mut order)
        })
        .collect();
    // polled last first: each would queue its payload at once, the newest first
    let results = futures_util::future::join_all(futures.into_iter().rev()).await;
    assert!(results.iter().all(|r| r == &Ok(1)), "{results:?}");
    let stored = state.query(move |s| s.records_after(0, 100)).await.unwrap();
    let times: Vec<f64> = stored.iter().map(|r| r.time_s).collect();
    assert_eq!(times.len(), payloads);
    assert!(
        times.windows(2).all(|pair| pair[0] < pair[1]),
        "logged in another order than they arrived: {times:?}"
    );
}

/// Records of tag `tag` sent one every `period`, each `delay_s` after its time, to a live
/// pipeline whose clock lags the wall by 0.5 s (the test site re-filters nothing): how many
/// were reported late. The tag must be tracked.
async fn late_deliveries(name: &str, tag: &str, count: usize, period: Duration, delay_s: f64) -> f64 {
    let state = state_on(
        name,
        PipelineConfig {
            partitions: 1,
            live_clock: true,
            clock_lag_s: 0.5,
            ..PipelineConfig::default()
        },
    );
    let app = rtls_server::http::router(state.clone());
    let unix_s = || {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_secs_f64()
    };
    for k in 0..count {
        let line = format!(
            r#"{{"t": {}, "tag": "{tag}", "kind": "fix", "position_m": [{}, 2.0], "covariance_m2": [0.04, 0.0, 0.0, 0.04]}}"#,
            unix_s() - delay_s,
            1.0 + 0.02 * k as f64
        );
        assert_eq!(state.pipeline.submit_lines("http", line.as_bytes()).await, Ok(1));
        tokio::time::sleep(period).await;
    }
    let live = state.pipeline.live().clone();
    assert!(
        eventually(Duration::from_secs(10), || live.tag(tag).is_some()).await,
        "{tag} was not tracked"
    );
    let metrics = call(&app, Method::GET, "/metrics", Some(READ), "").await.text();
    state.pipeline.shutdown();
    metric_value(&metrics, "rtls_records_unused_total{event=\"late\",kind=\"fix\"}")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn records_that_keep_coming_behind_the_wall_clock_are_tracked_not_reported_late() {
    // a gateway that delivers each record 1.5 s after its time, every 50 ms: a clock
    // advanced while records keep coming would pass each one before it is tracked
    let late = late_deliveries("ingest-behind-clock", "D1", 40, Duration::from_millis(50), 1.5).await;
    assert_eq!(late, 0.0, "records reported late while the stream kept coming");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn records_delivered_late_in_bursts_are_tracked_not_overtaken_by_the_clock_between_them() {
    // the same gateway every 400 ms: between two records the partition is idle long enough
    // to move its clock, and a clock at the wall clock minus the lag would pass the next
    // record before it came (the 6 000-tag soak: every record reported late after the first
    // minute); the clock follows the records' own time instead (`pipeline/event_clock.rs`)
    let late = late_deliveries("ingest-late-bursts", "B1", 12, Duration::from_millis(400), 1.5).await;
    assert_eq!(late, 0.0, "records reported late between bursts");
}
