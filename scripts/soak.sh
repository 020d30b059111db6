#!/usr/bin/env bash
# The soak of issue 20 against a real `rtls serve` process (release build, SQLite, the default
# server configuration, the load test's site): TAGS tags × RATE_HZ fixes over MQTT QoS 1 for
# RUN_S seconds, then SILENCE_S seconds with every tag silent, then SIGTERM.
#
#   scripts/soak.sh [OUT_DIR]          (default: target/soak)
#   TAGS=6000 RATE_HZ=10 RUN_S=600 REPORT_S=60 SILENCE_S=40 HISTORY_INTERVAL_S=0 scripts/soak.sh
#
# HISTORY_INTERVAL_S is the server's `server.history_interval_s` (0, the default: every track
# state stored); everything else is the server's default configuration.
#
# Writes OUT_DIR/{site.toml, server.toml, rtls.db, serve.out, serve.err, loadtest.json, windows.jsonl} and
# prints one JSON line: the load test's result (per-window acknowledged records/s, latency and
# the server's resident memory), the track rows stored while the tags were silent
# (`rtls_stored_locations_total`, from 20 s after the last record to the end of the silence),
# the time SIGTERM took to drain, and the records stored (ingest log rows + record blocks)
# against those acknowledged. Exits non-zero when an acknowledged record is missing. The
# database stays in OUT_DIR for inspection: about 8 GB after the default run; delete it after.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-target/soak}
TAGS=${TAGS:-6000} RATE_HZ=${RATE_HZ:-10} SECONDS_RUN=${RUN_S:-600}  # (not SECONDS: bash counts the seconds since its start in it)
REPORT_S=${REPORT_S:-60} SILENCE_S=${SILENCE_S:-40} HISTORY_INTERVAL_S=${HISTORY_INTERVAL_S:-0}
rm -rf "$OUT" && mkdir -p "$OUT"
cargo build --release -q -p rtls-cli --bin rtls
cargo build --release -q -p rtls-server --example loadtest
RTLS=target/release/rtls
LOADTEST=target/release/examples/loadtest
"$LOADTEST" --write-site "$OUT/site.toml"
printf '[server]\nhistory_interval_s = %s\n' "$HISTORY_INTERVAL_S" > "$OUT/server.toml"

export RTLS_WRITE_TOKEN="soak-write-$RANDOM$RANDOM" RTLS_READ_TOKEN="soak-read-$RANDOM$RANDOM"
"$RTLS" serve --config "$OUT/server.toml" --site "$OUT/site.toml" --db "sqlite:$OUT/rtls.db" --http 127.0.0.1:0 \
  --mqtt-listen 127.0.0.1:0 > "$OUT/serve.out" 2> "$OUT/serve.err" &
PID=$!
trap 'kill -9 $PID 2>/dev/null || true' EXIT
for _ in $(seq 100); do grep -q '"http"' "$OUT/serve.out" 2>/dev/null && break; sleep 0.1; done
addr() { python3 -c 'import json, sys; print(json.loads(open(sys.argv[1]).readline())[sys.argv[2]])' "$OUT/serve.out" "$1"; }
HTTP=$(addr http) MQTT=$(addr mqtt)
metric() {
  python3 - "$HTTP" "$RTLS_READ_TOKEN" "$1" <<'EOF'
import sys, urllib.request
http, token, name = sys.argv[1:4]
request = urllib.request.Request(f"http://{http}/metrics", headers={"Authorization": f"Bearer {token}"})
text = urllib.request.urlopen(request, timeout=10).read().decode()
print(sum(float(line.split()[-1]) for line in text.splitlines() if line.startswith(name + " ") or line.startswith(name + "{")))
EOF
}

"$LOADTEST" --mqtt "$MQTT" --http "$HTTP" --token "$RTLS_WRITE_TOKEN" --read-token "$RTLS_READ_TOKEN" \
  --server-pid "$PID" --tags "$TAGS" --rate-hz "$RATE_HZ" --seconds "$SECONDS_RUN" --report-s "$REPORT_S" \
  > "$OUT/loadtest.json" 2> "$OUT/windows.jsonl"
# the load test waited 2 s after its last batch; the tags are silent from here
sleep 18
ROWS_SILENT_FROM=$(metric rtls_stored_locations_total)
sleep $((SILENCE_S - 20))
ROWS_SILENT_TO=$(metric rtls_stored_locations_total)
RSS_SILENT=$(awk '/VmRSS/ {print $2 / 1024}' "/proc/$PID/status")
START=$(date +%s.%N)
kill -TERM "$PID"
wait "$PID" || true
DRAIN_S=$(python3 -c "import sys; print(round($(date +%s.%N) - $START, 2))")
trap - EXIT

python3 - "$OUT" "$ROWS_SILENT_FROM" "$ROWS_SILENT_TO" "$((SILENCE_S - 20))" "$RSS_SILENT" "$DRAIN_S" <<'EOF'
import json, os, sqlite3, sys
out, rows_from, rows_to, silent_s, rss_silent, drain_s = sys.argv[1:7]
load = json.load(open(f"{out}/loadtest.json"))
db = sqlite3.connect(f"{out}/rtls.db")
stored = db.execute("SELECT count(*) FROM records").fetchone()[0] + (
    db.execute("SELECT coalesce(sum(count), 0) FROM record_blocks").fetchone()[0])
size_mb = sum(os.path.getsize(f"{out}/{f}") for f in os.listdir(out) if f.startswith("rtls.db")) / 1e6
load.update({
    "location_rows_per_s_while_silent": (float(rows_to) - float(rows_from)) / float(silent_s),
    "rss_mb_silent": round(float(rss_silent), 1),
    "sigterm_drain_s": float(drain_s),
    "records_stored": stored,
    "acknowledged_not_stored": max(0, load["acknowledged"] - stored),
    "database_mb": round(size_mb, 1),
})
print(json.dumps(load))
sys.exit(1 if load["acknowledged_not_stored"] else 0)
EOF
