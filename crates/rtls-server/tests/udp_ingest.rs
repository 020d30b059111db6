//! UDP ingest (`[udp]`, `rtls serve --udp-listen` / `--udp-adapter`) on loopback: datagrams of
//! measurement lines and of a vendor's messages are stored and tracked; a malformed datagram
//! is counted and logged and the listener goes on.

mod common;

use std::net::SocketAddr;
use std::time::Duration;

use common::{eventually_some, get_json, loopback_config, metric_value, poll_text, temp_dir};
use rtls_server::adapters::Vendor;
use rtls_server::config::MqttMode;
use serde_json::Value;

/// The Quuppa push sample (DefaultLocation format), as in tests/adapters.rs; its `locationTS`
/// (2022) is replaced by the test's clock, since the live clock refuses records a day old.
const QUUPPA: &str = r##"{"tagId": "d10000001111", "tagName": null, "color": "#FF0000", "tagGroupName": null, "locationType": "position", "locationMovementStatus": "stationary", "locationRadius": 0.09, "location": [-1.09, 0.38, 1.0], "locationTS": 1641888440139, "locationCoordSysId": "3e7c4371-42be-4019-b7c0-ec2012d448ad", "locationCoordSysName": "CoordSys001"}"##;

fn now_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
}

/// The tag's entry in `GET /api/v1/tags`, once it is there (≤ 20 s).
async fn tracked(client: &reqwest::Client, http: SocketAddr, tag: &str) -> Option<Value> {
    eventually_some(Duration::from_secs(20), || async {
        let tags = get_json(client, http, "/api/v1/tags").await;
        tags.as_array()?.iter().find(|t| t["tag"] == tag).cloned()
    })
    .await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn datagrams_are_tracked_and_a_malformed_one_is_counted_without_stopping_the_listener() {
    let dir = temp_dir("udp-ingest");
    let mut config = loopback_config(&dir, MqttMode::Off);
    config.udp.listen = Some("127.0.0.1:0".parse().unwrap());
    config.udp.adapters.set(Vendor::Quuppa, "127.0.0.1:0".parse().unwrap());
    let running = common::serve_on_loopback(common::options(config)).await;
    let http = running.bound.http;
    let address = |wanted: Option<Vendor>| {
        running
            .bound
            .udp
            .iter()
            .find(|(vendor, _)| *vendor == wanted)
            .map(|(_, address)| *address)
            .expect("the listener is bound")
    };
    let (lines_at, quuppa_at) = (address(None), address(Some(Vendor::Quuppa)));
    let listener = format!("udp:{lines_at}");
    let client = reqwest::Client::new();
    let gateway = tokio::net::UdpSocket::bind("127.0.0.1:0").await.unwrap();

    // a malformed datagram first: refused, counted by listener and by reason
    gateway.send_to(b"{\"t\": not json", lines_at).await.unwrap();
    let refused = format!("rtls_udp_datagrams_total{{listener=\"{listener}\",outcome=\"refused\"}}");
    let metrics = poll_text(&client, http, "/metrics", |m| metric_value(m, &refused) >= 1.0).await;
    assert_eq!(metric_value(&metrics, &refused), 1.0, "{metrics}");
    assert_eq!(
        metric_value(&metrics, "rtls_ingest_refused_total{reason=\"format\"}"),
        1.0
    );

    // then a walk, one fix per datagram: the listener still takes them and the tag is tracked
    let t0 = now_s() - 3.0;
    let walk = common::walk("udp-walker", t0, 3.0);
    for line in walk.lines() {
        gateway.send_to(line.as_bytes(), lines_at).await.unwrap();
    }
    let tag = tracked(&client, http, "udp-walker")
        .await
        .expect("the walker is tracked");
    let x = tag["position_m"][0].as_f64().unwrap();
    assert!((1.5..=7.0).contains(&x), "{tag}");
    let accepted = format!("rtls_udp_datagrams_total{{listener=\"{listener}\",outcome=\"accepted\"}}");
    let lines = walk.lines().count() as f64;
    let metrics = poll_text(&client, http, "/metrics", |m| metric_value(m, &accepted) >= lines).await;
    assert_eq!(metric_value(&metrics, &accepted), lines, "{metrics}");
    assert_eq!(metric_value(&metrics, &refused), 1.0);

    // Quuppa's example through the quuppa listener, twice half a second apart, and a presence
    // message (no position): refused by reason, the datagram itself accepted
    let ms = (now_s() * 1000.0).round() as i64 - 1000;
    for message in [
        QUUPPA.replace("1641888440139", &ms.to_string()),
        QUUPPA.replace("1641888440139", &(ms + 500).to_string()),
        QUUPPA
            .replace("1641888440139", &(ms + 600).to_string())
            .replace(r#""locationType": "position""#, r#""locationType": "presence""#),
    ] {
        gateway.send_to(message.as_bytes(), quuppa_at).await.unwrap();
    }
    let tag = tracked(&client, http, "d10000001111")
        .await
        .expect("the Quuppa tag is tracked");
    let position = &tag["position_m"];
    assert!(
        (position[0].as_f64().unwrap() + 1.09).abs() < 0.05 && (position[1].as_f64().unwrap() - 0.38).abs() < 0.05,
        "{tag}"
    );
    let quuppa_accepted = "rtls_udp_datagrams_total{listener=\"udp:adapters/quuppa\",outcome=\"accepted\"}";
    let metrics = poll_text(&client, http, "/metrics", |m| metric_value(m, quuppa_accepted) >= 3.0).await;
    assert_eq!(metric_value(&metrics, quuppa_accepted), 3.0, "{metrics}");
    assert_eq!(
        metric_value(&metrics, "rtls_ingest_refused_total{reason=\"no_position\"}"),
        1.0
    );
    // nothing was dropped
    for source in [listener.as_str(), "udp:adapters/quuppa"] {
        let dropped = format!("rtls_udp_datagrams_total{{listener=\"{source}\",outcome=\"dropped\"}}");
        assert_eq!(metric_value(&metrics, &dropped), 0.0, "{dropped}");
    }

    // the listeners stop with the server
    running.stop().await;
}
