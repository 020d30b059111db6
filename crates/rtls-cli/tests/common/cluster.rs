//! A cluster on loopback for the cluster test and benchmark: three `nats-server`s with
//! JetStream, a PostgreSQL schema of its own, `rtls serve --cluster` nodes.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use super::KillOnDrop;

/// The nodes' write and read tokens.
pub const WRITE: &str = "cluster-test-write-token";
/// The read token.
pub const READ: &str = "cluster-test-read-token";

/// A 2-D fix-then-filter site; no re-ordering window (as the single-process load test,
/// `crates/rtls-server/examples/loadtest.rs`), so latency is the pipeline's.
pub const SITE: &str = r#"
name = "cluster test"
[[readers]]
id = "A1"
position_m = [0.0, 0.0, 2.5]
technology = "uwb"
[[readers]]
id = "A2"
position_m = [30.0, 0.0, 2.5]
technology = "uwb"
[tracker]
pipeline = "fix-then-filter"
motion_model = "cv"
filter = "ekf"
dimensions = 2
reorder_window_s = 0.0
rewind_horizon_s = 2.0
"#;

/// `RTLS_TEST_NATS_SERVER` and `RTLS_TEST_POSTGRES_URL`, or `None` after saying why.
pub fn services() -> Option<(String, String)> {
    match (
        std::env::var("RTLS_TEST_NATS_SERVER"),
        std::env::var("RTLS_TEST_POSTGRES_URL"),
    ) {
        (Ok(nats), Ok(postgres)) if !nats.is_empty() && !postgres.is_empty() => Some((nats, postgres)),
        _ => {
            eprintln!("skipped: RTLS_TEST_NATS_SERVER and RTLS_TEST_POSTGRES_URL are needed (.ci/services)");
            None
        }
    }
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Three JetStream servers clustered on loopback ports of their own (killed when dropped),
/// and their client URLs.
pub fn nats_cluster(binary: &str, dir: &Path) -> (Vec<KillOnDrop>, Vec<String>) {
    let client: Vec<u16> = (0..3).map(|_| free_port()).collect();
    let route: Vec<u16> = (0..3).map(|_| free_port()).collect();
    let servers = (0..3)
        .map(|i| {
            let routes: Vec<String> = (0..3)
                .filter(|&j| j != i)
                .map(|j| format!("nats://127.0.0.1:{}", route[j]))
                .collect();
            KillOnDrop(
                Command::new(binary)
                    .args([
                        "-a",
                        "127.0.0.1",
                        "-p",
                        &client[i].to_string(),
                        "-n",
                        &format!("n{i}"),
                        "-js",
                    ])
                    .arg("-sd")
                    .arg(dir.join(format!("js{i}")))
                    .args(["--cluster_name", "rtls-test"])
                    .args(["--cluster", &format!("nats://127.0.0.1:{}", route[i])])
                    .args(["--routes", &routes.join(",")])
                    .stdout(Stdio::null())
                    .stderr(Stdio::null())
                    .spawn()
                    .expect("nats-server starts"),
            )
        })
        .collect();
    let urls = client.iter().map(|p| format!("nats://127.0.0.1:{p}")).collect();
    (servers, urls)
}

/// A PostgreSQL schema of its own (dropped when dropped) and the `--db` URL that uses it.
pub struct Schema {
    url: String,
    name: String,
    /// The URL for `rtls serve --db`.
    pub db: String,
}

impl Schema {
    /// Creates `rtls_<purpose>_<pid>` afresh.
    pub fn new(url: &str, purpose: &str) -> Self {
        let name = format!("rtls_{purpose}_{}", std::process::id());
        Self::execute(
            url,
            &format!("DROP SCHEMA IF EXISTS {name} CASCADE; CREATE SCHEMA {name}"),
        );
        let separator = if url.contains('?') { '&' } else { '?' };
        Self {
            db: format!("{url}{separator}options=-csearch_path%3D{name}"),
            url: url.to_string(),
            name,
        }
    }

    /// The schema's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Runs a query (off the async runtime's workers).
    pub fn query(&self, sql: &str) -> Vec<postgres::Row> {
        let (url, sql) = (self.url.clone(), sql.to_string());
        tokio::task::block_in_place(move || {
            let mut client = postgres::Client::connect(&url, postgres::NoTls).expect("PostgreSQL");
            client.query(sql.as_str(), &[]).expect("query")
        })
    }

    fn execute(url: &str, sql: &str) {
        let (url, sql) = (url.to_string(), sql.to_string());
        let run = move || {
            let mut client = postgres::Client::connect(&url, postgres::NoTls).expect("PostgreSQL");
            client.batch_execute(&sql).expect("SQL");
        };
        match tokio::runtime::Handle::try_current() {
            Ok(_) => tokio::task::block_in_place(run),
            Err(_) => run(),
        }
    }
}

impl Drop for Schema {
    fn drop(&mut self) {
        Self::execute(&self.url, &format!("DROP SCHEMA IF EXISTS {} CASCADE", self.name));
    }
}

/// A running `rtls serve --cluster` node (killed when dropped); its log in `<dir>/node<i>.log`.
pub struct Node {
    /// The process.
    pub child: KillOnDrop,
    /// Its HTTP address.
    pub http: String,
    /// Its log file.
    pub log: PathBuf,
}

/// Starts node `index` of the cluster at `nats`, on the site in `<dir>/site.toml`; with no
/// NATS servers, one `rtls serve` without a cluster (the baseline).
pub fn start_node(dir: &Path, index: usize, nats: &[String], db: &str) -> Node {
    let log = dir.join(format!("node{index}.log"));
    let mut command = Command::new(env!("CARGO_BIN_EXE_rtls"));
    command
        .arg("serve")
        .arg("--site")
        .arg(dir.join("site.toml"))
        .args(["--http", "127.0.0.1:0", "--no-mqtt"]);
    if dir.join("server.toml").exists() {
        command.arg("--config").arg(dir.join("server.toml"));
    }
    if !nats.is_empty() {
        command
            .args(["--cluster", &nats.join(",")])
            .args(["--node-id", &format!("node{index}")]);
    }
    let mut child = command
        .args(["--db", db])
        .env("RTLS_WRITE_TOKEN", WRITE)
        .env("RTLS_READ_TOKEN", READ)
        .env(
            "RTLS_LOG",
            std::env::var("RTLS_TEST_CLUSTER_LOG").unwrap_or_else(|_| "warn".into()),
        )
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .expect("rtls serve starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let bound: serde_json::Value = serde_json::from_str(&line)
        .unwrap_or_else(|e| panic!("node {index}: announce line {line:?}: {e}; log {}", log.display()));
    Node {
        child: KillOnDrop(child),
        http: bound["http"].as_str().unwrap().to_string(),
        log,
    }
}

/// A metric's value on a node (0 when absent or unreachable).
pub async fn metric(client: &reqwest::Client, http: &str, name: &str) -> f64 {
    let Ok(response) = client
        .get(format!("http://{http}/metrics"))
        .bearer_auth(READ)
        .send()
        .await
    else {
        return 0.0;
    };
    let text = response.text().await.unwrap_or_default();
    text.lines()
        .find_map(|l| l.strip_prefix(name).and_then(|rest| rest.trim().parse().ok()))
        .unwrap_or(0.0)
}

/// Waits (40 s at most) until every node owns its fair share of `partitions`.
pub async fn wait_balanced(client: &reqwest::Client, nodes: &[Node], partitions: usize) {
    let started = std::time::Instant::now();
    loop {
        let mut owned = Vec::new();
        for node in nodes {
            owned.push(metric(client, &node.http, "rtls_cluster_partitions_owned").await as usize);
        }
        let fair = partitions.div_ceil(nodes.len());
        if owned.iter().sum::<usize>() == partitions && owned.iter().all(|&n| n + 1 >= fair && n <= fair) {
            return;
        }
        assert!(
            started.elapsed() < std::time::Duration::from_secs(40),
            "partitions owned per node: {owned:?}"
        );
        tokio::time::sleep(std::time::Duration::from_millis(200)).await;
    }
}

/// Seconds since the Unix epoch.
pub fn unix_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64()
}
