#!/usr/bin/env python3
"""Where each recording stands against issue 17's targets, from the output of scripts/evaluate.sh.

    scripts/evaluate.sh OUT > OUT.log; scripts/standing.py OUT.log

Reads the tuned rows (configurations starting with "tuned": `rtls tune --truth` on the first
half of a recording, scored on the second half) and prints, per recording, the filtered and the
smoothed configuration with the least RMSE, each with its share of truths inside the reported
95 % ellipse and its RMSE against the raw fixes it stands on: the "raw fixes" row of the same
run whose configuration shares the longest prefix with it (a tightly coupled track's are the
path-loss fixes of the same tuned site). Then counts the rows that meet the targets: at least
30 % below raw, and 90-98 % inside.
"""
import os
import sys
from collections import OrderedDict


def rows(lines):
    """(dataset, run, configuration, rmse, inside %) of each scored line of the log: two words,
    the configuration, then seven numbers (a long configuration overflows its column)."""
    for line in lines:
        words = line.split()
        if len(words) < 10 or words[0] == "dataset" or not words[-2].endswith("%"):
            continue
        try:
            rmse, inside = float(words[-6]), float(words[-2].rstrip("%"))
        except ValueError:
            continue
        yield words[0], words[1], " ".join(words[2:-7]), rmse, inside


def common_prefix(a, b):
    return len(os.path.commonprefix([a, b]))


def main():
    runs = OrderedDict()
    with open(sys.argv[1], encoding="utf-8") as log:
        for dataset, run, config, rmse, inside in rows(log):
            if config.startswith("tuned"):
                runs.setdefault((dataset, run), []).append((config, rmse, inside))
    print("| recording | run | best filtered: RMSE, inside | its raw fixes | vs raw "
          "| best smoothed: RMSE, inside | vs raw |")
    print("| --- | --- | --- | ---: | ---: | --- | ---: |")
    counts = {"filtered": [0, 0, 0], "smoothed": [0, 0, 0]}  # ≥ 30 % below raw, of, 90-98 % inside
    covered = [0, 0]  # best filtered 90-98 % inside, of
    for (dataset, run), configs in runs.items():
        raws = [c for c in configs if c[0].endswith("raw fixes")]
        cells = [dataset, run]
        for kind in ("filtered", "smoothed"):
            pool = [c for c in configs if not c[0].endswith("raw fixes")
                    and c[0].endswith("smoothed") == (kind == "smoothed")]
            if not pool:
                cells += ["—", "—", "—"] if kind == "filtered" else ["—", "—"]
                continue
            config, rmse, inside = min(pool, key=lambda c: c[1])
            label = config.removeprefix("tuned").strip(" ,")
            cells.append(f"{rmse:.3f} m, {inside:.1f} % ({label})")
            if kind == "filtered":
                covered[1] += 1
                covered[0] += 90.0 <= inside <= 98.0
            raw = max(raws, key=lambda r: common_prefix(r[0], config), default=None)
            if raw is None:
                cells += ["—", "—"] if kind == "filtered" else ["—"]
                continue
            change = 100.0 * (rmse / raw[1] - 1.0)
            counts[kind][0] += change <= -30.0
            counts[kind][1] += 1
            if kind == "filtered":
                cells.append(f"{raw[1]:.3f} m")
            cells.append(f"{change:+.0f} %")
        print("| " + " | ".join(cells) + " |")
    print()
    for kind in ("filtered", "smoothed"):
        print(f"- {kind} >= 30 % below its raw fixes: {counts[kind][0]} of {counts[kind][1]}")
    print(f"- best filtered configuration 90-98 % inside: {covered[0]} of {covered[1]}")


if __name__ == "__main__":
    main()
