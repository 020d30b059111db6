//! The embedded MQTT broker against a real MQTT client (rumqttc) and raw TCP streams.

mod mqtt_support;

use std::time::Duration;

use bytes::{BufMut, Bytes, BytesMut};
use mqtt_support::{
    client_options, raw_connect, read_until_closed, record_line, test_config, TestBroker, TestClient, TestSink,
    CONNACK_ACCEPTED, READ_TOKEN, WRITE_TOKEN,
};
use rtls_server::mqtt::error_topic;
use rtls_server::sink::{IngestError, Publication};
use rumqttc::mqttbytes::v4::SubscribeReasonCode;
use rumqttc::{ConnectReturnCode, ConnectionError, Event, Outgoing, Packet, QoS};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio::time::Instant;

const SECOND: Duration = Duration::from_secs(1);

fn measurement_topic(reader: &str) -> String {
    format!("rtls/v1/measurements/{reader}")
}

fn is_puback(packet: &Packet) -> bool {
    matches!(packet, Packet::PubAck(_))
}

#[tokio::test]
async fn the_puback_leaves_only_after_the_sink_stored_the_payload() {
    let sink = TestSink::new().with_delay(Duration::from_millis(300), 0);
    let broker = TestBroker::start(test_config(), sink.clone()).await;
    let mut reader = TestClient::start(client_options(broker.addr, "reader-1", Some(WRITE_TOKEN)), false);
    reader.connected().await;

    let published_at = Instant::now();
    let line = record_line("tag-1", 1.0);
    reader
        .client
        .publish(measurement_topic("reader-1"), QoS::AtLeastOnce, false, line.clone())
        .await
        .expect("queued");
    let (_, acked_at) = reader.expect_incoming(2 * SECOND, "PUBACK", is_puback).await;

    let calls = sink.calls();
    assert_eq!(calls.len(), 1);
    assert_eq!(calls[0].source, "mqtt:rtls/v1/measurements/reader-1");
    assert_eq!(calls[0].payload, Bytes::from(line));
    assert_eq!(calls[0].result, Ok(1));
    assert!(
        calls[0].completed_at <= acked_at,
        "PUBACK seen {:?} before the sink completed",
        calls[0].completed_at - acked_at
    );
    assert!(
        acked_at - published_at >= Duration::from_millis(300),
        "PUBACK after {:?}, sooner than the sink's 300 ms",
        acked_at - published_at
    );
    let stats = broker.stats.snapshot();
    assert_eq!(
        (stats.publishes_received, stats.records_stored, stats.acks_sent),
        (1, 1, 1)
    );
}

#[tokio::test]
async fn two_hundred_qos1_messages_are_acked_once_each_in_order_with_payloads_intact() {
    // Jitter of up to 4 ms per call: later payloads often finish before earlier ones.
    let sink = TestSink::new().with_delay(Duration::ZERO, 5);
    let broker = TestBroker::start(test_config(), sink.clone()).await;
    let mut reader = TestClient::start(client_options(broker.addr, "reader-200", Some(WRITE_TOKEN)), false);
    reader.connected().await;

    let payloads: Vec<String> = (0..200)
        .map(|i| record_line(&format!("tag-{}", i % 7), f64::from(i)))
        .collect();
    let client = reader.client.clone();
    let topic = measurement_topic("reader-200");
    let to_send = payloads.clone();
    let publisher = tokio::spawn(async move {
        for payload in to_send {
            client
                .publish(topic.as_str(), QoS::AtLeastOnce, false, payload)
                .await
                .expect("queued");
        }
    });

    let mut sent_ids = Vec::new();
    let mut acked_ids = Vec::new();
    let deadline = Instant::now() + 10 * SECOND;
    while acked_ids.len() < 200 {
        match reader
            .next_event(deadline.saturating_duration_since(Instant::now()))
            .await
        {
            Some(mqtt_support::ClientEvent::Event(Event::Outgoing(Outgoing::Publish(pkid)), _)) => sent_ids.push(pkid),
            Some(mqtt_support::ClientEvent::Event(Event::Incoming(Packet::PubAck(ack)), _)) => acked_ids.push(ack.pkid),
            Some(mqtt_support::ClientEvent::Event(..)) => {}
            Some(mqtt_support::ClientEvent::Error(error, _)) => panic!("connection error {error:?}"),
            None => panic!("only {} PUBACKs within 10 s", acked_ids.len()),
        }
    }
    publisher.await.expect("publisher task");
    assert_eq!(sent_ids.len(), 200);
    assert_eq!(
        acked_ids, sent_ids,
        "every PUBLISH acknowledged once, in the order sent"
    );
    // Nothing more arrives: no duplicate acknowledgements.
    assert!(
        !matches!(
            reader.next_event(Duration::from_millis(200)).await,
            Some(mqtt_support::ClientEvent::Event(Event::Incoming(Packet::PubAck(_)), _))
        ),
        "an extra PUBACK arrived"
    );

    let mut calls = sink.calls();
    assert_eq!(calls.len(), 200);
    assert!(
        sink.max_in_flight() > 1,
        "payloads of one connection were stored one at a time"
    );
    // The sink was called in the order published (its completion order may differ).
    calls.sort_by_key(|call| {
        let value: serde_json::Value = serde_json::from_slice(&call.payload).expect("JSON payload");
        value["t"].as_f64().expect("t") as u64
    });
    let received: Vec<String> = calls
        .iter()
        .map(|call| String::from_utf8(call.payload.to_vec()).expect("UTF-8"))
        .collect();
    assert_eq!(received, payloads, "payloads intact");
    let stats = broker.stats.snapshot();
    assert_eq!((stats.publishes_received, stats.acks_sent), (200, 200));
}

