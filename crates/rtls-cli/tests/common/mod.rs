//! What the CLI tests share: running the `rtls` binary and a fresh directory per test.

#![allow(dead_code)] // each test binary uses its own subset

pub mod cluster;

use std::path::PathBuf;
use std::process::Command;

/// Runs the `rtls` binary built for these tests with `args`.
pub fn rtls(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_rtls"))
        .args(args)
        .output()
        .expect("the rtls binary runs")
}

/// A fresh, empty directory for one test: `<tmp>/rtls-<suite>-<pid>-<name>`.
pub fn temp_dir(suite: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rtls-{suite}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A child process killed when dropped, so a failing test leaves no server running (which
/// would also keep the test's output pipe open).
pub struct KillOnDrop(pub std::process::Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A running `rtls serve` (killed when dropped) and the line it printed when bound
/// (`{"http", "mqtt", "tls"}`).
pub struct Served {
    pub child: KillOnDrop,
    pub bound: serde_json::Value,
}

impl Served {
    /// Its HTTP address.
    pub fn http(&self) -> String {
        self.bound["http"].as_str().unwrap().to_string()
    }
}

/// Starts `rtls serve` with `args` on loopback ports of its own (`127.0.0.1:0`), SQLite at
/// `db`, the write and read tokens in the environment, warnings only; waits for its bound line.
pub fn serve(args: &[&str], db: &std::path::Path, write: &str, read: &str) -> Served {
    use std::io::{BufRead, BufReader};
    let child = Command::new(env!("CARGO_BIN_EXE_rtls"))
        .arg("serve")
        .args(args)
        .args(["--http", "127.0.0.1:0", "--mqtt-listen", "127.0.0.1:0"])
        .arg("--db")
        .arg(format!("sqlite:{}", db.display()))
        .env("RTLS_WRITE_TOKEN", write)
        .env("RTLS_READ_TOKEN", read)
        .env("RTLS_LOG", "warn")
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("rtls serve starts");
    let mut child = KillOnDrop(child);
    let mut line = String::new();
    BufReader::new(child.0.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let bound = serde_json::from_str(&line).unwrap_or_else(|e| panic!("bound line {line:?}: {e}"));
    Served { child, bound }
}
