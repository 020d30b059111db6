#!/usr/bin/env python3
"""Golden test vectors for rtls-estimation, generated with FilterPy 2.0.0.

Run from the repository root:

    python3 crates/rtls-estimation/tests/golden/generate.py

Writes ``filterpy_vectors.json`` next to this file. The output is
deterministic: every scenario draws from its own
``numpy.random.default_rng(<fixed seed>)``.

Conventions (shared with the Rust crate)
----------------------------------------
* State ``x = [x, vx, y, vy]`` (2-D constant velocity).
* ``F(dt) = blockdiag([[1, dt], [0, 1]], [[1, dt], [0, 1]])``.
* ``Q(dt) = blockdiag(s2 * G G^T, s2 * G G^T)`` with ``G = [dt^2/2, dt]``
  (discrete white-noise acceleration, per axis).
* ``t_0 = 0``; ``dt_k ~ U[0.5, 1.5]`` s. ``steps[k]`` is one predict (by
  ``steps[k].dt``, from ``t = steps[k].t - steps[k].dt`` to ``steps[k].t``)
  followed by an update when ``z`` is not null. ``steps[0]`` predicts from
  ``x0``/``P0`` at ``t = 0``.
* Matrices are row-major nested lists; floats are written with Python's
  shortest round-trip ``repr`` (full double precision).

What FilterPy 2.0.0 actually computes (read from the installed source)
---------------------------------------------------------------------
KalmanFilter (kalman/kalman_filter.py)
  predict:  x = F x ;  P = _alpha_sq * (F P F^T) + Q   (_alpha_sq = 1.0)
  update:   y = z - H x ; PHT = P H^T ; S = H PHT + R ;
            SI = numpy.linalg.inv(S) ; K = PHT SI ; x = x + K y
            I_KH = I - K H
            P = (I_KH P) I_KH^T + (K R) K^T          <- Joseph form, no
                                                       symmetrisation
  update(None): x, P unchanged (posterior = prior).
  rts_smoother(Xs, Ps, Fs, Qs) (the *method*, lines ~1066-1072):
        for k in range(n-2, -1, -1):
            Pp[k] = dot(dot(Fs[k+1], P[k]), Fs[k+1].T) + Qs[k+1]
            K[k]  = dot(dot(P[k], Fs[k+1].T), inv(Pp[k]))
            x[k] += dot(K[k], x[k+1] - dot(Fs[k+1], x[k]))
            P[k] += dot(dot(K[k], P[k+1] - Pp[k]), K[k].T)
    i.e. the k -> k+1 transition uses Fs[k+1]/Qs[k+1]: Fs[i]/Qs[i] are the
    matrices of the predict that *produced* step i. We therefore pass
    Fs[i] = F(steps[i].dt), Qs[i] = Q(steps[i].dt) unshifted (Fs[0]/Qs[0]
    are never read). NB: the module-level function
    ``filterpy.kalman.rts_smoother`` uses Fs[k]/Qs[k] instead (opposite
    convention); we do not use it.

ExtendedKalmanFilter (kalman/EKF.py)
  predict:  x = F x + B u (B = 0, u = 0) ; P = (F P) F^T + Q
  update:   H = HJacobian(x_prior) ; PHT = P H^T ; S = H PHT + R ;
            SI = scipy.linalg.inv(S) ; K = PHT SI ;
            y = z - Hx(x_prior)  (residual=np.subtract) ; x = x + K y ;
            I_KH = I - K H ; P = (I_KH P) I_KH^T + (K R) K^T  <- Joseph form
  The Jacobian is evaluated once, at the prior mean (no iteration).
  dim_z given to the constructor is only used for the z=None bookkeeping;
  the measurement size per update is whatever H/R/z are (variable here).

UnscentedKalmanFilter (kalman/UKF.py, sigma_points.py,
unscented_transform.py)
  MerweScaledSigmaPoints: lambda = alpha^2 (n + kappa) - n
      Wm = Wc = 0.5/(n+lambda) ; Wm[0] = lambda/(n+lambda) ;
      Wc[0] = lambda/(n+lambda) + (1 - alpha^2 + beta)
      U = scipy.linalg.cholesky((lambda + n) * P)   (UPPER, U^T U = (n+l)P)
      sigmas[0] = x ; sigmas[k+1] = x + U[k] ; sigmas[n+k+1] = x - U[k]
      (row k of the upper factor == column k of the lower factor L = U^T,
       and the factor is of (n+lambda)*P, not sqrt(n+lambda)*chol(P))
  unscented_transform(sigmas, Wm, Wc, noise):
      x = Wm @ sigmas ; y = sigmas - x ; P = y^T (diag(Wc) y) + noise
  predict(dt):  sigmas = sigma_points(x, P) ; sigmas_f[i] = fx(sigmas[i], dt)
                x, P = UT(sigmas_f, Wm, Wc, Q)
                self.sigmas_f = self.points_fn.sigma_points(self.x, self.P)
      -> after predict the propagated points are DISCARDED and the sigma
         points are REDRAWN from the predicted (x_prior, P_prior) (which
         already contains Q). The update uses these redrawn points.
  update(z, R): sigmas_h[i] = hx(sigmas_f[i]) (redrawn points) ;
                zp, S = UT(sigmas_h, Wm, Wc, R) ; SI = numpy.linalg.inv(S)
                Pxz = sum_i Wc[i] outer(sigmas_f[i] - x_prior, sigmas_h[i] - zp)
                K = Pxz SI ; y = z - zp ; x = x + K y
                P = P - K (S K^T)        <- plain form, NOT Joseph
  rts_smoother(Xs, Ps, Qs, dts):
        for k in reversed(range(n-1)):
            sigmas = self.points_fn.sigma_points(xs[k], ps[k])   # filtered
            for i in range(num_sigmas):
                sigmas_f[i] = self.fx(sigmas[i], dts[k])
            xb, Pb = UT(sigmas_f, self.Wm, self.Wc, self.Q, ...)
            Pxb = sum_i Wc[i] outer(sigmas[i] - Xs[k], sigmas_f[i] - xb)
            K = dot(Pxb, self.inv(Pb))
            xs[k] += dot(K, xs[k+1] - xb)
            ps[k] += dot(K, ps[k+1] - Pb).dot(K.T)
    Two traps:
      (a) dts[k] is used for the k -> k+1 step (opposite to the KF method's
          Fs[k+1]); so dts[k] must be steps[k+1].dt.
      (b) the ``Qs`` argument is accepted but NEVER USED: ``self.Q`` (whatever
          Q the filter holds when rts_smoother is called) is added to Pb for
          every k. With irregular dt this is wrong.
    To get the model-correct smoother (Q(steps[k+1].dt) on the k -> k+1
    step) while still using FilterPy's own arithmetic, we run FilterPy's
    rts_smoother one backward step at a time on 2-element inputs
    [filtered_k, smoothed_{k+1}] with ukf.Q = Q(steps[k+1].dt) and
    dts = [steps[k+1].dt, steps[k+1].dt]. For k in that 2-element call
    xs[0] = Xs[0] = filtered_k, so the arithmetic is identical to one
    iteration of the full call; this script asserts the chained result is
    bit-identical to a single full call when Q is held constant, and that
    the ``Qs`` argument indeed has no effect.

Scenarios and RNG usage are described in README.md. The truth trajectory is
not written (schema is fixed); per step the draws are, in order:
dt ~ U[0.5, 1.5]; process-noise accelerations a_x, a_y ~ N(0, s2)
(w = [G a_x, G a_y], i.e. an exact draw from the rank-2 Q(dt)); then the
measurement-related draws of the scenario.
"""

