#!/usr/bin/env bash
# Reproduces the tables of docs/EVALUATION.md: imports the recorded datasets of ../shared/data,
# tracks them with `rtls track` in each configuration and scores the tracks with `rtls eval`.
#
#   scripts/evaluate.sh [OUT_DIR]      (default: target/evaluation)
#
# Prints one line per configuration: dataset, run, configuration, samples, RMSE, mean, median, p95 (m),
# the share of truths inside the reported 95 % ellipse and the mean NEES (2 when consistent).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-target/evaluation}
DATA=${RTLS_DATA_DIR:-../shared/data}
cargo build --release -q -p rtls-cli
RTLS=target/release/rtls
mkdir -p "$OUT"

import() { [ -d "$OUT/$2" ] || "$RTLS" import "$DATA/$1" --out "$OUT/$2" > "$OUT/$2.import.txt"; }
import uwb_lias_cuhksz_planar_rbl lias
import ble_rssi_tracking_danis_tetam ble
import uwb_odometry_labyrinth_tuc labyrinth
import ujiindoorloc uji

# score DATASET RUN CONFIG TRUTH TRACKS [eval flags…]
score() {
  local dataset=$1 run=$2 config=$3 truth=$4 tracks=$5; shift 5
  "$RTLS" eval --truth "$truth" --tracks "$tracks" --json "$@" | python3 -c '
import json, sys
j = json.load(sys.stdin)
o, c = j["overall"], j.get("consistency")
row = sys.argv[1:4] + [o[k] for k in ("count", "rmse_m", "mean_m", "median_m", "p95_m")]
row += ["%6.1f%%" % (100 * c["inside_95"]), "%8.2f" % c["mean_nees"]] if c else ["-", "-"]
print("%-10s %-32s %-44s %7d %7.3f %7.3f %7.3f %7.3f %7s %8s" % tuple(row))' "$dataset" "$run" "$config"
}

# track RUN_DIR NAME INPUT [track flags…] → $RUN_DIR/NAME.tracks.jsonl, NAME.fixes.jsonl, NAME.events.jsonl
track() {
  local dir=$1 name=$2 input=$3; shift 3
  local site=${SITE:-$dir/site.toml} status=0
  "$RTLS" track --site "$site" --input "$dir/$input" --output "$dir/$name.tracks.jsonl" \
    --events "$dir/$name.events.jsonl" --fixes "$dir/$name.fixes.jsonl" --quiet "$@" 2> "$dir/$name.summary.txt" || status=$?
  # exit status 3: a tag had records but no track (named in the summary); anything else stops here
  if [ "$status" -eq 3 ]; then echo "note: $dir/$name: $(grep -m1 'no track for tag' "$dir/$name.summary.txt")" >&2
  elif [ "$status" -ne 0 ]; then cat "$dir/$name.summary.txt" >&2; exit "$status"; fi
}

# tuned RUN_DIR NAME INPUT [track flags…]: `rtls tune --truth` on the first half of the recording
# (by truth time) with the same --pipeline/--filter/--motion-model flags the track will run, then
# the whole recording tracked with the tuned site; scored on the second
# half only (truth-late.csv), with the raw fixes of the same run
tuned() {
  local dir=$1 name=$2 input=$3; shift 3
  local split
  split=$(python3 -c 'import csv, sys; t = sorted(float(r["t"]) for r in csv.DictReader(open(sys.argv[1]))); print(t[len(t) // 2])' "$dir/truth.csv")
  python3 -c 'import csv, sys
rows = list(csv.reader(open(sys.argv[1])))
w = csv.writer(open(sys.argv[2], "w", newline=""), lineterminator="\n")
w.writerow(rows[0]); w.writerows(r for r in rows[1:] if float(r[0]) > float(sys.argv[3]))' "$dir/truth.csv" "$dir/truth-late.csv" "$split"
  "$RTLS" tune --site "$dir/site.toml" --input "$dir/$input" --truth "$dir/truth.csv" --until-s "$split" \
    --out "$dir/$name.tuned.toml" "$@" > "$dir/$name.tune.txt"
  SITE="$dir/$name.tuned.toml" track "$dir" "$name" "$input" "$@"
}

