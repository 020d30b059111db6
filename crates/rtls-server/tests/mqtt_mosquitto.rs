//! The bridge to an external broker, against a real mosquitto. Runs only when
//! `RTLS_TEST_MOSQUITTO_URL` names one (`.ci/services/mosquitto.sh` starts one and prints the
//! variable); otherwise each test says it skipped.

mod mqtt_support;

use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;
use std::time::Duration;

use bytes::Bytes;
use mqtt_support::{record_line, TestClient, TestSink};
use rtls_server::mqtt::{BridgeStatsHandle, ExternalBroker};
use rtls_server::sink::{IngestError, Publication};
use rumqttc::{MqttOptions, Packet, QoS};
use tokio::sync::{broadcast, oneshot};
use tokio::task::JoinHandle;

const SECOND: Duration = Duration::from_secs(1);

/// The broker's URL, or `None` (after saying so) when the tests should skip.
fn mosquitto_url() -> Option<String> {
    let url = std::env::var("RTLS_TEST_MOSQUITTO_URL")
        .ok()
        .filter(|url| !url.is_empty());
    if url.is_none() {
        println!("skipped: RTLS_TEST_MOSQUITTO_URL not set");
    }
    url
}

/// A name no other test (of this run or an earlier one on the same broker) uses.
fn unique(what: &str) -> String {
    static NEXT: AtomicU32 = AtomicU32::new(0);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    format!(
        "{what}-{}-{nanos}-{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    )
}

/// The bridge's URL: the broker's with the given client id.
fn bridge_url(base: &str, client_id: &str) -> String {
    let separator = if base.contains('?') { '&' } else { '?' };
    format!("{base}{separator}client_id={client_id}")
}

/// A test client of mosquitto (not the bridge).
fn client_of(base: &str, client_id: &str) -> TestClient {
    let mut options = MqttOptions::parse_url(bridge_url(base, client_id)).expect("the broker URL parses");
    options.set_keep_alive(Duration::from_secs(5));
    TestClient::start(options, false)
}

/// A running bridge.
struct RunningBridge {
    stats: BridgeStatsHandle,
    publications: broadcast::Sender<Publication>,
    stop: oneshot::Sender<()>,
    task: JoinHandle<()>,
}

impl RunningBridge {
    async fn start(url: &str, sink: TestSink, measurement_filter: &str) -> Self {
        let (publications, _) = broadcast::channel(64);
        let bridge = ExternalBroker::connect(url, Arc::new(sink), publications.clone(), measurement_filter)
            .await
            .expect("the bridge connects to mosquitto");
        let stats = bridge.stats_handle();
        let (stop, stopped) = oneshot::channel::<()>();
        let task = tokio::spawn(bridge.run(async move {
            let _ = stopped.await;
        }));
        Self {
            stats,
            publications,
            stop,
            task,
        }
    }

    async fn shutdown(self) {
        let _ = self.stop.send(());
        tokio::time::timeout(10 * SECOND, self.task)
            .await
            .expect("the bridge stops in time")
            .expect("the bridge task did not panic");
    }
}

/// Waits until `condition` holds for the bridge's counters.
async fn wait_for_stats(
    stats: &BridgeStatsHandle,
    within: Duration,
    what: &str,
    condition: impl Fn(&rtls_server::mqtt::BridgeStats) -> bool,
) {
    let deadline = tokio::time::Instant::now() + within;
    while !condition(&stats.snapshot()) {
        assert!(
            tokio::time::Instant::now() < deadline,
            "{what} within {within:?}; stats {:?}",
            stats.snapshot()
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

#[tokio::test]
async fn measurements_published_to_mosquitto_are_stored_and_acknowledged() {
    let Some(base) = mosquitto_url() else { return };
    let site = unique("site");
    let filter = format!("rtls/v1/measurements/{site}/#");
    let topic = format!("rtls/v1/measurements/{site}/reader-1");
    let bridge_id = unique("bridge");
    let sink = TestSink::new();
    let bridge = RunningBridge::start(&bridge_url(&base, &bridge_id), sink.clone(), &filter).await;

    let mut publisher = client_of(&base, &unique("publisher"));
    publisher.connected().await;
    let lines: Vec<String> = (0..5).map(|i| record_line("tag-m", f64::from(i))).collect();
    for line in &lines {
        publisher
            .client
            .publish(topic.as_str(), QoS::AtLeastOnce, false, line.clone())
            .await
            .expect("queued");
    }
    let calls = sink.wait_for_calls(5, 5 * SECOND).await;
    let payloads: Vec<Bytes> = calls.iter().map(|call| call.payload.clone()).collect();
    let expected: Vec<Bytes> = lines.iter().cloned().map(Bytes::from).collect();
    assert_eq!(payloads, expected, "every message stored once, in order, intact");
    assert!(calls
        .iter()
        .all(|call| call.source == format!("mqtt:{topic}") && call.result == Ok(1)));
    wait_for_stats(&bridge.stats, 2 * SECOND, "5 acknowledgements", |s| s.acks_sent == 5).await;
    // Give the acknowledgements time to reach the broker, then stop.
    tokio::time::sleep(Duration::from_millis(200)).await;
    bridge.shutdown().await;

    // The broker got the acknowledgements: a bridge resuming the same session gets nothing
    // redelivered.
    let resumed_sink = TestSink::new();
    let resumed = RunningBridge::start(&bridge_url(&base, &bridge_id), resumed_sink.clone(), &filter).await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert!(
        resumed_sink.calls().is_empty(),
        "acknowledged messages were delivered again"
    );
    resumed.shutdown().await;
}

#[tokio::test]
async fn messages_sent_while_the_bridge_is_down_are_stored_when_it_resumes() {
    let Some(base) = mosquitto_url() else { return };
    let site = unique("site");
    let filter = format!("rtls/v1/measurements/{site}/#");
    let bridge_id = unique("bridge");
    // Create the persistent session (and its subscription), then stop the bridge.
    RunningBridge::start(&bridge_url(&base, &bridge_id), TestSink::new(), &filter)
        .await
        .shutdown()
        .await;

    let mut publisher = client_of(&base, &unique("publisher"));
    publisher.connected().await;
    let line = record_line("tag-offline", 7.0);
    publisher
        .client
        .publish(
            format!("rtls/v1/measurements/{site}/reader-2"),
            QoS::AtLeastOnce,
            false,
            line.clone(),
        )
        .await
        .expect("queued");
    publisher
        .expect_incoming(2 * SECOND, "PUBACK from mosquitto", |p| matches!(p, Packet::PubAck(_)))
        .await;

    let sink = TestSink::new();
    let bridge = RunningBridge::start(&bridge_url(&base, &bridge_id), sink.clone(), &filter).await;
    let calls = sink.wait_for_calls(1, 5 * SECOND).await;
    assert_eq!(calls[0].payload, Bytes::from(line));
    bridge.shutdown().await;
}

#[tokio::test]
async fn publications_appear_on_mosquitto_for_a_subscriber() {
    let Some(base) = mosquitto_url() else { return };
    let site = unique("site");
    let bridge = RunningBridge::start(
        &bridge_url(&base, &unique("bridge")),
        TestSink::new(),
        &format!("rtls/v1/measurements/{site}/#"),
    )
    .await;
    let mut subscriber = client_of(&base, &unique("subscriber"));
    subscriber.connected().await;
    subscriber
        .client
        .subscribe(format!("rtls/v1/tracks/{site}/+"), QoS::AtMostOnce)
        .await
        .expect("queued");
    subscriber
        .expect_incoming(2 * SECOND, "SUBACK", |p| matches!(p, Packet::SubAck(_)))
        .await;

    for (topic, payload) in [
        (
            format!("rtls/v1/events/{site}/zone"),
            r#"{"event":"not for this subscriber"}"#,
        ),
        (
            format!("rtls/v1/tracks/{site}/tag-9"),
            r#"{"tag":"tag-9","x":1.5,"y":-2.0}"#,
        ),
    ] {
        bridge
            .publications
            .send(Publication {
                topic,
                payload: Bytes::from_static(payload.as_bytes()),
            })
            .expect("the bridge receives publications");
    }
    let (packet, _) = subscriber
        .expect_incoming(3 * SECOND, "the track", |p| matches!(p, Packet::Publish(_)))
        .await;
    let Packet::Publish(publish) = packet else {
        unreachable!()
    };
    assert_eq!(publish.topic, format!("rtls/v1/tracks/{site}/tag-9"));
    assert_eq!(
        publish.payload,
        Bytes::from_static(br#"{"tag":"tag-9","x":1.5,"y":-2.0}"#)
    );
    wait_for_stats(&bridge.stats, 2 * SECOND, "2 forwarded", |s| {
        s.publications_forwarded == 2
    })
    .await;
    bridge.shutdown().await;
}

#[tokio::test]
async fn an_unavailable_sink_leads_to_redelivery_after_the_bridge_reconnects() {
    let Some(base) = mosquitto_url() else { return };
    let site = unique("site");
    let topic = format!("rtls/v1/measurements/{site}/reader-3");
    let sink = TestSink::new();
    sink.fail_unavailable(1);
    let bridge = RunningBridge::start(
        &bridge_url(&base, &unique("bridge")),
        sink.clone(),
        &format!("rtls/v1/measurements/{site}/#"),
    )
    .await;
    let mut publisher = client_of(&base, &unique("publisher"));
    publisher.connected().await;
    let line = record_line("tag-u", 3.0);
    publisher
        .client
        .publish(topic.as_str(), QoS::AtLeastOnce, false, line.clone())
        .await
        .expect("queued");

    let calls = sink.wait_for_calls(2, 5 * SECOND).await;
    assert!(matches!(calls[0].result, Err(IngestError::Unavailable(_))));
    assert_eq!(calls[1].result, Ok(1), "the redelivered message is stored");
    assert_eq!(calls[0].payload, Bytes::from(line.clone()));
    assert_eq!(calls[1].payload, Bytes::from(line));
    wait_for_stats(&bridge.stats, 2 * SECOND, "the redelivery acknowledged", |s| {
        s.messages_unavailable == 1 && s.acks_sent == 1 && s.connections >= 2
    })
    .await;
    bridge.shutdown().await;
}

#[tokio::test]
async fn a_bad_url_or_unreachable_broker_is_an_error_naming_it() {
    // Needs no broker.
    let (publications, _) = broadcast::channel(4);
    let sink = Arc::new(TestSink::new());
    let error = ExternalBroker::connect(
        "http://user:secret@127.0.0.1:18830",
        sink.clone(),
        publications.clone(),
        "rtls/v1/measurements/#",
    )
    .await
    .expect_err("http is not an MQTT scheme");
    let message = error.to_string();
    assert!(message.contains("http://user:***@127.0.0.1:18830"), "{message}");
    assert!(!message.contains("secret"), "{message}");

    // Nothing listens on port 1 of the loopback address.
    let error = ExternalBroker::connect("mqtt://127.0.0.1:1", sink, publications, "rtls/v1/measurements/#")
        .await
        .expect_err("nothing listens there");
    assert!(
        error.to_string().contains("cannot connect to mqtt://127.0.0.1:1"),
        "{error}"
    );
}

/// The TLS listener of the test broker and its CA, or `None` (after saying so).
fn mosquitto_tls() -> Option<(String, String)> {
    let url = std::env::var("RTLS_TEST_MOSQUITTOS_URL")
        .ok()
        .filter(|url| !url.is_empty());
    let ca = std::env::var("RTLS_TEST_MOSQUITTO_CA").ok().filter(|ca| !ca.is_empty());
    if url.is_none() || ca.is_none() {
        println!("skipped: RTLS_TEST_MOSQUITTOS_URL and RTLS_TEST_MOSQUITTO_CA not set");
    }
    url.zip(ca)
}

#[tokio::test]
async fn the_bridge_speaks_tls_to_the_broker_and_refuses_one_its_ca_did_not_sign() {
    let (Some(base), Some((tls_base, ca_file))) = (mosquitto_url(), mosquitto_tls()) else {
        return;
    };
    let site = unique("site");
    let filter = format!("rtls/v1/measurements/{site}/#");
    let topic = format!("rtls/v1/measurements/{site}/reader-tls");
    let sink = TestSink::new();
    let tls_url = format!("{tls_base}?ca_file={ca_file}&client_id={}", unique("bridge-tls"));
    let bridge = RunningBridge::start(&tls_url, sink.clone(), &filter).await;

    // A reader on the broker's plain listener; the bridge reads over TLS.
    let mut publisher = client_of(&base, &unique("publisher"));
    publisher.connected().await;
    let line = record_line("tag-tls", 3.0);
    publisher
        .client
        .publish(topic.as_str(), QoS::AtLeastOnce, false, line.clone())
        .await
        .expect("queued");
    let calls = sink.wait_for_calls(1, 5 * SECOND).await;
    assert_eq!(calls[0].payload, Bytes::from(line));
    wait_for_stats(&bridge.stats, 2 * SECOND, "1 acknowledgement", |s| s.acks_sent == 1).await;
    bridge.shutdown().await;

    // A CA that did not sign the broker's certificate: the handshake fails and the bridge
    // does not start.
    let foreign = rcgen::generate_simple_self_signed(vec!["127.0.0.1".to_owned()]).expect("a certificate");
    let foreign_ca = std::env::temp_dir().join(format!("{}.pem", unique("foreign-ca")));
    std::fs::write(&foreign_ca, foreign.cert.pem()).expect("written");
    let (publications, _) = broadcast::channel(4);
    let error = ExternalBroker::connect(
        &format!("{tls_base}?ca_file={}", foreign_ca.display()),
        Arc::new(TestSink::new()),
        publications,
        &filter,
    )
    .await
    .expect_err("a broker whose certificate the CA did not sign");
    std::fs::remove_file(&foreign_ca).ok();
    assert!(error.to_string().contains("cannot connect to mqtts://"), "{error}");
}
