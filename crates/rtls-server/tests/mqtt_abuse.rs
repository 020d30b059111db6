//! The embedded broker under the lockout attacks of issue 22: idle sockets that never send
//! CONNECT, a flood of token-less subscribers, a wrong password, a client reusing a reader's
//! client id. Attackers connect from other loopback addresses (127.0.0.2, 127.0.0.3) than the
//! real reader (127.0.0.1), as hosts on a site network would.

mod mqtt_support;

use std::net::SocketAddr;
use std::time::Duration;

use mqtt_support::{
    client_options, raw_connect, read_until_closed, record_line, test_config, TestBroker, TestClient, TestSink,
    CONNACK_ACCEPTED, WRITE_TOKEN,
};
use rtls_server::auth::Tokens;
use rumqttc::mqttbytes::v4::Connect;
use rumqttc::{ConnectReturnCode, ConnectionError, Packet, QoS};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpSocket, TcpStream};

const SECOND: Duration = Duration::from_secs(1);

/// A TCP connection to `broker` from the loopback address `source` (e.g. 127.0.0.2).
async fn connect_from(source: &str, broker: SocketAddr) -> std::io::Result<TcpStream> {
    let socket = TcpSocket::new_v4()?;
    socket.bind(format!("{source}:0").parse().expect("address"))?;
    socket.connect(broker).await
}

/// A real reader from 127.0.0.1 connects with the write token and gets its QoS 1 PUBACK.
async fn a_reader_still_publishes(broker: &TestBroker, client_id: &str) {
    let mut reader = TestClient::start(client_options(broker.addr, client_id, Some(WRITE_TOKEN)), false);
    reader.connected().await;
    reader
        .client
        .publish(
            format!("rtls/v1/measurements/{client_id}"),
            QoS::AtLeastOnce,
            false,
            record_line("t1", 1.0),
        )
        .await
        .expect("queued");
    reader
        .expect_incoming(2 * SECOND, "PUBACK", |p| matches!(p, Packet::PubAck(_)))
        .await;
}