import json
import os

import numpy as np
import scipy
import scipy.linalg
import scipy.stats

import filterpy
from filterpy.kalman import (ExtendedKalmanFilter, KalmanFilter,
                             MerweScaledSigmaPoints, UnscentedKalmanFilter)

assert filterpy.__version__ == "2.0.0", filterpy.__version__

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "filterpy_vectors.json")

N_STEPS = 40


# --------------------------------------------------------------------------
# model
# --------------------------------------------------------------------------
def F_cv(dt):
    return np.array([[1.0, dt, 0.0, 0.0],
                     [0.0, 1.0, 0.0, 0.0],
                     [0.0, 0.0, 1.0, dt],
                     [0.0, 0.0, 0.0, 1.0]])


def Q_cv(dt, s2):
    g = np.array([dt * dt / 2.0, dt])
    q = s2 * np.outer(g, g)
    Q = np.zeros((4, 4))
    Q[0:2, 0:2] = q
    Q[2:4, 2:4] = q
    return Q


def fx_cv(x, dt):
    return F_cv(dt) @ x


def ranges(x, anchors):
    return np.array([np.hypot(x[0] - a[0], x[2] - a[1]) for a in anchors])


def range_jacobian(x, anchors):
    H = np.zeros((len(anchors), 4))
    for i, a in enumerate(anchors):
        dx, dy = x[0] - a[0], x[2] - a[1]
        r = np.hypot(dx, dy)
        H[i, 0] = dx / r
        H[i, 2] = dy / r
    return H


