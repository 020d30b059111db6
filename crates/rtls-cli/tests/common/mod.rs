//! What the CLI tests share: running the `rtls` binary and a fresh directory per test.

#![allow(dead_code)] // each test binary uses its own subset

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