#[tokio::test]
async fn payloads_of_one_connection_are_in_the_sink_at_most_max_inflight_at_once() {
    let sink = TestSink::new().with_delay(Duration::from_millis(100), 0);
    let mut config = test_config();
    config.max_inflight_per_connection = 4;
    let broker = TestBroker::start(config, sink.clone()).await;
    let mut reader = TestClient::start(client_options(broker.addr, "reader-window", Some(WRITE_TOKEN)), false);
    reader.connected().await;
    for i in 0..12 {
        reader
            .client
            .publish(
                measurement_topic("reader-window"),
                QoS::AtLeastOnce,
                false,
                record_line("t", f64::from(i)),
            )
            .await
            .expect("queued");
    }
    for _ in 0..12 {
        reader.expect_incoming(3 * SECOND, "PUBACK", is_puback).await;
    }
    assert_eq!(sink.max_in_flight(), 4, "the window of 4 is used and not exceeded");
}

#[tokio::test]
async fn a_wrong_or_missing_token_is_refused_at_connect() {
    let sink = TestSink::new();
    let broker = TestBroker::start(test_config(), sink.clone()).await;

    let mut wrong = TestClient::start(client_options(broker.addr, "intruder", Some("guess")), false);
    let (error, _) = wrong.expect_error(2 * SECOND, |_| false).await;
    assert!(
        matches!(
            error,
            ConnectionError::ConnectionRefused(ConnectReturnCode::BadUserNamePassword)
        ),
        "{error:?}"
    );
    let mut missing = TestClient::start(client_options(broker.addr, "anonymous", None), false);
    let (error, _) = missing.expect_error(2 * SECOND, |_| false).await;
    assert!(
        matches!(
            error,
            ConnectionError::ConnectionRefused(ConnectReturnCode::NotAuthorized)
        ),
        "{error:?}"
    );
    let stats = broker.stats.snapshot();
    assert_eq!((stats.connections_refused, stats.connections_open), (2, 0));
}

#[tokio::test]
async fn a_read_token_may_subscribe_but_its_publish_closes_the_connection() {
    let sink = TestSink::new();
    let broker = TestBroker::start(test_config(), sink.clone()).await;
    let mut viewer = TestClient::start(client_options(broker.addr, "viewer", Some(READ_TOKEN)), false);
    viewer.connected().await;
    viewer
        .client
        .subscribe("rtls/v1/tracks/+", QoS::AtLeastOnce)
        .await
        .expect("queued");
    let (suback, _) = viewer
        .expect_incoming(2 * SECOND, "SUBACK", |p| matches!(p, Packet::SubAck(_)))
        .await;
    let Packet::SubAck(suback) = suback else { unreachable!() };
    assert_eq!(
        suback.return_codes,
        vec![SubscribeReasonCode::Success(QoS::AtMostOnce)],
        "granted QoS 0"
    );

    viewer
        .client
        .publish(
            measurement_topic("viewer"),
            QoS::AtLeastOnce,
            false,
            record_line("t", 1.0),
        )
        .await
        .expect("queued");
    viewer.expect_error(2 * SECOND, is_puback).await;
    tokio::time::sleep(Duration::from_millis(50)).await;
    assert!(sink.calls().is_empty(), "a read-only publish reached the sink");
    assert_eq!(broker.stats.snapshot().protocol_violations, 1);
}

