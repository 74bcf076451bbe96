"""Cross-check of the smoother's primitive contractors (``z = x + y``,
``z = x * y``) with Codac 2 (test-only dependency).

For random boxes (half of them built around a solution point, half arbitrary)
our HC4-revise result must (1) contain every solution point we planted and
(2) be no wider than Codac's forward-backward result by more than a few ulp
at either end (``ULPS`` below).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from _hc4 import hc4

import imubounds.interval as iv
from imubounds.interval.rounding import round_to_nearest, rounding, rounding_mode

codac = pytest.importorskip("codac", reason="codac is a test-only dependency (pip install codac)")
# Importing codac switches the whole process to round-upward (its rules need it);
# ours need round-to-nearest. Restore it at once (other tests may run in this
# process) and give codac its mode only around its own calls.
CODAC_MODE = rounding_mode()
round_to_nearest()

ULPS = {"add": 2, "mul": 2}
OPS2 = {"add": "AddOp", "mul": "MulOp"}
N = 400


def _codac_hc4(op: str, z, a, b):
    with rounding(CODAC_MODE):
        return _codac_hc4_raw(op, z, a, b)


def _codac_hc4_raw(op: str, z, a, b):
    Z = codac.Interval(*z)
    A = codac.Interval(*a)
    cls = getattr(codac, OPS2[op])
    B = codac.Interval(*b)
    Z &= cls.fwd(A, B)
    cls.bwd(Z, A, B)
    if Z.is_empty() or A.is_empty() or B.is_empty():
        return None
    return (Z.lb(), Z.ub()), (A.lb(), A.ub()), (B.lb(), B.ub())


def _slack(x: float, n: int) -> float:
    if math.isinf(x):
        return 0.0
    u = math.ulp(x) if x != 0 else 5e-324
    return n * max(u, 2.0**-1060)


def _boxes(op: str, rng: np.random.Generator):
    p = rng.normal(0, 2, N) * 10.0 ** rng.uniform(-2, 2, N)
    q = rng.normal(0, 2, N) * 10.0 ** rng.uniform(-2, 2, N)
    f = p + q if op == "add" else p * q

    def around(c, planted):
        w1 = np.abs(c) * 10.0 ** rng.uniform(-8, 0, N) + 10.0 ** rng.uniform(-4, 0.5, N)
        w2 = np.abs(c) * 10.0 ** rng.uniform(-8, 0, N) + 10.0 ** rng.uniform(-4, 0.5, N)
        lo, hi = c - w1, c + w2
        if not planted:  # arbitrary boxes, possibly inconsistent
            sh = rng.normal(0, 1, N) * (w1 + w2)
            lo, hi = lo + sh, hi + sh
        return lo, hi

    return p, q, f, around


def test_codac_import_left_round_to_nearest() -> None:
    assert rounding_mode() == 0
    assert iv.I(1, 2).to_tuples() == [(1.0, 2.0)]


@pytest.mark.parametrize("op", list(ULPS))
def test_primitive_contractors_vs_codac(op: str) -> None:
    rng = np.random.default_rng(2024 + len(op))
    p, q, f, around = _boxes(op, rng)
    n_both_empty = n_cmp = 0
    for planted in (True, False):
        zlo, zhi = around(f, planted)
        xlo, xhi = around(p, planted)
        ylo, yhi = around(q, planted)
        res = hc4(op, iv.IntervalArray(zlo, zhi), iv.IntervalArray(xlo, xhi),
                  iv.IntervalArray(ylo, yhi))
        for i in range(N):
            if planted:  # the planted solution point survives
                assert res.a.lo[i] <= p[i] <= res.a.hi[i], (op, i)
                assert res.b.lo[i] <= q[i] <= res.b.hi[i], (op, i)
            ref = _codac_hc4(op, (zlo[i], zhi[i]), (xlo[i], xhi[i]), (ylo[i], yhi[i]))
            ours = [(res.z.lo[i], res.z.hi[i]), (res.a.lo[i], res.a.hi[i]),
                    (res.b.lo[i], res.b.hi[i])]
            if ref is None:
                # Codac proved the box empty; we must too, or be a sliver of a few ulp
                if res.code[i] >= 0:
                    n_both_empty += 1
                    continue
                wz = ours[0][1] - ours[0][0]
                assert wz <= _slack(ours[0][0], ULPS[op]) * 2, (op, i, ours)
                continue
            assert res.code[i] == -1, (op, i, ref)
            n_cmp += 1
            for (lo, hi), (clo, chi) in zip(ours, ref, strict=True):
                assert lo >= clo - _slack(clo, ULPS[op]), (op, i, planted, lo, clo, ours, ref)
                assert hi <= chi + _slack(chi, ULPS[op]), (op, i, planted, hi, chi, ours, ref)
    assert n_cmp > N // 2