printf '%-10s %-32s %-44s %7s %7s %7s %7s %7s %7s %8s\n' dataset run configuration samples RMSE mean median p95 in95 NEES
# UWB two-way ranging with motion capture: 3 tags on a trolley, 8 anchors (first 1 s skipped)
for run in fast mid; do
  d=$OUT/lias/$run
  track "$d" tc-ekf measurements.jsonl --pipeline tightly-coupled --filter ekf
  track "$d" tc-ukf measurements.jsonl --pipeline tightly-coupled --filter ukf
  track "$d" tc-imm measurements.jsonl --pipeline tightly-coupled --filter ekf --motion-model imm
  track "$d" ftf measurements.jsonl --pipeline fix-then-filter --filter kf
  track "$d" tc-ekf-smooth measurements.jsonl --pipeline tightly-coupled --filter ekf --smooth
  track "$d" ftf-smooth measurements.jsonl --pipeline fix-then-filter --filter kf --smooth
  track "$d" raw-tc-ekf measurements-raw.jsonl --pipeline tightly-coupled --filter ekf
  track "$d" raw-ftf measurements-raw.jsonl --pipeline fix-then-filter --filter kf
  score uwb-lias "$run" "tightly coupled EKF, calibrated" "$d/truth.csv" "$d/tc-ekf.tracks.jsonl" --skip-initial 1
  score uwb-lias "$run" "tightly coupled UKF, calibrated" "$d/truth.csv" "$d/tc-ukf.tracks.jsonl" --skip-initial 1
  score uwb-lias "$run" "tightly coupled EKF IMM, calibrated" "$d/truth.csv" "$d/tc-imm.tracks.jsonl" --skip-initial 1
  score uwb-lias "$run" "fix-then-filter KF, calibrated" "$d/truth.csv" "$d/ftf.tracks.jsonl" --skip-initial 1
  score uwb-lias "$run" "raw fixes (Gauss-Newton), calibrated" "$d/truth.csv" "$d/ftf.fixes.jsonl" --skip-initial 1
  score uwb-lias "$run" "tightly coupled EKF, calibrated, smoothed" "$d/truth.csv" "$d/tc-ekf-smooth.tracks.jsonl" --skip-initial 1
  score uwb-lias "$run" "fix-then-filter KF, calibrated, smoothed" "$d/truth.csv" "$d/ftf-smooth.tracks.jsonl" --skip-initial 1
  score uwb-lias "$run" "tightly coupled EKF, raw ranges" "$d/truth.csv" "$d/raw-tc-ekf.tracks.jsonl" --skip-initial 1
  score uwb-lias "$run" "fix-then-filter KF, raw ranges" "$d/truth.csv" "$d/raw-ftf.tracks.jsonl" --skip-initial 1
  score uwb-lias "$run" "raw fixes, raw ranges" "$d/truth.csv" "$d/raw-ftf.fixes.jsonl" --skip-initial 1
done

