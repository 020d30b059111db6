//! `rtls serve` over TLS with real clients, as an integrator runs it: a self-signed certificate
//! generated on first start, `curl --cacert` over HTTPS, `mosquitto_pub` / `mosquitto_sub
//! --cafile` over MQTTS (a QoS 1 payload acknowledged, its track received), plain HTTP refused,
//! and a renewed certificate served without a restart.
//!
//! Needs `curl`, `mosquitto_pub` and `mosquitto_sub` (`.ci/services/mosquitto.sh` installs
//! them); without them the test prints a notice and passes, unless `RTLS_TEST_MOSQUITTO_URL`
//! says this is CI.

mod common;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use serde_json::Value;

const READ: &str = "tls-read-token-1";
const WRITE: &str = "tls-write-token-1";

const SITE: &str = r#"
name = "tls bench"
[[readers]]
id = "A1"
position_m = [0.0, 0.0]
technology = "uwb"
[[readers]]
id = "A2"
position_m = [20.0, 0.0]
technology = "uwb"
[[readers]]
id = "A3"
position_m = [0.0, 20.0]
technology = "uwb"
[tracker]
initiation = { confirm_updates = 2, within_s = 5.0 }
"#;

fn tools_present() -> bool {
    let present = ["curl", "mosquitto_pub", "mosquitto_sub"].iter().all(|tool| {
        Command::new(tool)
            .arg("--help")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok()
    });
    if !present {
        assert!(
            std::env::var_os("RTLS_TEST_MOSQUITTO_URL").is_none(),
            "CI: curl, mosquitto_pub and mosquitto_sub must be installed (.ci/services/mosquitto.sh)"
        );
        eprintln!("notice: the TLS test did not run: install curl and mosquitto-clients");
    }
    present
}

fn curl(args: &[&str]) -> Output {
    Command::new("curl")
        .args(["-sS", "--max-time", "5"])
        .args(args)
        .output()
        .expect("curl runs")
}

fn now_s() -> f64 {
    SystemTime::now().duration_since(UNIX_EPOCH).unwrap().as_secs_f64()
}

/// Fixes of `tag` over the last second, one per 0.2 s, as JSON lines.
fn fixes(tag: &str) -> String {
    let now = now_s();
    (0..5)
        .map(|k| {
            let t = now - 1.0 + 0.2 * f64::from(k);
            format!(
                "{{\"t\": {t:.3}, \"tag\": \"{tag}\", \"kind\": \"fix\", \"position_m\": [{}, 5.0], \"covariance_m2\": [0.04, 0.0, 0.0, 0.04]}}\n",
                5.0 + 0.2 * f64::from(k)
            )
        })
        .collect()
}

/// Replaces `target` with `source`'s content atomically (a renewal as certbot does it).
fn replace(source: &Path, target: &Path) {
    let staging = target.with_extension("new");
    std::fs::copy(source, &staging).unwrap();
    std::fs::rename(&staging, target).unwrap();
}

