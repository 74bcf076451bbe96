"""Benchmark: the HC4-revise contractors the estimator's smoother runs
(``z = x + y``, ``z = x * y``, scalar numba functions in a compiled loop) on
1e6 boxes, against Codac 2 objects driven from Python.

Run ``python benchmarks/bench_interval.py [--n N] [--repeat R]``. The last
line is ``interval_speedup_vs_codac <ratio>``: the smaller of the two
speed-ups. Codac is a test-only dependency; without it the script still times
our path and prints ratio ``nan``.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from numba import njit

from imubounds.interval import scalar_contractors as k
from imubounds.interval.rounding import round_to_nearest

OPS = ("add", "mul")


def _boxes(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """(6, n) endpoints z, x, y around x + y (add) and x * y (mul) solutions."""
    rng = np.random.default_rng(seed)
    x = rng.normal(0.0, 2.0, n)
    y = rng.normal(0.0, 2.0, n)
    return {
        "add": np.array([x + y - 0.05, x + y + 0.05, x - 0.1, x + 0.1, y - 0.1, y + 0.1]),
        "mul": np.array([x * y - 0.05, x * y + 0.05, x - 0.1, x + 0.1, y - 0.1, y + 0.1]),
    }


@njit(cache=True)
def _loop(op, zlo, zhi, xlo, xhi, ylo, yhi):
    bad = 0
    for i in range(zlo.size):
        if op == 0:
            r = k.ctc_add(zlo[i], zhi[i], xlo[i], xhi[i], ylo[i], yhi[i], 3)
        else:
            r = k.ctc_mul(zlo[i], zhi[i], xlo[i], xhi[i], ylo[i], yhi[i], 3)
        zlo[i], zhi[i], xlo[i], xhi[i], ylo[i], yhi[i] = r[0], r[1], r[2], r[3], r[4], r[5]
        bad += r[6] >= 0
    return bad


def time_ours(op: str, data: np.ndarray, repeat: int) -> tuple[float, np.ndarray]:
    """Best wall time over ``repeat`` runs on fresh copies (copy not timed)."""
    code = OPS.index(op)
    out = data.copy()
    _loop(code, *out)  # compile / load the cache
    best = math.inf
    for _ in range(repeat):
        a = data.copy()
        t = time.perf_counter()
        _loop(code, *a)
        best = min(best, time.perf_counter() - t)
    return best, out


def time_codac(op: str, data: np.ndarray) -> tuple[float, np.ndarray]:
    import codac  # NB: sets the process to round-upward, which codac relies on

    try:
        cls = {"add": codac.AddOp, "mul": codac.MulOp}[op]
        Interval = codac.Interval
        a = [row.tolist() for row in data]
        res = []
        t = time.perf_counter()
        for i in range(len(a[0])):
            X = Interval(a[2][i], a[3][i])
            Y = Interval(a[4][i], a[5][i])
            Z = Interval(a[0][i], a[1][i])
            Z &= cls.fwd(X, Y)
            cls.bwd(Z, X, Y)
            res.append((Z.lb(), Z.ub(), X.lb(), X.ub(), Y.lb(), Y.ub()))
        return time.perf_counter() - t, np.array(res).T
    finally:
        round_to_nearest()  # our rules need round-to-nearest


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--n", type=int, default=1_000_000, help="number of boxes")
    ap.add_argument("--repeat", type=int, default=5, help="timing repeats (best is kept)")
    args = ap.parse_args()
    n = args.n
    boxes = _boxes(n)
    ours = {op: time_ours(op, boxes[op], args.repeat) for op in OPS}
    print(f"boxes: {n}")
    for op in OPS:
        t = ours[op][0]
        print(f"ours (numba) HC4 z=x{'+' if op == 'add' else '*'}y : {t * 1e3:9.2f} ms "
              f"({t / n * 1e9:6.1f} ns/box)")
    try:
        import codac  # noqa: F401
    except ImportError:
        print("codac not installed: no comparison")
        print("interval_speedup_vs_codac nan")
        return
    finally:
        round_to_nearest()
    ratios = []
    for op in OPS:
        tc, ref = time_codac(op, boxes[op])
        diff = np.nanmax(np.abs(ours[op][1] - ref))
        ratios.append(tc / ours[op][0])
        print(f"codac (Python) HC4 z=x{'+' if op == 'add' else '*'}y: {tc * 1e3:9.2f} ms "
              f"({tc / n * 1e9:6.1f} ns/box); max |ours - codac| endpoint {diff:.3g}; "
              f"speed-up {ratios[-1]:.0f}x")
    print(f"interval_speedup_vs_codac {min(ratios):.1f}")


if __name__ == "__main__":
    main()
