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
use rtls_server::pipeline::{ClockLag, PipelineConfig};
use rtls_server::sink::{IngestOrder, MeasurementSink};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn payloads_of_one_sender_are_logged_in_arrival_order_whatever_the_polling_order() {
    let state = state("ingest-order");
    let sink: &dyn MeasurementSink = &state.pipeline;
    let mut order = IngestOrder::default();
    let payloads = 40;
    let futures: Vec<_> = (0..payloads)
        .map(|k| {
            let line = fix_line("T1", 100.0 + 0.1 * k as f64, 1.0);
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

/// The wall clock, Unix seconds.
fn unix_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
}

/// A fix of `tag` at time `t_s` at `(x_m, 2)` m, σ = 0.2 m: one measurement line.
fn fix_line(tag: &str, t_s: f64, x_m: f64) -> String {
    format!(
        r#"{{"t": {t_s}, "tag": "{tag}", "kind": "fix", "position_m": [{x_m}, 2.0], "covariance_m2": [0.04, 0.0, 0.0, 0.04]}}"#
    )
}

/// One partition, advanced by the wall clock with `clock_lag`.
fn live_pipeline(clock_lag: ClockLag) -> PipelineConfig {
    PipelineConfig {
        partitions: 1,
        live_clock: true,
        clock_lag,
        ..PipelineConfig::default()
    }
}

/// Records of tag `tag` sent one every `period`, each `delay_s` after its time, to a live
/// pipeline whose clock lags the wall by 0.5 s (the test site re-filters nothing): how many
/// were reported late. The tag must be tracked.
async fn late_deliveries(name: &str, tag: &str, count: usize, period: Duration, delay_s: f64) -> f64 {
    let state = state_on(name, live_pipeline(ClockLag::Fixed(0.5)));
    let app = rtls_server::http::router(state.clone());
    for k in 0..count {
        let line = fix_line(tag, unix_s() - delay_s, 1.0 + 0.02 * k as f64);
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

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_prompt_tag_falling_silent_coasts_a_measured_lag_after_its_output_interval_not_two_seconds() {
    // records delivered at once: the measured lag (`pipeline/clock_lag.rs`) is ~0.1 s, so
    // the tag's first coasting output (the site's output interval, 1 s, after its last
    // record) comes ~1.1–1.4 s after it; the former fixed lag of 2 s made it 3 s
    let state = state_on("ingest-measured-lag", live_pipeline(ClockLag::Auto));
    assert_eq!(PipelineConfig::default().clock_lag, ClockLag::Auto);
    let app = rtls_server::http::router(state.clone());
    let mut last_sent = std::time::Instant::now();
    for k in 0..15 {
        let line = fix_line("S1", unix_s(), 1.0 + 0.1 * k as f64);
        assert_eq!(state.pipeline.submit_lines("http", line.as_bytes()).await, Ok(1));
        last_sent = std::time::Instant::now();
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let live = state.pipeline.live().clone();
    assert!(
        eventually(Duration::from_secs(10), || live
            .tag("S1")
            .is_some_and(|tag| tag.status == "coasting"))
        .await,
        "S1 never coasted"
    );
    let coasted_after_s = last_sent.elapsed().as_secs_f64();
    let metrics = call(&app, Method::GET, "/metrics", Some(READ), "").await.text();
    state.pipeline.shutdown();
    assert!(
        coasted_after_s < 2.5,
        "the first coasting output came {coasted_after_s:.2} s after the last record"
    );
    let count = metric_value(&metrics, "rtls_live_clock_lag_seconds_count");
    let sum = metric_value(&metrics, "rtls_live_clock_lag_seconds_sum");
    assert!(count > 0.0, "the live clock never moved");
    assert!(sum / count < 0.5, "mean live-clock lag {} s", sum / count);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_sender_behind_the_others_is_neither_coasted_nor_revised() {
    // two gateways into one partition of a site that re-filters within 2 s and reports every
    // 0.5 s: one delivers each record at once, the other 1.2 s after its time. Ticks driven by
    // the prompt gateway's records would coast the slow one's tag, and each of its records
    // would then rewind its track and publish its updates again as revisions; the partition's
    // watermark (`pipeline/watermark.rs`) holds the ticks for the slow gateway instead
    let site_text = common::SITE.replace(
        "reorder_window_s = 0.2",
        "reorder_window_s = 0.0\nrewind_horizon_s = 2.0\noutput_interval_s = 0.5",
    );
    let site = rtls_engine::site::Site::from_toml_str(&site_text, "watermark-site.toml").expect("site");
    let state = common::state_on_site("ingest-watermark", site, live_pipeline(ClockLag::Auto));
    let app = rtls_server::http::router(state.clone());
    let delay_s = 1.2;
    let start_s = unix_s();
    for k in 0..50 {
        let now_s = unix_s();
        let x = 1.0 + 0.05 * f64::from(k);
        let prompt = fix_line("PROMPT", now_s, x);
        assert_eq!(state.pipeline.submit_lines("fast", prompt.as_bytes()).await, Ok(1));
        if now_s - delay_s >= start_s {
            let slow = fix_line("SLOW", now_s - delay_s, x);
            assert_eq!(state.pipeline.submit_lines("slow", slow.as_bytes()).await, Ok(1));
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let live = state.pipeline.live().clone();
    assert!(
        eventually(Duration::from_secs(10), || live.tag("SLOW").is_some()).await,
        "the slow gateway's tag was not tracked"
    );
    let metrics = call(&app, Method::GET, "/metrics", Some(READ), "").await.text();
    state.pipeline.shutdown();
    let updates = metric_value(&metrics, "rtls_track_updates_total");
    let revised = metric_value(&metrics, "rtls_track_updates_revised_total");
    let late = metric_value(&metrics, "rtls_records_unused_total{event=\"late\",kind=\"fix\"}");
    assert!(updates > 50.0, "{updates} track updates");
    assert_eq!(revised, 0.0, "{revised} of {updates} updates revised");
    assert_eq!(late, 0.0, "{late} records late");
}