#[tokio::test]
async fn publishing_outside_the_prefix_or_at_qos_2_closes_the_connection() {
    let sink = TestSink::new();
    let broker = TestBroker::start(test_config(), sink.clone()).await;
    for (client_id, topic, qos) in [
        ("outside", "rtls/v1/tracks/tag-1".to_owned(), QoS::AtLeastOnce),
        ("bare-prefix", "rtls/v1/measurements/".to_owned(), QoS::AtMostOnce),
        ("qos2", measurement_topic("qos2"), QoS::ExactlyOnce),
        ("no-vendor", "rtls/v1/adapters/acme/tags".to_owned(), QoS::AtLeastOnce),
    ] {
        let mut writer = TestClient::start(client_options(broker.addr, client_id, Some(WRITE_TOKEN)), false);
        writer.connected().await;
        writer
            .client
            .publish(topic, qos, false, record_line("t", 1.0))
            .await
            .expect("queued");
        writer
            .expect_error(2 * SECOND, |p| matches!(p, Packet::PubAck(_) | Packet::PubRec(_)))
            .await;
    }
    assert!(sink.calls().is_empty());
    assert_eq!(broker.stats.snapshot().protocol_violations, 4);
}

#[tokio::test]
async fn a_vendor_topic_reaches_the_sink_and_is_acknowledged() {
    let sink = TestSink::new();
    let broker = TestBroker::start(test_config(), sink.clone()).await;
    let mut engine = TestClient::start(client_options(broker.addr, "pozyx-gateway", Some(WRITE_TOKEN)), false);
    engine.connected().await;
    let message = r#"[{"tagId": "10006789", "timestamp": 1671165464.3779979, "success": true, "data": {"coordinates": {"x": 29340, "y": 69521, "z": 1000}}}]"#;
    engine
        .client
        .publish("rtls/v1/adapters/pozyx/tags/10006789", QoS::AtLeastOnce, false, message)
        .await
        .expect("queued");
    engine.expect_incoming(2 * SECOND, "PUBACK", is_puback).await;
    let calls = sink.calls();
    assert_eq!(calls.len(), 1);
    assert_eq!(calls[0].source, "mqtt:rtls/v1/adapters/pozyx/tags/10006789");
    assert_eq!(calls[0].payload, Bytes::from(message));
}

#[tokio::test]
async fn an_invalid_payload_is_acked_and_reported_on_the_clients_own_error_topic() {
    let sink = TestSink::new();
    let broker = TestBroker::start(test_config(), sink.clone()).await;
    // Another client listening on every error topic must not hear this reader's errors.
    let mut snoop = TestClient::start(client_options(broker.addr, "snoop", Some(READ_TOKEN)), false);
    snoop.connected().await;
    snoop
        .client
        .subscribe("rtls/v1/errors/#", QoS::AtMostOnce)
        .await
        .expect("queued");
    snoop
        .expect_incoming(2 * SECOND, "SUBACK", |p| matches!(p, Packet::SubAck(_)))
        .await;

    let mut reader = TestClient::start(client_options(broker.addr, "reader-bad", Some(WRITE_TOKEN)), false);
    reader.connected().await;
    reader
        .client
        .subscribe(error_topic("reader-bad"), QoS::AtLeastOnce)
        .await
        .expect("queued");
    reader
        .expect_incoming(2 * SECOND, "SUBACK", |p| matches!(p, Packet::SubAck(_)))
        .await;
    let payload = format!("{}\nthis is not json\n", record_line("t", 1.0));
    reader
        .client
        .publish(measurement_topic("reader-bad"), QoS::AtLeastOnce, false, payload)
        .await
        .expect("queued");

    let (error, _) = reader
        .expect_incoming(2 * SECOND, "the error message", |p| matches!(p, Packet::Publish(_)))
        .await;
    reader.expect_incoming(2 * SECOND, "PUBACK", is_puback).await;
    let Packet::Publish(error) = error else { unreachable!() };
    assert_eq!(error.topic, "rtls/v1/errors/reader-bad");
    assert_eq!(error.qos, QoS::AtMostOnce);
    let body: serde_json::Value = serde_json::from_slice(&error.payload).expect("the error is JSON");
    assert_eq!(body["topic"], "rtls/v1/measurements/reader-bad");
    let message = body["error"].as_str().expect("error text");
    assert!(message.starts_with("line 2: not JSON"), "{message}");

    assert!(
        !matches!(
            snoop.next_event(Duration::from_millis(300)).await,
            Some(mqtt_support::ClientEvent::Event(Event::Incoming(Packet::Publish(_)), _))
        ),
        "another client received the reader's error"
    );
    assert!(matches!(sink.calls()[0].result, Err(IngestError::Invalid(_))));
    let stats = broker.stats.snapshot();
    assert_eq!(
        (stats.publishes_invalid, stats.acks_sent, stats.records_stored),
        (1, 1, 0)
    );
}

