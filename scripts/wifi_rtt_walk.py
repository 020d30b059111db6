#!/usr/bin/env python3
"""A simulated Wi-Fi RTT office walk whose readers report one at a time, for trying
fix-then-filter and tightly coupled tracking on a kind of recording ../shared/data lacks.

    scripts/wifi_rtt_walk.py OUT_DIR [SEED] [--odometry]

Writes OUT_DIR/{site.toml, measurements.jsonl, truth.csv}: 8 access points at 2.8 m on the
walls of a 40 m x 20 m office, a phone at 1.2 m walking a loop three times at 1.2 m/s with
pauses of 0-4 s at the corners. One range per access point per second, each at its own time
(access point i at k + (i + 0.5)/8 s); each range is the slant distance plus the access
point's bias (N(0.5, 0.7) m, fixed per access point), a multipath error per access point
(AR(1), correlation time 3 s, sigma 0.8 m), white noise (sigma 0.5 m) and, with probability
0.12, a non-line-of-sight excess (exponential, mean 3 m); 10 % of the ranges are missing.
Negative ranges are kept. The site states range_std_m = 1.0 and no bias, as a datasheet would;
it sets no tracker.epoch_s. With --odometry, OUT_DIR/measurements.jsonl also holds the phone's
speed and heading every 0.5 s (pedestrian dead reckoning: sigma 0.1 m/s and 0.05 rad, stated
in each record). No Python packages beyond the standard library.
"""
import json
import math
import os
import random
import sys


def main():
    args = [a for a in sys.argv[1:] if a != "--odometry"]
    odometry = "--odometry" in sys.argv[1:]
    out_dir = args[0]
    seed = int(args[1]) if len(args) > 1 else 1
    rng = random.Random(seed)
    os.makedirs(out_dir, exist_ok=True)
    aps = [(0, 0), (13, 0), (26, 0), (40, 0), (0, 20), (13, 20), (26, 20), (40, 20)]
    ap_height_m, tag_height_m = 2.8, 1.2
    waypoints = [(3, 3), (37, 3), (37, 17), (20, 17), (20, 8), (5, 8), (5, 17)] * 3 + [(3, 3)]
    speed_mps, dt = 1.2, 0.05
    truth = []  # (t, x, y) every dt
    t = 0.0
    for (ax, ay), (bx, by) in zip(waypoints, waypoints[1:]):
        steps = int(math.hypot(bx - ax, by - ay) / (speed_mps * dt))
        for i in range(steps):
            f = i / steps
            truth.append((t, ax + f * (bx - ax), ay + f * (by - ay)))
            t += dt
        for _ in range(int(rng.uniform(0, 4) / dt)):  # a pause at the corner
            truth.append((t, bx, by))
            t += dt
    end_s = truth[-1][0]

    def position(time_s):
        i = min(int(time_s / dt), len(truth) - 1)
        return truth[i][1], truth[i][2]

    bias = [rng.gauss(0.5, 0.7) for _ in aps]
    multipath = [0.0] * len(aps)
    a = math.exp(-1.0 / 3.0)  # one step of a second, correlation time 3 s
    records = []
    for k in range(int(end_s)):
        for j, (px, py) in enumerate(aps):
            tk = k + (j + 0.5) / len(aps)
            if tk >= end_s:
                continue
            multipath[j] = a * multipath[j] + math.sqrt(1 - a * a) * rng.gauss(0, 0.8)
            x, y = position(tk)
            d = math.sqrt((x - px) ** 2 + (y - py) ** 2 + (ap_height_m - tag_height_m) ** 2)
            r = d + bias[j] + multipath[j] + rng.gauss(0, 0.5)
            if rng.random() < 0.12:
                r += rng.expovariate(1 / 3.0)
            if rng.random() < 0.1:
                continue
            records.append({"t": round(tk, 3), "tag": "phone", "kind": "range",
                            "anchor": f"AP{j + 1}", "range_m": round(r, 3)})
    if odometry:
        # speed and heading from the truth every 0.5 s, with the stated noise (its own stream,
        # so the ranges are those of the run without odometry)
        odo_rng = random.Random(seed + 1000)
        samples = truth[::10]
        for (t0, x0, y0), (t1, x1, y1) in zip(samples, samples[1:]):
            speed = math.hypot(x1 - x0, y1 - y0) / (t1 - t0)
            heading = math.atan2(y1 - y0, x1 - x0) if speed > 0.01 else 0.0
            records.append({"t": round(t1, 3), "tag": "phone", "kind": "odometry",
                            "speed_mps": round(max(0.0, speed + odo_rng.gauss(0, 0.1)), 3),
                            "heading_rad": round(heading + odo_rng.gauss(0, 0.05), 4),
                            "speed_std_mps": 0.1, "heading_std_rad": 0.05})
        records.sort(key=lambda r: r["t"])
    with open(os.path.join(out_dir, "measurements.jsonl"), "w", encoding="utf-8") as f:
        for record in records:
            f.write(json.dumps(record) + "\n")
    with open(os.path.join(out_dir, "truth.csv"), "w", encoding="utf-8") as f:
        f.write("t,tag,x,y,z\n")
        for (tt, x, y) in truth[::10]:
            f.write(f"{tt:.3f},phone,{x:.3f},{y:.3f},\n")
    with open(os.path.join(out_dir, "site.toml"), "w", encoding="utf-8") as f:
        f.write('name = "simulated Wi-Fi RTT office (scripts/wifi_rtt_walk.py)"\n\n')
        for j, (px, py) in enumerate(aps):
            f.write(f'[[readers]]\nid = "AP{j + 1}"\nposition_m = [{px}.0, {py}.0, {ap_height_m}]\n'
                    'technology = "wifi"\nradio = { range = { range_std_m = 1.0, bias_m = 0.0 } }\n\n')
        f.write(f'[tracker]\nplatform = "walker"\ntag_height_m = {tag_height_m}\n')
    print(f"{len(records)} records over {end_s:.0f} s; access point biases (m): "
          + ", ".join(f"{b:+.2f}" for b in bias))


if __name__ == "__main__":
    main()
