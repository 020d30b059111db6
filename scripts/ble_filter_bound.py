#!/usr/bin/env python3
"""What filtering the BLE raw fixes can give at best (issue 17).

For each BLE run of an evaluation directory (`scripts/evaluate.sh OUT` writes
OUT/ble/<run>/{pl-ftf.fixes.jsonl, truth.csv}), a constant-velocity Kalman filter and its
Rauch-Tung-Striebel smoother over the raw path-loss fixes (their reported covariances), with the
white-acceleration intensity q chosen per run *against the truth* — an oracle no tracker has —
and, for every q, the mean over the runs. Scored as `rtls eval --skip-initial 2` does (2-D RMSE
at the fixes' times, truth linearly interpolated). Needs numpy.

Usage: scripts/ble_filter_bound.py OUT
"""
import csv
import glob
import json
import math
import os
import sys

import numpy as np

QS = [0.001, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0]


def truth(path):
    rows = list(csv.DictReader(open(path)))
    return tuple(np.array([float(r[k]) for r in rows]) for k in ("t", "x", "y"))


def kf_and_rts(fixes, q):
    """Filtered and smoothed [x, vx, y, vy] at each fix, CV model with intensity q (m²/s³)."""
    h = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    x = np.array([fixes[0]["x"], 0, fixes[0]["y"], 0.0])
    p = np.diag([fixes[0]["cov"][0], 1.0, fixes[0]["cov"][3], 1.0])
    t = fixes[0]["t"]
    filtered, covs, priors, prior_covs, transitions = [], [], [], [], []
    for i, fix in enumerate(fixes):
        dt = fix["t"] - t
        t = fix["t"]
        f = np.eye(4)
        f[0, 1] = f[2, 3] = dt
        block = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
        qm = np.zeros((4, 4))
        qm[:2, :2] = qm[2:, 2:] = block
        if i > 0:
            x = f @ x  # x⁻ = F x
            p = f @ p @ f.T + qm  # P⁻ = F P Fᵀ + Q
        priors.append(x.copy())
        prior_covs.append(p.copy())
        transitions.append(f)
        r = np.array(fix["cov"]).reshape(2, 2)
        s = h @ p @ h.T + r  # S = H P Hᵀ + R
        k = p @ h.T @ np.linalg.inv(s)  # K = P Hᵀ S⁻¹
        x = x + k @ (np.array([fix["x"], fix["y"]]) - h @ x)
        p = (np.eye(4) - k @ h) @ p
        filtered.append(x.copy())
        covs.append(p.copy())
    smoothed = [None] * len(fixes)
    smoothed[-1] = filtered[-1]
    for k in range(len(fixes) - 2, -1, -1):
        c = covs[k] @ transitions[k + 1].T @ np.linalg.inv(prior_covs[k + 1])  # C = P F Pₖ₊₁⁻¹
        smoothed[k] = filtered[k] + c @ (smoothed[k + 1] - priors[k + 1])
    return filtered, smoothed


def rmse(fixes, states, tt, tx, ty, skip_s=2.0):
    start = fixes[0]["t"] + skip_s
    errors = [
        (s[0] - np.interp(f["t"], tt, tx)) ** 2 + (s[2] - np.interp(f["t"], tt, ty)) ** 2
        for f, s in zip(fixes, states)
        if f["t"] >= start
    ]
    return math.sqrt(np.mean(errors))


def main():
    out = sys.argv[1]
    runs = sorted(glob.glob(os.path.join(out, "ble", "*", "pl-ftf.fixes.jsonl")))
    if not runs:
        sys.exit(f"no BLE runs under {out}/ble (run scripts/evaluate.sh {out} first)")
    per_q = {q: ([], []) for q in QS}
    best = []
    for path in runs:
        run = os.path.basename(os.path.dirname(path))
        tt, tx, ty = truth(os.path.join(os.path.dirname(path), "truth.csv"))
        fixes = [json.loads(line) for line in open(path)]
        fixes = [f for f in fixes if tt[0] <= f["t"] <= tt[-1]]
        raw = rmse(fixes, [np.array([f["x"], 0, f["y"], 0]) for f in fixes], tt, tx, ty)
        filt, smooth = {}, {}
        for q in QS:
            a, b = kf_and_rts(fixes, q)
            filt[q], smooth[q] = rmse(fixes, a, tt, tx, ty), rmse(fixes, b, tt, tx, ty)
            per_q[q][0].append(filt[q])
            per_q[q][1].append(smooth[q])
        qf, qs = min(filt, key=filt.get), min(smooth, key=smooth.get)
        best.append((raw, filt[qf], smooth[qs]))
        print(f"{run:30} raw {raw:.2f} m  best filter {filt[qf]:.2f} m (q {qf:g})  "
              f"best smoother {smooth[qs]:.2f} m (q {qs:g})")
    raw, filt, smooth = np.mean(best, axis=0)
    print(f"{'mean of the runs':30} raw {raw:.2f} m  best filter {filt:.2f} m ({100 * (1 - filt / raw):.0f} %)  "
          f"best smoother {smooth:.2f} m ({100 * (1 - smooth / raw):.0f} %)")
    for q in QS:
        print(f"q {q:<6g} (every run): filter {np.mean(per_q[q][0]):.2f} m, smoother {np.mean(per_q[q][1]):.2f} m")


if __name__ == "__main__":
    main()