#[test]
fn https_and_mqtts_with_a_self_signed_certificate_and_a_renewal_without_restart() {
    if !tools_present() {
        return;
    }
    let dir = common::temp_dir("tls", "end-to-end");
    let (cert, key): (PathBuf, PathBuf) = (dir.join("server.crt"), dir.join("server.key"));
    std::fs::write(dir.join("site.toml"), SITE).unwrap();
    std::fs::write(
        dir.join("server.toml"),
        format!(
            "[server]\nsite = \"{}\"\n[tls]\ncert = \"{}\"\nkey = \"{}\"\nself_signed = true\nreload_s = 0.3\n",
            dir.join("site.toml").display(),
            cert.display(),
            key.display()
        ),
    )
    .unwrap();
    let config = dir.join("server.toml");
    let served = common::serve(
        &["--config", config.to_str().unwrap()],
        &dir.join("rtls.db"),
        WRITE,
        READ,
    );
    let bound = &served.bound;
    assert_eq!(bound["tls"], true, "{bound}");
    let http = bound["http"].as_str().unwrap().to_string();
    let mqtt = bound["mqtt"].as_str().unwrap().to_string();
    let (mqtt_host, mqtt_port) = mqtt.rsplit_once(':').unwrap();
    assert!(cert.exists() && key.exists(), "the self-signed pair was written");
    let cafile = cert.to_str().unwrap().to_string();

    // HTTPS with the certificate as the trust anchor
    let health = curl(&["--cacert", &cafile, &format!("https://{http}/health")]);
    assert!(health.status.success(), "{}", String::from_utf8_lossy(&health.stderr));
    let body: Value = serde_json::from_slice(&health.stdout).unwrap();
    assert_eq!(body["status"], "ok");
    // an unknown certificate is not trusted, and plain HTTP gets no answer
    assert!(!curl(&[&format!("https://{http}/health")]).status.success());
    assert!(!curl(&[&format!("http://{http}/health")]).status.success());

    // MQTTS: a subscriber with the read token, a QoS 1 publisher with the write token
    let subscriber = Command::new("mosquitto_sub")
        .args(["--cafile", &cafile, "-h", mqtt_host, "-p", mqtt_port])
        .args([
            "-u",
            "viewer",
            "-P",
            READ,
            "-t",
            "rtls/v1/tracks/#",
            "-C",
            "1",
            "-W",
            "20",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("mosquitto_sub runs");
    let mut subscriber = common::KillOnDrop(subscriber);
    std::thread::sleep(Duration::from_millis(500));
    let mut delivered = false;
    let deadline = Instant::now() + Duration::from_secs(10);
    while Instant::now() < deadline {
        let published = Command::new("mosquitto_pub")
            .args(["--cafile", &cafile, "-h", mqtt_host, "-p", mqtt_port])
            .args([
                "-u",
                "gateway",
                "-P",
                WRITE,
                "-q",
                "1",
                "-t",
                "rtls/v1/measurements/gw-1",
            ])
            .args(["-m", &fixes("tag-tls")])
            .output()
            .expect("mosquitto_pub runs");
        assert!(
            published.status.success(),
            "QoS 1 publish over MQTTS: {}",
            String::from_utf8_lossy(&published.stderr)
        );
        // `mosquitto_sub -C 1` exits once it has its message
        if subscriber.0.try_wait().expect("mosquitto_sub status").is_some() {
            delivered = true;
            break;
        }
        std::thread::sleep(Duration::from_millis(500));
    }
    assert!(delivered, "the subscriber received a track over MQTTS");
    let output = subscriber_output(subscriber);
    assert!(output.contains("tag-tls"), "{output}");

    // a renewed certificate (a new key) is served from the next connection on
    let old_ca = dir.join("old.crt");
    std::fs::copy(&cert, &old_ca).unwrap();
    let renewed = dir.join("renewed");
    std::fs::create_dir_all(&renewed).unwrap();
    let (new_cert, new_key) = (renewed.join("server.crt"), renewed.join("server.key"));
    rtls_server::tls::ensure_self_signed(&new_cert, &new_key, &["127.0.0.1".to_string()]).unwrap();
    replace(&new_key, &key);
    replace(&new_cert, &cert);
    let new_ca = new_cert.to_str().unwrap().to_string();
    let deadline = Instant::now() + Duration::from_secs(10);
    while !curl(&["--cacert", &new_ca, &format!("https://{http}/health")])
        .status
        .success()
    {
        assert!(
            Instant::now() < deadline,
            "the renewed certificate was not served within 10 s"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    assert!(
        !curl(&["--cacert", old_ca.to_str().unwrap(), &format!("https://{http}/health")])
            .status
            .success(),
        "the old certificate is gone"
    );
}

fn subscriber_output(mut subscriber: common::KillOnDrop) -> String {
    let mut out = String::new();
    if let Some(stdout) = subscriber.0.stdout.take() {
        let _ = BufReader::new(stdout).read_line(&mut out);
    }
    out
}