def simulate_truth_step(rng, xt, s2):
    """Draws dt, then (a_x, a_y); returns (dt, new truth)."""
    dt = float(rng.uniform(0.5, 1.5))
    g = np.array([dt * dt / 2.0, dt])
    a = rng.normal(0.0, np.sqrt(s2), size=2)
    w = np.concatenate([g * a[0], g * a[1]])
    return dt, F_cv(dt) @ xt + w


# --------------------------------------------------------------------------
# JSON helpers
# --------------------------------------------------------------------------
def vec(v):
    return [float(e) for e in np.asarray(v, dtype=float).ravel()]


def mat(m):
    m = np.atleast_2d(np.asarray(m, dtype=float))
    return [[float(e) for e in row] for row in m]


def step_record(t, dt, z, anchor_idx, xp, Pp, xu, Pu, y, S, ranged):
    rec = {"t": float(t), "dt": float(dt),
           "z": None if z is None else vec(z)}
    if ranged:
        rec["anchor_indices"] = [] if anchor_idx is None else [int(i) for i in anchor_idx]
    rec.update({
        "prior_x": vec(xp), "prior_P": mat(Pp),
        "posterior_x": vec(xu), "posterior_P": mat(Pu),
        "innovation": None if y is None else vec(y),
        "S": None if S is None else mat(S),
    })
    return rec


# --------------------------------------------------------------------------
# 1. linear KF, correlated position measurement, KF RTS smoother
# --------------------------------------------------------------------------
def scenario_kf_position(seed=1001):
    rng = np.random.default_rng(seed)
    s2 = 0.5
    R = np.array([[4.0, 1.0], [1.0, 9.0]])
    L = np.linalg.cholesky(R)
    x0 = np.array([0.0, 1.0, 0.0, 0.5])
    P0 = np.diag([10.0, 2.0, 10.0, 2.0])
    H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])

    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.x = x0.copy()          # 1-D state: z/y are 1-D as well
    kf.P = P0.copy()
    kf.H = H.copy()
    kf.R = R.copy()

    xt = x0 + np.linalg.cholesky(P0) @ rng.standard_normal(4)
    t = 0.0
    steps, Xs, Ps, Fs, Qs, truth = [], [], [], [], [], []
    for k in range(N_STEPS):
        dt, xt = simulate_truth_step(rng, xt, s2)
        t += dt
        z = H @ xt + L @ rng.standard_normal(2)   # always drawn (keeps RNG stream simple)
        if k % 7 == 3:
            z = None
        F, Q = F_cv(dt), Q_cv(dt, s2)
        kf.predict(F=F, Q=Q)
        xp, Pp = kf.x.copy(), kf.P.copy()
        kf.update(z)
        y = None if z is None else kf.y.copy()
        S = None if z is None else kf.S.copy()
        steps.append(step_record(t, dt, z, None, xp, Pp, kf.x, kf.P, y, S, False))
        Xs.append(kf.x.copy())
        Ps.append(kf.P.copy())
        Fs.append(F)
        Qs.append(Q)
        truth.append(xt.copy())

    Xs, Ps = np.array(Xs), np.array(Ps)
    # Fs[i]/Qs[i] = matrices of the predict INTO step i; the method reads
    # Fs[k+1]/Qs[k+1] for the k -> k+1 step (see module docstring).
    xs, ps, _, _ = kf.rts_smoother(Xs, Ps, Fs, Qs)

    sc = {"x0": vec(x0), "P0": mat(P0), "sigma2": s2, "anchors": [], "R": mat(R),
          "steps": steps, "smoothed_x": mat(xs),
          "smoothed_P": [mat(p) for p in ps]}
    return sc, np.array(truth)