#[tokio::test]
async fn an_unavailable_sink_gets_no_puback_and_the_resend_after_reconnecting_is_acked() {
    let sink = TestSink::new();
    sink.fail_unavailable(1);
    let broker = TestBroker::start(test_config(), sink.clone()).await;
    let mut reader = TestClient::start(client_options(broker.addr, "reader-retry", Some(WRITE_TOKEN)), true);
    reader.connected().await;
    let line = record_line("tag-r", 42.0);
    reader
        .client
        .publish(measurement_topic("reader-retry"), QoS::AtLeastOnce, false, line.clone())
        .await
        .expect("queued");

    // No PUBACK: the connection closes.
    reader.expect_error(2 * SECOND, is_puback).await;
    // The reader reconnects and sends the unacknowledged record again (rumqttc 0.25 resends
    // its pending publishes only into a resumed session, so the test does it); the sink has
    // recovered.
    reader
        .expect_incoming(3 * SECOND, "CONNACK after reconnecting", |p| {
            matches!(p, Packet::ConnAck(_))
        })
        .await;
    reader
        .client
        .publish(measurement_topic("reader-retry"), QoS::AtLeastOnce, false, line.clone())
        .await
        .expect("queued");
    reader
        .expect_incoming(3 * SECOND, "PUBACK of the resend", is_puback)
        .await;

    let calls = sink.calls();
    assert_eq!(calls.len(), 2);
    assert!(matches!(calls[0].result, Err(IngestError::Unavailable(_))));
    assert_eq!(calls[1].result, Ok(1));
    assert_eq!(calls[0].payload, Bytes::from(line.clone()));
    assert_eq!(calls[1].payload, Bytes::from(line));
    let stats = broker.stats.snapshot();
    assert_eq!((stats.publishes_unavailable, stats.acks_sent), (1, 1));
}

#[tokio::test]
async fn wildcard_subscriptions_receive_the_matching_publications_and_no_others() {
    let broker = TestBroker::start(test_config(), TestSink::new()).await;
    let mut tracks = TestClient::start(client_options(broker.addr, "tracks", Some(READ_TOKEN)), false);
    let mut everything = TestClient::start(client_options(broker.addr, "everything", Some(READ_TOKEN)), false);
    for (client, filter) in [(&mut tracks, "rtls/v1/tracks/+"), (&mut everything, "rtls/v1/#")] {
        client.connected().await;
        client.client.subscribe(filter, QoS::AtMostOnce).await.expect("queued");
        client
            .expect_incoming(2 * SECOND, "SUBACK", |p| matches!(p, Packet::SubAck(_)))
            .await;
    }
    for topic in [
        "rtls/v1/tracks/tag-1",
        "rtls/v1/events/zone_entered",
        "rtls/v1/tracks/tag-2/history",
        "site/other",
        "rtls/v1/tracks/zz-last",
    ] {
        broker
            .publications
            .send(Publication {
                topic: topic.into(),
                payload: Bytes::from(format!("{{\"about\":\"{topic}\"}}")),
            })
            .expect("there are subscribers");
    }
    let mut received = Vec::new();
    for client in [&mut tracks, &mut everything] {
        let mut topics = Vec::new();
        while topics.last().map(String::as_str) != Some("rtls/v1/tracks/zz-last") {
            let (packet, _) = client
                .expect_incoming(2 * SECOND, "a publication", |p| matches!(p, Packet::Publish(_)))
                .await;
            let Packet::Publish(publish) = packet else {
                unreachable!()
            };
            assert_eq!(publish.qos, QoS::AtMostOnce);
            assert_eq!(
                publish.payload,
                Bytes::from(format!("{{\"about\":\"{}\"}}", publish.topic))
            );
            topics.push(publish.topic);
        }
        received.push(topics);
    }
    assert_eq!(received[0], ["rtls/v1/tracks/tag-1", "rtls/v1/tracks/zz-last"]);
    assert_eq!(
        received[1],
        [
            "rtls/v1/tracks/tag-1",
            "rtls/v1/events/zone_entered",
            "rtls/v1/tracks/tag-2/history",
            "rtls/v1/tracks/zz-last"
        ]
    );
    assert_eq!(broker.stats.snapshot().messages_delivered, 6);
}

