"""Benchmark: HC4-revise contractors on 1e6 boxes, ours (vectorised, numba)
against Codac 2 objects driven from Python, plus the scalar numba path.

Run ``python benchmarks/bench_interval.py [--n N] [--repeat R]``. The last
line is ``interval_speedup_vs_codac <ratio>``: the smaller of the two
speed-ups (z = x + y, and z = sin(x)). Codac is a test-only dependency; without
it the script still times our paths and prints ratio ``nan``.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from numba import njit

from imubounds.interval import _ctc as k
from imubounds.interval import hc4_inplace
from imubounds.interval.rounding import round_to_nearest


def _boxes(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = rng.normal(0.0, 2.0, n)
    y = rng.normal(0.0, 2.0, n)
    return {
        "x": x,
        "y": y,
        "add": np.array([x + y - 0.05, x + y + 0.05, x - 0.1, x + 0.1, y - 0.1, y + 0.1]),
        "sin": np.array([np.sin(x) - 0.01, np.sin(x) + 0.02, x - 0.5, x + 0.5]),
    }


def _best(fn, data: np.ndarray, repeat: int) -> float:  # type: ignore[no-untyped-def]
    """Best wall time of ``fn(fresh copy of data)`` (the copy is not timed)."""
    fn(data.copy())  # compile / load the cache
    best = math.inf
    for _ in range(repeat):
        a = data.copy()
        t = time.perf_counter()
        fn(a)
        best = min(best, time.perf_counter() - t)
    return best


def time_ours(b: dict[str, np.ndarray], repeat: int) -> tuple[float, float]:
    def run_add(a: np.ndarray) -> None:
        hc4_inplace("add", a[0], a[1], a[2], a[3], a[4], a[5])

    def run_sin(a: np.ndarray) -> None:
        hc4_inplace("sin", a[0], a[1], a[2], a[3])

    return _best(run_add, b["add"], repeat), _best(run_sin, b["sin"], repeat)


@njit(cache=True)
def _scalar_loop_add(zlo, zhi, xlo, xhi, ylo, yhi):  # type: ignore[no-untyped-def]
    bad = 0
    for i in range(zlo.size):
        r = k.ctc_add(zlo[i], zhi[i], xlo[i], xhi[i], ylo[i], yhi[i], 3)
        zlo[i], zhi[i], xlo[i], xhi[i], ylo[i], yhi[i] = r[0], r[1], r[2], r[3], r[4], r[5]
        bad += r[6] >= 0
    return bad


@njit(cache=True)
def _scalar_loop_sin(zlo, zhi, xlo, xhi):  # type: ignore[no-untyped-def]
    bad = 0
    for i in range(zlo.size):
        r = k.ctc_sin(zlo[i], zhi[i], xlo[i], xhi[i], 3)
        zlo[i], zhi[i], xlo[i], xhi[i] = r[0], r[1], r[2], r[3]
        bad += r[6] >= 0
    return bad


def time_scalar(b: dict[str, np.ndarray], repeat: int) -> tuple[float, float]:
    def run_add(a: np.ndarray) -> None:
        _scalar_loop_add(a[0], a[1], a[2], a[3], a[4], a[5])

    def run_sin(a: np.ndarray) -> None:
        _scalar_loop_sin(a[0], a[1], a[2], a[3])

    return _best(run_add, b["add"], repeat), _best(run_sin, b["sin"], repeat)


def time_codac(b: dict[str, np.ndarray]) -> tuple[float, float, dict[str, np.ndarray]]:
    import codac  # NB: sets the process to round-upward, which codac relies on

    try:
        return _time_codac(codac, b)
    finally:
        round_to_nearest()  # our rules need round-to-nearest


def _time_codac(codac, b):  # type: ignore[no-untyped-def]

    Interval = codac.Interval
    add, sin = codac.AddOp, codac.SinOp
    a = [row.tolist() for row in b["add"]]
    n = len(a[0])
    out_add = np.empty((6, n))
    t = time.perf_counter()
    res = []
    for i in range(n):
        X = Interval(a[2][i], a[3][i])
        Y = Interval(a[4][i], a[5][i])
        Z = Interval(a[0][i], a[1][i])
        Z &= add.fwd(X, Y)
        add.bwd(Z, X, Y)
        res.append((Z.lb(), Z.ub(), X.lb(), X.ub(), Y.lb(), Y.ub()))
    t_add = time.perf_counter() - t
    out_add[:] = np.array(res).T
    s = [row.tolist() for row in b["sin"]]
    t = time.perf_counter()
    res = []
    for i in range(n):
        X = Interval(s[2][i], s[3][i])
        Z = Interval(s[0][i], s[1][i])
        Z &= sin.fwd(X)
        sin.bwd(Z, X)
        res.append((Z.lb(), Z.ub(), X.lb(), X.ub()))
    t_sin = time.perf_counter() - t
    out_sin = np.array(res).T
    return t_add, t_sin, {"add": out_add, "sin": out_sin}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1_000_000, help="number of boxes")
    ap.add_argument("--repeat", type=int, default=5, help="timing repeats (best is kept)")
    args = ap.parse_args()
    n = args.n
    b = _boxes(n)
    v_add, v_sin = time_ours(b, args.repeat)
    s_add, s_sin = time_scalar(b, args.repeat)
    print(f"boxes: {n}")
    print(f"ours vectorised  HC4 z=x+y   : {v_add * 1e3:9.2f} ms  ({v_add / n * 1e9:6.1f} ns/box)")
    print(f"ours vectorised  HC4 z=sin(x): {v_sin * 1e3:9.2f} ms  ({v_sin / n * 1e9:6.1f} ns/box)")
    print(f"ours scalar njit HC4 z=x+y   : {s_add * 1e3:9.2f} ms  ({s_add / n * 1e9:6.1f} ns/box)")
    print(f"ours scalar njit HC4 z=sin(x): {s_sin * 1e3:9.2f} ms  ({s_sin / n * 1e9:6.1f} ns/box)")
    try:
        c_add, c_sin, ref = time_codac(b)
    except ImportError:
        print("codac not installed: no comparison")
        print("interval_speedup_vs_codac nan")
        return
    print(f"codac (Python)   HC4 z=x+y   : {c_add * 1e3:9.2f} ms  ({c_add / n * 1e9:6.1f} ns/box)")
    print(f"codac (Python)   HC4 z=sin(x): {c_sin * 1e3:9.2f} ms  ({c_sin / n * 1e9:6.1f} ns/box)")
    # agreement: our domains within a few ulp of Codac's (both enclose the truth)
    round_to_nearest()
    a = b["add"].copy()
    hc4_inplace("add", a[0], a[1], a[2], a[3], a[4], a[5])
    s = b["sin"].copy()
    hc4_inplace("sin", s[0], s[1], s[2], s[3])
    d_add = np.nanmax(np.abs(a - ref["add"]))
    d_sin = np.nanmax(np.abs(s - ref["sin"]))
    print(f"max |ours - codac| endpoint difference: add {d_add:.3g}, sin {d_sin:.3g}")
    r_add = c_add / v_add
    r_sin = c_sin / v_sin
    print(f"speed-up vs codac: add {r_add:.0f}x, sin {r_sin:.0f}x "
          f"(scalar njit path: add {c_add / s_add:.0f}x, sin {c_sin / s_sin:.0f}x)")
    print(f"interval_speedup_vs_codac {min(r_add, r_sin):.1f}")


if __name__ == "__main__":
    main()