# --------------------------------------------------------------------------
# 2. EKF with a varying subset of range anchors
# --------------------------------------------------------------------------
def scenario_ekf_range(seed=1002):
    rng = np.random.default_rng(seed)
    s2 = 0.3
    anchors = np.array([[0.0, 0.0], [30.0, 5.0], [10.0, 40.0], [-20.0, 25.0]])
    rvar = 0.25
    x0 = np.array([5.0, 0.8, 5.0, 0.6])
    P0 = np.diag([4.0, 1.0, 4.0, 1.0])

    ekf = ExtendedKalmanFilter(dim_x=4, dim_z=4)
    ekf.x = x0.copy()
    ekf.P = P0.copy()

    xt = x0 + np.linalg.cholesky(P0) @ rng.standard_normal(4)
    t = 0.0
    steps, truth = [], []
    for k in range(N_STEPS):
        dt, xt = simulate_truth_step(rng, xt, s2)
        t += dt
        # subset: size m ~ U{1..4}, then m distinct anchors in random order
        # (z, R and anchor_indices follow that order, unsorted on purpose)
        m = int(rng.integers(1, 5))
        idx = rng.choice(4, size=m, replace=False)
        z = ranges(xt, anchors[idx]) + rng.normal(0.0, np.sqrt(rvar), size=m)
        if k % 9 == 5:
            z, idx = None, None

        ekf.F = F_cv(dt)
        ekf.Q = Q_cv(dt, s2)
        ekf.predict()
        xp, Pp = ekf.x.copy(), ekf.P.copy()
        if z is None:
            ekf.update(None, None, None)
            y = S = None
        else:
            a = anchors[idx]
            ekf.update(z, HJacobian=lambda x, a=a: range_jacobian(x, a),
                       Hx=lambda x, a=a: ranges(x, a),
                       R=np.eye(m) * rvar)
            y, S = ekf.y.copy(), ekf.S.copy()
        steps.append(step_record(t, dt, z, idx, xp, Pp, ekf.x, ekf.P, y, S, True))
        truth.append(xt.copy())

    sc = {"x0": vec(x0), "P0": mat(P0), "sigma2": s2, "anchors": mat(anchors),
          "range_variance": rvar, "steps": steps}
    return sc, np.array(truth)


# --------------------------------------------------------------------------
# 3./4. UKF ranges + UKF RTS smoother
# --------------------------------------------------------------------------
def ukf_smooth_model_correct(ukf, Xs, Ps, dts_in, s2):
    """UKF RTS smoother with Q(dt_{k+1}) on the k -> k+1 step, using
    FilterPy's rts_smoother one backward step at a time (see docstring).

    dts_in[i] = dt of the predict INTO step i.
    """
    n = len(Xs)
    xs, ps = Xs.copy(), Ps.copy()
    for k in range(n - 2, -1, -1):
        dt_next = dts_in[k + 1]
        ukf.Q = Q_cv(dt_next, s2)
        x2, p2, _ = ukf.rts_smoother(np.array([Xs[k], xs[k + 1]]),
                                     np.array([Ps[k], ps[k + 1]]),
                                     dts=[dt_next, dt_next])
        xs[k], ps[k] = x2[0], p2[0]
    return xs, ps