#[tokio::test]
async fn garbage_bytes_close_that_connection_while_another_client_keeps_working() {
    let sink = TestSink::new();
    let broker = TestBroker::start(test_config(), sink.clone()).await;
    let mut reader = TestClient::start(client_options(broker.addr, "steady", Some(WRITE_TOKEN)), false);
    reader.connected().await;

    // Garbage instead of a CONNECT.
    let mut before_connect = TcpStream::connect(broker.addr).await.expect("connects");
    before_connect.write_all(&[0xFF; 16]).await.expect("written");
    assert!(read_until_closed(&mut before_connect, 2 * SECOND).await.is_empty());

    // A valid session, then a PUBLISH whose topic length points past the packet's end.
    let mut in_session = TcpStream::connect(broker.addr).await.expect("connects");
    in_session.write_all(&raw_connect("raw-1", 30)).await.expect("written");
    let mut connack = [0u8; 4];
    in_session.read_exact(&mut connack).await.expect("CONNACK");
    assert_eq!(connack, CONNACK_ACCEPTED);
    in_session
        .write_all(&[0x30, 0x05, 0xFF, 0xFF, b'a', b'b', b'c'])
        .await
        .expect("written");
    assert!(read_until_closed(&mut in_session, 2 * SECOND).await.is_empty());

    reader
        .client
        .publish(
            measurement_topic("steady"),
            QoS::AtLeastOnce,
            false,
            record_line("t", 1.0),
        )
        .await
        .expect("queued");
    reader.expect_incoming(2 * SECOND, "PUBACK", is_puback).await;
    assert_eq!(sink.calls().len(), 1);
    assert_eq!(broker.stats.snapshot().protocol_violations, 2);
}

#[tokio::test]
async fn an_oversize_packet_closes_the_connection() {
    let sink = TestSink::new();
    let mut config = test_config();
    config.max_packet_bytes = 1024;
    let broker = TestBroker::start(config, sink.clone()).await;
    let mut reader = TestClient::start(client_options(broker.addr, "big", Some(WRITE_TOKEN)), false);
    reader.connected().await;
    let big = format!("{}\n{}", record_line("t", 1.0), " ".repeat(4096));
    reader
        .client
        .publish(measurement_topic("big"), QoS::AtLeastOnce, false, big)
        .await
        .expect("queued");
    reader.expect_error(2 * SECOND, is_puback).await;
    assert!(sink.calls().is_empty());
    assert_eq!(broker.stats.snapshot().protocol_violations, 1);
}

#[tokio::test]
async fn an_mqtt_5_connect_is_refused_with_unacceptable_protocol_version() {
    let broker = TestBroker::start(test_config(), TestSink::new()).await;
    let mut stream = TcpStream::connect(broker.addr).await.expect("connects");
    let mut connect = raw_connect("v5", 30);
    // Protocol level: after the fixed header (2 bytes) and the name "MQTT" (6 bytes).
    assert_eq!(&connect[2..9], &[0, 4, b'M', b'Q', b'T', b'T', 4]);
    connect[8] = 5;
    stream.write_all(&connect).await.expect("written");
    let answer = read_until_closed(&mut stream, 2 * SECOND).await;
    assert_eq!(
        answer,
        [0x20, 0x02, 0x00, 0x01],
        "CONNACK 'unacceptable protocol version'"
    );
    assert_eq!(broker.stats.snapshot().connections_refused, 1);
}

