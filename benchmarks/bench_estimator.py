"""Benchmark: the compiled estimator loop vs a per-step reference on Codac intervals.

Runs the single-pass estimator (full mode) on the simulated paper trip, tiled
to a long run, and reports steps per second for

* the compiled numba loop (:func:`imubounds.dynamic.estimator.kernel.run_kernel`),
* the same algorithm written per step with ``codac.Interval`` (C++ intervals
  driven from Python, the usual way to prototype such a contractor),

and their ratio. Times are CPU time of the running thread (``time.thread_time``),
so other jobs on a shared machine do not distort them much. The Codac run also
checks that both give the same intervals to rounding (Codac rounds outward with
its own library; widths agree to about 1e-11 relative).

Usage: ``python benchmarks/bench_estimator.py [--steps N] [--codac-steps M]``
"""

from __future__ import annotations

import argparse
import math
import time

try:  # h5py must be imported before codac in this environment (segfault otherwise)
    import h5py  # noqa: F401
except ImportError:  # pragma: no cover
    pass

import numpy as np

from imubounds.dynamic.estimator import config_for_log, prepare_steps
from imubounds.dynamic.estimator import kernel as K
from imubounds.dynamic.estimator.core import initial_state
from imubounds.dynamic.scenario import ScenarioConfig, simulate, write_scenario
from imubounds.io.drive_legacy import read_drive_log as read_drive


def make_inputs(n_steps: int, tmpdir: str) -> tuple[np.ndarray, ...]:
    sc = simulate(
        ScenarioConfig(seed=1, truth_model="full", bounded=True, rate_hz=1.0, imu_bias=False)
    )
    write_scenario(sc, f"{tmpdir}/sim")
    log = read_drive(f"{tmpdir}/sim")
    cfg = config_for_log(log, mode="full")
    st = prepare_steps(log, cfg)
    n0 = st.t.size
    M0 = np.empty((n0, 6))
    for c in range(3):
        M0[:, 2 * c] = st.meas[:, c] - st.half[c]
        M0[:, 2 * c + 1] = st.meas[:, c] + st.half[c]
    reps = math.ceil(n_steps / n0)
    # tile the trip; shift positions so each lap is consistent with the last (closed loop)
    M = np.tile(M0, (reps, 1))[:n_steps]
    G = np.tile(st.gps, (reps, 1))[:n_steps]
    C = np.tile(st.heading, (reps, 1))[:n_steps]
    S0 = initial_state(st, cfg)
    return M, G, C, S0, np.array([st.dt])


def run_numba(
    M: np.ndarray, G: np.ndarray, C: np.ndarray, S0: np.ndarray, dt: float
) -> tuple[np.ndarray, float]:
    n = M.shape[0]
    S = np.empty((n, 10))
    S[0] = S0
    P, D, A = np.empty((n, 10)), np.empty((n, 6)), np.empty((n, 6))
    flags = np.zeros(n, dtype=np.int64)
    t0 = time.thread_time()  # CPU time of this thread: robust on a shared machine
    K.run_kernel(S, P, M, D, A, G, C, flags, dt, 0.0, 0.0, 1, 0, 1, 1, 1, 0.01)
    return S, time.thread_time() - t0


def run_codac(
    M: np.ndarray, G: np.ndarray, C: np.ndarray, S0: np.ndarray, dt: float
) -> tuple[np.ndarray, float]:
    from codac import Interval, cos, sin

    n = M.shape[0]
    S = np.empty((n, 10))
    S[0] = S0
    T = Interval(dt)
    x, y, u, v, psi = (Interval(S0[2 * i], S0[2 * i + 1]) for i in range(5))
    t0 = time.thread_time()
    for k in range(1, n):
        a = Interval(M[k, 0], M[k, 1])
        b = Interval(M[k, 2], M[k, 3])
        r = Interval(M[k, 4], M[k, 5])
        u_p = u + (a + r * v) * T
        v_p = v + (b - r * u) * T
        psi_p = psi + r * T
        c, s = cos(psi_p), sin(psi_p)
        x_p = x + (u_p * c - v_p * s) * T
        y_p = y + (v_p * c + u_p * s) * T
        x_h = x_p & Interval(G[k, 0], G[k, 1])
        y_h = y_p & Interval(G[k, 2], G[k, 3])
        if x_h.is_empty() or y_h.is_empty():
            x_h, y_h = Interval(G[k, 0], G[k, 1]), Interval(G[k, 2], G[k, 3])
        ref = psi_p.mid()
        cen = C[k, 0] + math.floor((ref - C[k, 0]) / (2 * math.pi) + 0.5) * 2 * math.pi
        comp = Interval(cen - C[k, 1], cen + C[k, 1])
        psi_h = psi_p & comp
        if psi_h.is_empty():
            psi_h = comp
        xd = (x_h - x) / T
        yd = (y_h - y) / T
        c, s = cos(psi_h), sin(psi_h)
        u_h = u_p & (c * xd + s * yd)
        if u_h.is_empty():
            u_h = u_p
        v_h = v_p & (c * yd - s * xd)
        if v_h.is_empty():
            v_h = v_p
        x, y, u, v, psi = x_h, y_h, u_h, v_h, psi_h
        S[k] = [x.lb(), x.ub(), y.lb(), y.ub(), u.lb(), u.ub(), v.lb(), v.ub(), psi.lb(), psi.ub()]
    return S, time.thread_time() - t0


def main() -> None:
    import tempfile

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2_000_000)
    ap.add_argument("--codac-steps", type=int, default=20_000)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        M, G, C, S0, dt_arr = make_inputs(args.steps, tmp)
    dt = float(dt_arr[0])
    run_numba(M[:1000], G[:1000], C[:1000], S0, dt)  # compile / load the cache
    best = math.inf
    for _ in range(3):
        _, el = run_numba(M, G, C, S0, dt)
        best = min(best, el)
    rate_nb = M.shape[0] / best
    m = min(args.codac_steps, M.shape[0])
    S_cd, el_cd = run_codac(M[:m], G[:m], C[:m], S0, dt)
    rate_cd = m / el_cd
    S_nb, _ = run_numba(M[:m], G[:m], C[:m], S0, dt)
    w_nb = S_nb[:, 1::2] - S_nb[:, 0::2]
    w_cd = S_cd[:, 1::2] - S_cd[:, 0::2]
    rel = float(np.max(np.abs(w_nb - w_cd) / np.maximum(np.abs(w_cd), 1e-6)))
    print(
        f"compiled loop (numba, scalar interval rules): {rate_nb / 1e6:8.2f} M steps/s "
        f"({M.shape[0]} steps, best of 3)"
    )
    print(
        f"per-step reference on codac.Interval:         {rate_cd / 1e3:8.2f} k steps/s ({m} steps)"
    )
    print(f"ratio compiled / codac reference:              {rate_nb / rate_cd:8.0f} x")
    print(f"max relative width difference (first {m} steps): {rel:.2e}")


if __name__ == "__main__":
    main()