def scenario_ukf_range(seed, anchors, alpha, beta, kappa):
    rng = np.random.default_rng(seed)
    s2 = 0.01
    anchors = np.asarray(anchors, dtype=float)
    rvar = 0.09
    na = len(anchors)
    x0 = np.array([2.0, 0.1, 10.0, 0.5])
    P0 = np.diag([1.0, 0.1, 1.0, 0.1])

    points = MerweScaledSigmaPoints(4, alpha=alpha, beta=beta, kappa=kappa)
    ukf = UnscentedKalmanFilter(dim_x=4, dim_z=na, dt=1.0,
                                hx=lambda x: ranges(x, anchors),
                                fx=fx_cv, points=points)
    ukf.x = x0.copy()
    ukf.P = P0.copy()
    R = np.eye(na) * rvar

    xt = x0 + np.linalg.cholesky(P0) @ rng.standard_normal(4)
    t = 0.0
    steps, Xs, Ps, dts, truth = [], [], [], [], []
    for k in range(N_STEPS):
        dt, xt = simulate_truth_step(rng, xt, s2)
        t += dt
        z = ranges(xt, anchors) + rng.normal(0.0, np.sqrt(rvar), size=na)
        ukf.Q = Q_cv(dt, s2)
        ukf.predict(dt=dt)
        xp, Pp = ukf.x.copy(), ukf.P.copy()
        ukf.update(z, R=R)
        steps.append(step_record(t, dt, z, np.arange(na), xp, Pp, ukf.x, ukf.P,
                                 ukf.y, ukf.S, True))
        Xs.append(ukf.x.copy())
        Ps.append(ukf.P.copy())
        dts.append(dt)
        truth.append(xt.copy())
    Xs, Ps = np.array(Xs), np.array(Ps)

    xs, ps = ukf_smooth_model_correct(ukf, Xs, Ps, dts, s2)

    # --- self-checks of the FilterPy rts_smoother reading -----------------
    dts_shift = dts[1:] + [dts[-1]]          # dts[k] is used for k -> k+1
    Qs_shift = [Q_cv(d, s2) for d in dts_shift]
    ukf.Q = Q_cv(1.0, s2)
    ref, refp, _ = ukf.rts_smoother(Xs, Ps, Qs=Qs_shift, dts=dts_shift)
    # (b) Qs is ignored: garbage Qs gives bit-identical output
    junk, junkp, _ = ukf.rts_smoother(Xs, Ps, Qs=[np.eye(4) * 1e6] * len(Xs), dts=dts_shift)
    assert np.array_equal(ref, junk) and np.array_equal(refp, junkp), "UKF rts Qs is used?"
    # chained 2-point calls == one full call when Q is constant (bitwise)
    n = len(Xs)
    cx, cp = Xs.copy(), Ps.copy()
    for k in range(n - 2, -1, -1):
        x2, p2, _ = ukf.rts_smoother(np.array([Xs[k], cx[k + 1]]),
                                     np.array([Ps[k], cp[k + 1]]),
                                     dts=[dts_shift[k], dts_shift[k]])
        cx[k], cp[k] = x2[0], p2[0]
    assert np.array_equal(cx, ref) and np.array_equal(cp, refp), "chaining not exact"
    # the model-correct result must differ from the constant-Q one
    assert not np.allclose(xs, ref, rtol=0, atol=1e-12)

    sc = {"x0": vec(x0), "P0": mat(P0), "sigma2": s2, "anchors": mat(anchors),
          "range_variance": rvar,
          "ukf": {"alpha": float(alpha), "beta": float(beta), "kappa": float(kappa)},
          "steps": steps, "smoothed_x": mat(xs), "smoothed_P": [mat(p) for p in ps]}
    return sc, np.array(truth)


