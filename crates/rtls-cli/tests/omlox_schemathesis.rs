//! The omlox hub 2.0 OpenAPI (`../shared/reference/omlox_Hub_API_2.0.0.json`) run through
//! schemathesis (a property-based API fuzzer from PyPI) against `rtls serve` on loopback: every
//! operation but the WebSocket's, examples, coverage, fuzzing and stateful phases, and every
//! check: no server error, responses that match their schema and their documented status
//! codes and content types, schema-violating requests refused, schema-valid requests accepted.
//! The exceptions are in `omlox-schemathesis.toml`, each with its reason; those of the last
//! check — schema-valid requests the spec's text forbids or the hub cannot honour (another CRS
//! than `local` and `EPSG:4326`, an unknown zone as a proximity's source, a timestamp years
//! old …), each with the spec sentence — are predicates of `omlox-schemathesis-hooks.py`'s
//! `filter_failure`, which drops such a failure only when the hub's omlox Error names the
//! field and the request's value of it shows the reason (docs/SERVER.md, "omlox conformance").
//!
//! Needs `RTLS_SCHEMATHESIS` (the `st` command; `.ci/services/schemathesis.sh` installs it) and
//! the spec file; without either the test says so and passes.

mod common;

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

const WRITE: &str = "schemathesis-write";
const READ: &str = "schemathesis-read";
/// Examples per operation and phase: about a minute of the debug build.
const MAX_EXAMPLES: &str = "50";

#[test]
fn the_omlox_openapi_holds_under_a_property_based_fuzzer() {
    let Ok(st) = std::env::var("RTLS_SCHEMATHESIS") else {
        eprintln!("RTLS_SCHEMATHESIS is not set (.ci/services/schemathesis.sh): the omlox fuzz run is skipped");
        return;
    };
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    let spec = manifest.join("../../../shared/reference/omlox_Hub_API_2.0.0.json");
    if !spec.exists() {
        eprintln!("{} is missing: the omlox fuzz run is skipped", spec.display());
        return;
    }
    let dir = common::temp_dir("schemathesis", "omlox");
    // the example site: georeferenced, so EPSG:4326 locations and fences are taken
    let site = manifest.join("../../examples/site.toml");
    let served = common::serve(&["--site", site.to_str().unwrap()], &dir.join("rtls.db"), WRITE, READ);
    let started = Instant::now();
    let output = Command::new(&st)
        // the exceptions of the positive-data check (omlox-schemathesis.toml says which and why)
        .env("SCHEMATHESIS_HOOKS", manifest.join("tests/omlox-schemathesis-hooks.py"))
        .arg("--config-file")
        .arg(manifest.join("tests/omlox-schemathesis.toml"))
        .arg("run")
        .arg(&spec)
        .args(["--url", &format!("http://{}/v2", served.http())])
        .args(["-H", &format!("Authorization: Bearer {WRITE}")])
        .args(["--max-examples", MAX_EXAMPLES, "--seed", "1", "--no-color"])
        // a WebSocket: its messages are checked in the server's omlox_ws tests
        .args(["--exclude-path", "/ws/socket"])
        .current_dir(&dir)
        .output()
        .expect("schemathesis runs");
    let report = String::from_utf8_lossy(&output.stdout);
    let summary: Vec<&str> = report
        .lines()
        .filter(|line| {
            let line = line.trim_start();
            (line.starts_with(|c: char| c.is_ascii_digit()) && line.contains(" generated"))
                || line.starts_with("Filtered:")
                || line.starts_with('❌')
        })
        .collect();
    println!(
        "schemathesis on the omlox OpenAPI, {:.0} s: {}",
        started.elapsed().as_secs_f64(),
        summary.join(" | ")
    );
    assert!(
        output.status.success(),
        "schemathesis found deviations:\n{report}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(
        report.contains("generated") && report.contains("passed"),
        "no test case ran:\n{report}"
    );
    // the positive-data check ran, and its exceptions were in use (else trim the hooks)
    assert!(
        report.contains("dropped by `filter_failure`"),
        "the hooks of omlox-schemathesis-hooks.py excused nothing:\n{report}"
    );
    assert!(started.elapsed() < Duration::from_secs(600));
    drop(served);
    let _ = std::fs::remove_dir_all(&dir);
}
