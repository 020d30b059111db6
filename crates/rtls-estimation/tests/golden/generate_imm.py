#!/usr/bin/env python3
"""Golden vectors for the IMM, from FilterPy 2.0.0's ``IMMEstimator``.

Writes ``imm_vectors.json`` next to this file. FilterPy's IMM requires every mode to share
one state vector, so these cases use constant-velocity modes ``[x, vx, y, vy]`` that differ in
process noise; our IMM must reproduce FilterPy's mode probabilities, mode-conditioned
posteriors and combined estimate exactly (the layout conversions are then identities).

    pip install filterpy==2.0.0 scipy numpy
    python3 crates/rtls-estimation/tests/golden/generate_imm.py

FilterPy details matched by the Rust test (tests/golden_imm.rs):
* ``IMMEstimator.predict()`` mixes with the mixing probabilities computed at the end of the
  previous ``update`` (or at construction) and then predicts each filter: the same as our
  ``predict`` computing c̄ and μ_{i|j} from the current probabilities.
* Each mode's likelihood is ``KalmanFilter.likelihood`` = N(y; 0, S) evaluated by
  ``scipy.stats.multivariate_normal``; ``mu = cbar * likelihood / sum``.
* After ``update``, ``imm.x``/``imm.P`` are the moment-matched combination of the posteriors.
"""
import json
import os

import numpy as np

import filterpy
from filterpy.kalman import IMMEstimator, KalmanFilter

from generate import F_cv, Q_cv, vec, mat

assert filterpy.__version__ == "2.0.0", filterpy.__version__

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "imm_vectors.json")


def make_kf(q, r, x0, P0):
    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.F = F_cv(1.0)
    kf.Q = Q_cv(1.0, q)
    kf.H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    kf.R = r.copy()
    kf.x = x0.copy()
    kf.P = P0.copy()
    return kf


def scenario(name, seed, qs, M, mu0, steps=60):
    rng = np.random.default_rng(seed)
    r = np.array([[4.0, 1.0], [1.0, 3.0]])
    x0 = np.array([0.0, 1.0, 0.0, 0.5])
    P0 = np.diag([10.0, 2.0, 10.0, 2.0])
    filters = [make_kf(q, r, x0, P0) for q in qs]
    imm = IMMEstimator(filters, np.array(mu0), np.array(M))
    truth = x0.copy()
    records = []
    for k in range(1, steps + 1):
        # manoeuvre: accelerate along x between steps 20 and 35, turn y-velocity at 40
        a = np.array([0.6 if 20 <= k < 35 else 0.0, -0.4 if 40 <= k < 45 else 0.0])
        truth = F_cv(1.0) @ truth + np.array([a[0] / 2, a[0], a[1] / 2, a[1]])
        z = np.array([truth[0], truth[2]]) + rng.multivariate_normal(np.zeros(2), r)
        imm.predict()
        prior_x = [vec(f.x) for f in filters]
        prior_P = [mat(f.P) for f in filters]
        imm.update(z)
        records.append({
            "z": vec(z),
            "mode_prior_x": prior_x,
            "mode_prior_P": prior_P,
            "mode_x": [vec(f.x) for f in filters],
            "mode_P": [mat(f.P) for f in filters],
            "mu": vec(imm.mu),
            "x": vec(imm.x),
            "P": mat(imm.P),
        })
    return {"name": name, "q": [float(q) for q in qs], "M": mat(M), "mu0": vec(mu0),
            "R": mat(r), "x0": vec(x0), "P0": mat(P0), "steps": records}


def main():
    doc = {
        "filterpy_version": filterpy.__version__,
        "generator": "crates/rtls-estimation/tests/golden/generate_imm.py",
        "scenarios": [
            scenario("two_cv_modes", 2001, [0.001, 0.5], [[0.97, 0.03], [0.05, 0.95]], [0.6, 0.4]),
            scenario("three_cv_modes", 2002, [0.0005, 0.05, 2.0],
                     [[0.9, 0.05, 0.05], [0.1, 0.8, 0.1], [0.02, 0.08, 0.9]], [1 / 3, 1 / 3, 1 / 3]),
        ],
    }
    with open(OUT, "w") as f:
        json.dump(doc, f, allow_nan=False)
    print("wrote", OUT)


if __name__ == "__main__":
    main()