# --------------------------------------------------------------------------
# 5. chi-square table
# --------------------------------------------------------------------------
CHI2_P = [0.001, 0.025, 0.05, 0.5, 0.95, 0.975, 0.99, 0.999]
CHI2_DOF = [1, 2, 3, 4, 6, 9, 20, 100, 1000]
CHI2_X_FIXED = [0.01, 0.1, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0]
CHI2_X_REL = [0.5, 0.9, 1.0, 1.1, 1.5]     # x = f * dof


def chi2_tables():
    ppf = [{"p": p, "dof": d, "ppf": float(scipy.stats.chi2.ppf(p, d))}
           for d in CHI2_DOF for p in CHI2_P]
    cdf = []
    for d in CHI2_DOF:
        xs = sorted(set(CHI2_X_FIXED) | {float(f * d) for f in CHI2_X_REL})
        cdf.extend({"x": x, "dof": d, "cdf": float(scipy.stats.chi2.cdf(x, d))}
                   for x in xs)
    return ppf, cdf


# --------------------------------------------------------------------------
def main():
    out_truth = {}
    scenarios = {}
    scenarios["kf_position"], out_truth["kf_position"] = scenario_kf_position()
    scenarios["ekf_range"], out_truth["ekf_range"] = scenario_ekf_range()
    # Seed 34 (not 1): with only two anchors the position is ambiguous up to
    # the mirror image across the anchor baseline; with seed 1 the truth
    # crosses that line and the filter (correctly) loses it. Seed 34 keeps
    # the truth >= 5 m on x0's side of the baseline (asserted below).
    scenarios["ukf_range_001"], out_truth["ukf_range_001"] = scenario_ukf_range(
        seed=34, anchors=[[2.0, 2.0], [20.0, 40.0]], alpha=0.01, beta=2.0, kappa=0.0)
    scenarios["ukf_range_wide"], out_truth["ukf_range_wide"] = scenario_ukf_range(
        seed=2, anchors=[[2.0, 2.0], [20.0, 40.0], [35.0, 5.0]],
        alpha=0.5, beta=2.0, kappa=-1.0)
    ppf, cdf = chi2_tables()

    doc = {"filterpy_version": filterpy.__version__,
           "scenarios": scenarios,
           "chi2": ppf,
           "chi2_cdf": cdf}

    # sanity: SPD posteriors (and smoothed), UKF tracks
    for name, sc in scenarios.items():
        covs = [np.array(s["posterior_P"]) for s in sc["steps"]]
        covs += [np.array(p) for p in sc.get("smoothed_P", [])]
        for P in covs:
            assert np.allclose(P, P.T, rtol=0, atol=1e-9 * max(1.0, np.abs(P).max())), name
            assert np.linalg.eigvalsh(0.5 * (P + P.T)).min() > 0, name
        if name.startswith("ukf"):
            err = np.hypot(*(np.array(sc["steps"][-1]["posterior_x"])[[0, 2]]
                             - out_truth[name][-1][[0, 2]]))
            assert err < 1.0, (name, err)
    # two-anchor scenario: truth never comes near the mirror line (baseline)
    a = np.array(scenarios["ukf_range_001"]["anchors"])
    d = a[1] - a[0]
    nrm = np.array([-d[1], d[0]]) / np.hypot(d[0], d[1])
    side = (out_truth["ukf_range_001"][:, [0, 2]] - a[0]) @ nrm
    assert side.min() > 2.0, side.min()

    with open(OUT, "w") as f:
        json.dump(doc, f, indent=1, allow_nan=False)
        f.write("\n")
    print("wrote", os.path.relpath(OUT))


if __name__ == "__main__":
    main()