/// The bytes of a token-less CONNECT.
fn anonymous_connect(client_id: &str) -> bytes::BytesMut {
    let mut bytes = bytes::BytesMut::new();
    Connect::new(client_id).write(&mut bytes).expect("encodable CONNECT");
    bytes
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn idle_sockets_that_never_connect_cannot_lock_a_reader_out() {
    let mut config = test_config();
    config.max_connections = 8;
    config.max_connections_per_ip = 16;
    config.max_pending_connects = 32;
    let broker = TestBroker::start(config, TestSink::new()).await;
    // 200 idle sockets from one host: 16 wait for their CONNECT, the rest are refused
    let mut idle = Vec::new();
    for _ in 0..200 {
        if let Ok(stream) = connect_from("127.0.0.2", broker.addr).await {
            idle.push(stream);
        }
    }
    tokio::time::sleep(Duration::from_millis(200)).await;
    // more idle sockets than sessions: none of them holds a session slot
    a_reader_still_publishes(&broker, "reader-1").await;
    let stats = broker.stats.snapshot();
    assert!(stats.connections_refused >= 150, "{stats:?}");
    assert!(stats.connections_open <= 1, "idle sockets hold no session: {stats:?}");
    drop(idle);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flood_of_tokenless_subscribers_leaves_room_for_readers() {
    let mut config = test_config();
    // reads open: anyone may subscribe without a token
    config.tokens = Tokens::new(WRITE_TOKEN, None);
    config.max_connections = 20;
    config.max_read_connections = 10;
    let broker = TestBroker::start(config, TestSink::new()).await;
    let mut accepted = 0;
    let mut refused = 0;
    let mut held = Vec::new();
    for k in 0..30 {
        let mut stream = connect_from("127.0.0.3", broker.addr).await.expect("connects");
        stream
            .write_all(&anonymous_connect(&format!("lurker-{k}")))
            .await
            .expect("sends CONNECT");
        let mut connack = [0u8; 4];
        tokio::time::timeout(2 * SECOND, stream.read_exact(&mut connack))
            .await
            .expect("CONNACK in time")
            .expect("CONNACK");
        match connack[3] {
            0 => accepted += 1,
            3 => refused += 1, // server unavailable
            code => panic!("unexpected CONNACK code {code}"),
        }
        held.push(stream);
    }
    assert_eq!((accepted, refused), (10, 20), "read-only sessions are capped");
    a_reader_still_publishes(&broker, "reader-2").await;
    drop(held);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_wrong_password_is_refused_even_when_reads_are_open() {
    let mut config = test_config();
    config.tokens = Tokens::new(WRITE_TOKEN, None);
    let broker = TestBroker::start(config, TestSink::new()).await;
    let mut guess = TestClient::start(client_options(broker.addr, "guesser", Some("guess")), false);
    let (error, _) = guess.expect_error(2 * SECOND, |_| false).await;
    assert!(
        matches!(
            error,
            ConnectionError::ConnectionRefused(ConnectReturnCode::BadUserNamePassword)
        ),
        "{error:?}"
    );
    // no password still reads
    let mut anonymous = TestClient::start(client_options(broker.addr, "viewer", None), false);
    anonymous.connected().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_reusing_a_readers_id_without_its_token_cannot_take_over() {
    let mut config = test_config();
    config.tokens = Tokens::new(WRITE_TOKEN, None);
    let broker = TestBroker::start(config, TestSink::new()).await;
    let mut reader = TestClient::start(client_options(broker.addr, "gateway-7", Some(WRITE_TOKEN)), false);
    reader.connected().await;
    // the same id without the write token: identifier rejected, the reader stays connected
    let mut stream = connect_from("127.0.0.2", broker.addr).await.expect("connects");
    stream
        .write_all(&anonymous_connect("gateway-7"))
        .await
        .expect("CONNECT");
    let answer = read_until_closed(&mut stream, 2 * SECOND).await;
    assert_eq!(answer, [0x20, 0x02, 0x00, 0x02], "CONNACK identifier rejected");
    reader
        .client
        .publish(
            "rtls/v1/measurements/gateway-7",
            QoS::AtLeastOnce,
            false,
            record_line("t1", 1.0),
        )
        .await
        .expect("queued");
    reader
        .expect_incoming(2 * SECOND, "PUBACK on the original session", |p| {
            matches!(p, Packet::PubAck(_))
        })
        .await;
    // with the write token, the same id takes over as before
    let mut twin = TcpStream::connect(broker.addr).await.expect("connects");
    twin.write_all(&raw_connect("gateway-7", 30)).await.expect("CONNECT");
    let mut connack = [0u8; 4];
    twin.read_exact(&mut connack).await.expect("CONNACK");
    assert_eq!(connack, CONNACK_ACCEPTED);
    reader.expect_error(2 * SECOND, |_| false).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_topic_with_nul_or_an_endless_reader_name_closes_the_connection() {
    let sink = TestSink::new();
    let broker = TestBroker::start(test_config(), sink.clone()).await;
    let long = format!("rtls/v1/measurements/{}", "r".repeat(300));
    for topic in ["rtls/v1/measurements/gate\0way", long.as_str()] {
        let mut stream = TcpStream::connect(broker.addr).await.expect("connects");
        stream.write_all(&raw_connect("nul-writer", 30)).await.expect("CONNECT");
        let mut connack = [0u8; 4];
        stream.read_exact(&mut connack).await.expect("CONNACK");
        assert_eq!(connack, CONNACK_ACCEPTED);
        let mut publish = bytes::BytesMut::new();
        let mut packet = rumqttc::mqttbytes::v4::Publish::new(topic, QoS::AtLeastOnce, record_line("t1", 1.0));
        packet.pkid = 1;
        packet.write(&mut publish).expect("encodable PUBLISH");
        stream.write_all(&publish).await.expect("PUBLISH");
        let answer = read_until_closed(&mut stream, 2 * SECOND).await;
        assert!(answer.is_empty(), "no PUBACK for {topic:?}: {answer:?}");
    }
    assert!(sink.calls().is_empty(), "nothing reached the sink");
}