# BLE RSSI, one beacon, 12 sensors; path loss and radio map fitted on the other 8 tracks
for d in "$OUT"/ble/*/; do
  d=${d%/}; run=$(basename "$d")
  track "$d" pl-tc measurements.jsonl --pipeline tightly-coupled --filter ekf
  track "$d" pl-ftf measurements.jsonl --pipeline fix-then-filter --filter kf
  track "$d" fp-ftf measurements-vectors.jsonl --pipeline fix-then-filter --filter kf
  track "$d" pl-tc-smooth measurements.jsonl --pipeline tightly-coupled --filter ekf --smooth
  track "$d" pl-ftf-smooth measurements.jsonl --pipeline fix-then-filter --filter kf --smooth
  track "$d" fp-ftf-smooth measurements-vectors.jsonl --pipeline fix-then-filter --filter kf --smooth
  score ble "$run" "path loss, tightly coupled EKF" "$d/truth.csv" "$d/pl-tc.tracks.jsonl" --skip-initial 2 --max-gap 1
  score ble "$run" "path loss, fix-then-filter KF (1 s epochs)" "$d/truth.csv" "$d/pl-ftf.tracks.jsonl" --skip-initial 2 --max-gap 1
  score ble "$run" "path loss, raw fixes" "$d/truth.csv" "$d/pl-ftf.fixes.jsonl" --skip-initial 2 --max-gap 1
  score ble "$run" "fingerprint WKNN, fix-then-filter KF" "$d/truth.csv" "$d/fp-ftf.tracks.jsonl" --skip-initial 2 --max-gap 1
  score ble "$run" "fingerprint WKNN, raw fixes" "$d/truth.csv" "$d/fp-ftf.fixes.jsonl" --skip-initial 2 --max-gap 1
  score ble "$run" "path loss, tightly coupled EKF, smoothed" "$d/truth.csv" "$d/pl-tc-smooth.tracks.jsonl" --skip-initial 2 --max-gap 1
  score ble "$run" "path loss, fix-then-filter KF, smoothed" "$d/truth.csv" "$d/pl-ftf-smooth.tracks.jsonl" --skip-initial 2 --max-gap 1
  score ble "$run" "fingerprint WKNN, fix-then-filter, smoothed" "$d/truth.csv" "$d/fp-ftf-smooth.tracks.jsonl" --skip-initial 2 --max-gap 1
done

# UWB + wheel odometry, labyrinth robot (4 anchors, one range per step)
d=$OUT/labyrinth/labyrinth
track "$d" uwb-odo measurements.jsonl --pipeline tightly-coupled --filter ekf
track "$d" uwb measurements-uwb-only.jsonl --pipeline tightly-coupled --filter ekf
track "$d" uwb-odo-smooth measurements.jsonl --pipeline tightly-coupled --filter ekf --smooth
score labyrinth labyrinth "UWB + odometry, tightly coupled EKF" "$d/truth.csv" "$d/uwb-odo.tracks.jsonl" --skip-initial 1
score labyrinth labyrinth "UWB + odometry, tightly coupled, smoothed" "$d/truth.csv" "$d/uwb-odo-smooth.tracks.jsonl" --skip-initial 1
score labyrinth labyrinth "UWB only, tightly coupled EKF" "$d/truth.csv" "$d/uwb.tracks.jsonl" --skip-initial 1

# UJIIndoorLoc validation scans located in the training radio map
d=$OUT/uji/validation
track "$d" fp measurements.jsonl
track "$d" fp-smooth measurements.jsonl --smooth
score uji validation "fingerprint WKNN, fix-then-filter KF" "$d/truth.csv" "$d/fp.tracks.jsonl" --max-gap 0
score uji validation "fingerprint WKNN, KF, smoothed" "$d/truth.csv" "$d/fp-smooth.tracks.jsonl" --max-gap 0
score uji validation "fingerprint WKNN, raw fixes" "$d/truth.csv" "$d/fp.fixes.jsonl" --max-gap 0

# rtls tune with ground truth on the first half of each recording, scored on the second half
for run in fast mid; do
  d=$OUT/lias/$run
  tuned "$d" tuned-tc "measurements-raw.jsonl" --pipeline tightly-coupled --filter ekf
  tuned "$d" tuned-ftf "measurements-raw.jsonl" --pipeline fix-then-filter --filter kf
  score uwb-lias "$run" "tuned (raw ranges), tightly coupled EKF" "$d/truth-late.csv" "$d/tuned-tc.tracks.jsonl"
  score uwb-lias "$run" "tuned (raw ranges), fix-then-filter KF" "$d/truth-late.csv" "$d/tuned-ftf.tracks.jsonl"
  score uwb-lias "$run" "tuned (raw ranges), raw fixes" "$d/truth-late.csv" "$d/tuned-ftf.fixes.jsonl"
  SITE="$d/tuned-tc.tuned.toml" track "$d" tuned-tc-smooth measurements-raw.jsonl --pipeline tightly-coupled --filter ekf --smooth
  SITE="$d/tuned-ftf.tuned.toml" track "$d" tuned-ftf-smooth measurements-raw.jsonl --pipeline fix-then-filter --filter kf --smooth
  score uwb-lias "$run" "tuned (raw ranges), tightly coupled EKF, smoothed" "$d/truth-late.csv" "$d/tuned-tc-smooth.tracks.jsonl"
  score uwb-lias "$run" "tuned (raw ranges), fix-then-filter KF, smoothed" "$d/truth-late.csv" "$d/tuned-ftf-smooth.tracks.jsonl"
done
for d in "$OUT"/ble/*/; do
  d=${d%/}; run=$(basename "$d")
  tuned "$d" tuned-tc measurements.jsonl --pipeline tightly-coupled --filter ekf
  tuned "$d" tuned-ftf measurements.jsonl --pipeline fix-then-filter --filter kf
  tuned "$d" tuned-fp measurements-vectors.jsonl --pipeline fix-then-filter --filter kf
  SITE="$d/tuned-tc.tuned.toml" track "$d" tuned-tc-smooth measurements.jsonl --pipeline tightly-coupled --filter ekf --smooth
  SITE="$d/tuned-ftf.tuned.toml" track "$d" tuned-ftf-smooth measurements.jsonl --pipeline fix-then-filter --filter kf --smooth
  SITE="$d/tuned-fp.tuned.toml" track "$d" tuned-fp-smooth measurements-vectors.jsonl --pipeline fix-then-filter --filter kf --smooth
  score ble "$run" "tuned path loss, tightly coupled EKF" "$d/truth-late.csv" "$d/tuned-tc.tracks.jsonl" --max-gap 1
  score ble "$run" "tuned path loss, fix-then-filter KF" "$d/truth-late.csv" "$d/tuned-ftf.tracks.jsonl" --max-gap 1
  score ble "$run" "tuned path loss, raw fixes" "$d/truth-late.csv" "$d/tuned-ftf.fixes.jsonl" --max-gap 1
  score ble "$run" "tuned fingerprint WKNN, fix-then-filter KF" "$d/truth-late.csv" "$d/tuned-fp.tracks.jsonl" --max-gap 1
  score ble "$run" "tuned fingerprint WKNN, raw fixes" "$d/truth-late.csv" "$d/tuned-fp.fixes.jsonl" --max-gap 1
  score ble "$run" "tuned path loss, tightly coupled EKF, smoothed" "$d/truth-late.csv" "$d/tuned-tc-smooth.tracks.jsonl" --max-gap 1
  score ble "$run" "tuned path loss, fix-then-filter, smoothed" "$d/truth-late.csv" "$d/tuned-ftf-smooth.tracks.jsonl" --max-gap 1
  score ble "$run" "tuned fingerprint WKNN, fix-then-filter, smoothed" "$d/truth-late.csv" "$d/tuned-fp-smooth.tracks.jsonl" --max-gap 1