#[tokio::test]
async fn a_client_silent_for_one_and_a_half_keep_alives_is_disconnected() {
    let broker = TestBroker::start(test_config(), TestSink::new()).await;
    let mut stream = TcpStream::connect(broker.addr).await.expect("connects");
    stream.write_all(&raw_connect("sleepy", 1)).await.expect("written");
    let connected_at = Instant::now();
    let mut connack = [0u8; 4];
    stream.read_exact(&mut connack).await.expect("CONNACK");
    assert_eq!(connack, CONNACK_ACCEPTED);
    // A PINGREQ half-way keeps it alive; silence after it does not.
    tokio::time::sleep(Duration::from_millis(700)).await;
    let mut ping = BytesMut::new();
    ping.put_slice(&[0xC0, 0x00]);
    stream.write_all(&ping).await.expect("written");
    let answer = read_until_closed(&mut stream, 4 * SECOND).await;
    let elapsed = connected_at.elapsed();
    assert_eq!(answer, [0xD0, 0x00], "PINGRESP, then the close");
    assert!(
        elapsed >= Duration::from_millis(700 + 1400),
        "closed after {elapsed:?}, before 1.5 × keep-alive after the ping"
    );
    assert!(
        elapsed < Duration::from_millis(700 + 2500),
        "closed only after {elapsed:?}"
    );
}

#[tokio::test]
async fn a_connection_over_the_limit_is_refused_with_server_unavailable() {
    let mut config = test_config();
    config.max_connections = 1;
    let broker = TestBroker::start(config, TestSink::new()).await;
    let mut first = TestClient::start(client_options(broker.addr, "first", Some(WRITE_TOKEN)), false);
    first.connected().await;
    let mut second = TestClient::start(client_options(broker.addr, "second", Some(WRITE_TOKEN)), false);
    let (error, _) = second.expect_error(3 * SECOND, |_| false).await;
    assert!(
        matches!(
            error,
            ConnectionError::ConnectionRefused(ConnectReturnCode::ServiceUnavailable)
        ),
        "{error:?}"
    );
    let stats = broker.stats.snapshot();
    assert_eq!((stats.connections_open, stats.connections_refused), (1, 1));
}

#[tokio::test]
async fn a_second_connection_with_the_same_client_id_takes_over() {
    let broker = TestBroker::start(test_config(), TestSink::new()).await;
    let mut first = TestClient::start(client_options(broker.addr, "twin", Some(WRITE_TOKEN)), false);
    first.connected().await;
    let mut second = TestClient::start(client_options(broker.addr, "twin", Some(WRITE_TOKEN)), false);
    second.connected().await;
    first.expect_error(2 * SECOND, |_| false).await;
    // The survivor still works.
    second
        .client
        .subscribe("rtls/v1/#", QoS::AtMostOnce)
        .await
        .expect("queued");
    second
        .expect_incoming(2 * SECOND, "SUBACK", |p| matches!(p, Packet::SubAck(_)))
        .await;
    assert_eq!(broker.stats.snapshot().connections_open, 1);
}

#[tokio::test]
async fn shutdown_acknowledges_what_the_sink_holds_then_closes_and_returns() {
    let sink = TestSink::new().with_delay(Duration::from_millis(300), 0);
    let broker = TestBroker::start(test_config(), sink.clone()).await;
    let mut reader = TestClient::start(client_options(broker.addr, "last-words", Some(WRITE_TOKEN)), false);
    reader.connected().await;
    reader
        .client
        .publish(
            measurement_topic("last-words"),
            QoS::AtLeastOnce,
            false,
            record_line("t", 1.0),
        )
        .await
        .expect("queued");
    // Shut down while the payload is in the sink.
    tokio::time::sleep(Duration::from_millis(100)).await;
    let stats = broker.stats.clone();
    broker.shutdown(3 * SECOND).await;
    reader
        .expect_incoming(SECOND, "PUBACK before the close", is_puback)
        .await;
    reader.expect_error(SECOND, |_| false).await;
    assert_eq!(sink.calls().len(), 1);
    assert_eq!(stats.snapshot().connections_open, 0);
}