done
d=$OUT/labyrinth/labyrinth
tuned "$d" tuned-odo measurements.jsonl --pipeline tightly-coupled --filter ekf
tuned "$d" tuned-uwb measurements-uwb-only.jsonl --pipeline tightly-coupled --filter ekf
score labyrinth labyrinth "tuned, UWB + odometry, tightly coupled EKF" "$d/truth-late.csv" "$d/tuned-odo.tracks.jsonl"
score labyrinth labyrinth "tuned, UWB only, tightly coupled EKF" "$d/truth-late.csv" "$d/tuned-uwb.tracks.jsonl"
SITE="$d/tuned-odo.tuned.toml" track "$d" tuned-odo-smooth measurements.jsonl --pipeline tightly-coupled --filter ekf --smooth
SITE="$d/tuned-uwb.tuned.toml" track "$d" tuned-uwb-smooth measurements-uwb-only.jsonl --pipeline tightly-coupled --filter ekf --smooth
score labyrinth labyrinth "tuned, UWB + odometry, tightly coupled EKF, smoothed" "$d/truth-late.csv" "$d/tuned-odo-smooth.tracks.jsonl"
score labyrinth labyrinth "tuned, UWB only, tightly coupled EKF, smoothed" "$d/truth-late.csv" "$d/tuned-uwb-smooth.tracks.jsonl"
d=$OUT/uji/validation
tuned "$d" tuned-fp measurements.jsonl
score uji validation "tuned σ_a, fingerprint WKNN, KF" "$d/truth-late.csv" "$d/tuned-fp.tracks.jsonl" --max-gap 0
score uji validation "tuned σ_a, fingerprint WKNN, raw fixes" "$d/truth-late.csv" "$d/tuned-fp.fixes.jsonl" --max-gap 0
SITE="$d/tuned-fp.tuned.toml" track "$d" tuned-fp-smooth measurements.jsonl --smooth
score uji validation "tuned σ_a, fingerprint WKNN, KF, smoothed" "$d/truth-late.csv" "$d/tuned-fp-smooth.tracks.jsonl" --max-gap 0
