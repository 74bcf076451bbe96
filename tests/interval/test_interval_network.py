"""Constraint network: textbook FBP, Waltz fixed points, parsing, batch form,
inconsistency as data, and a pure-Python reference of both kernels."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imubounds.errors import OptionError
from imubounds.interval import _ctc as k
from imubounds.interval.network import Network

INF = math.inf


def test_textbook_fbp() -> None:
    net = Network()
    net.var("x", 1, 2)
    net.var("y", 0, 5)
    net.var("z", 4, 6)
    net.add("z = x + y")
    r = net.contract("fbp")
    assert r.consistent and r["y"] == (2.0, 5.0) and r["x"] == (1.0, 2.0) and r["z"] == (4.0, 6.0)
    assert net.domain("y") == (2.0, 5.0)  # stored in place


def _parabola_line(xlo: float) -> Network:
    net = Network()
    net.var("x", xlo, 10)
    net.var("y", -10, 10)
    net.add("y = x**2")
    net.add("y = 2 - x")
    return net


def test_waltz_reaches_the_solution_of_a_well_posed_network() -> None:
    # x in [0, 10]: the only solution of y = x^2, y = 2 - x is x = y = 1
    net = _parabola_line(0.0)
    r = net.contract("waltz", tol=0.0)
    assert r.consistent and r.converged
    for name in ("x", "y"):
        lo, hi = r[name]
        assert lo <= 1.0 <= hi and hi - lo <= 4 * 2.0**-52
    # one forward-backward pass is much weaker
    r1 = _parabola_line(0.0).contract("fbp")
    assert r1["x"][1] - r1["x"][0] > 1.0


def test_waltz_reaches_the_known_hc4_fixed_point() -> None:
    # x in [-10, 10]: two solutions (1, 1) and (-2, 4); the HC4 fixed point is
    # x in [-2, 2], y in [0, 4] (each projection is consistent at its bounds)
    net = _parabola_line(-10.0)
    r = net.contract("waltz", tol=0.0, max_revisions=200_000)
    xlo, xhi = r["x"]
    ylo, yhi = r["y"]
    assert -2.0 - 1e-9 <= xlo <= -2.0 and xhi == 2.0
    assert ylo == 0.0 and 4.0 <= yhi <= 4.0 + 1e-8


def test_linear_system_fixed_point() -> None:
    net = Network()
    net.var("x", 0, 10)
    net.var("y", 0, 10)
    net.add("x + y = 3")
    net.add("x - y = 1")
    r = net.contract("waltz", tol=0.0)
    # HC4 is a local consistency: on this system it stops at x in [1, 3],
    # y in [0, 2] (every bound has a support in each single equation), not
    # at the solution (2, 1) -- the textbook fixed point, reached exactly.
    assert r.consistent and r.converged
    assert r["x"] == (1.0, 3.0) and r["y"] == (0.0, 2.0)


def test_iteration_cap_is_reported() -> None:
    net = _parabola_line(-10.0)
    r = net.contract("waltz", tol=0.0, max_revisions=10)
    assert not r.converged and r.revisions == 10 and r.consistent


def test_inconsistency_is_data() -> None:
    net = Network()
    net.var("x", 0, 1)
    net.var("y", 0, 1)
    net.add("z = x + y")
    net.add("z = 5")
    r = net.contract("waltz")
    assert not r.consistent
    assert r.emptied_equation == 1 and r.equation_text == "z = 5"
    assert r.emptied_variable in ("z", "_c[5]")
    assert net.domain("x") == (0.0, 1.0)  # left untouched
    net2 = Network()
    net2.var("x", 0, 1)
    net2.add("sqrt(x) = -1")
    r2 = net2.contract("fbp")
    assert not r2.consistent and r2.emptied_equation == 0


def test_expression_decomposition() -> None:
    net = Network()
    net.var("x", 1, 2)
    net.var("y", 1, 2)
    net.var("w", 0, 0.5)
    net.var("z", -100, 100)
    net.add("z = x*y + sin(w)")
    ops = [p.name for p in net.primitives]
    assert ops == ["mul", "sin", "add"]
    assert net.names[-2:] == ["_t1", "_t2"]  # temporaries
    r = net.contract("fbp")
    lo, hi = r["z"]
    assert lo <= 1.0 and math.sin(0.5) + 4 <= hi < math.sin(0.5) + 4 + 1e-12
    net.add("atan2(y, x) = 0.5")
    net.add("exp(w) - log(x) = sqr(y) / 2 + sqrt(x) ** 2 - -w")
    assert net.contract("waltz").consistent in (True, False)


def test_decimal_constants_are_enclosed() -> None:
    net = Network()
    net.var("x", -1, 1)
    net.add("x = 0.1")
    r = net.contract("fbp")
    lo, hi = r["x"]
    assert lo < 0.1 <= hi or lo <= 0.1 < hi
    assert hi == math.nextafter(lo, INF)
    net2 = Network()
    net2.var("t", -10, 10)
    net2.add("t = pi")
    lo, hi = net2.contract("fbp")["t"]
    assert lo == math.pi and hi == math.nextafter(math.pi, INF)


@pytest.mark.parametrize(
    "bad", ["x = y = z", "x + ", "z = foo(x)", "z = x ** 3", "z = x % y", "x"]
)
def test_bad_equations_raise_one_line_option_errors(bad: str) -> None:
    net = Network()
    net.var("x", 0, 1)
    n_before = (len(net.names), len(net.primitives))
    with pytest.raises(OptionError) as e:
        net.add(bad)
    assert "\n" not in str(e.value)
    assert (len(net.names), len(net.primitives)) == n_before  # rolled back


def test_strict_mode_and_bad_options() -> None:
    net = Network()
    net.var("x", 0, 1)
    with pytest.raises(OptionError):
        net.add("x = q + 1", strict=True)
    with pytest.raises(OptionError):
        net.contract("newton")
    with pytest.raises(OptionError):
        net.var("x", 2, 1)
    with pytest.raises(OptionError):
        net.add_primitive("add", "x", "x")


# --- reference kernels in plain Python ----------------------------------------------


def _ref_apply(net: Network, ci: int, mode: int, lo: list[float], hi: list[float]) -> int:
    p = net.primitives[ci]
    b = p.b
    r = k.revise(p.op, lo[p.out], hi[p.out], lo[p.a], hi[p.a], lo[b] if b >= 0 else 0.0,
                 hi[b] if b >= 0 else 0.0, mode)
    if r[6] >= 0:
        v = (p.out, p.a, b)[r[6]]
        lo[v], hi[v] = INF, -INF
        return v
    for v, nlo, nhi in ((p.out, r[0], r[1]), (p.a, r[2], r[3]), (b, r[4], r[5])):
        if v < 0:
            continue
        lo[v] = max(lo[v], nlo)
        hi[v] = min(hi[v], nhi)
        if not lo[v] <= hi[v]:
            lo[v], hi[v] = INF, -INF
            return v
    return -1


def ref_fbp(net: Network) -> tuple[list[float], list[float], int]:
    lo, hi = list(net.lo), list(net.hi)
    groups: dict[int, list[int]] = {}
    for ci, p in enumerate(net.primitives):
        groups.setdefault(p.equation, []).append(ci)
    for g in sorted(groups):
        for ci in groups[g]:
            if _ref_apply(net, ci, 1, lo, hi) >= 0:
                return lo, hi, ci
        for ci in reversed(groups[g]):
            if _ref_apply(net, ci, 2, lo, hi) >= 0:
                return lo, hi, ci
    return lo, hi, -1


def ref_waltz(net: Network, tol: float) -> tuple[list[float], list[float], int]:
    from collections import deque

    lo, hi = list(net.lo), list(net.hi)
    queue = deque(range(len(net.primitives)))
    inq = set(queue)

    def sig(olo: float, ohi: float, nlo: float, nhi: float) -> bool:
        ow = ohi - olo
        if ow < INF:
            return (nlo - olo) + (ohi - nhi) > tol * ow
        if (olo == -INF and nlo > -INF) or (ohi == INF and nhi < INF):
            return True
        return (nlo > olo and nlo - olo > tol * max(1.0, abs(olo))) or (
            nhi < ohi and ohi - nhi > tol * max(1.0, abs(ohi)))

    while queue:
        ci = queue.popleft()
        inq.discard(ci)
        p = net.primitives[ci]
        vs = [v for v in (p.out, p.a, p.b)]
        old = [(lo[v], hi[v]) if v >= 0 else (0.0, 0.0) for v in vs]
        if _ref_apply(net, ci, 3, lo, hi) >= 0:
            return lo, hi, ci
        for v, (olo, ohi) in zip(vs, old, strict=True):
            if v >= 0 and sig(olo, ohi, lo[v], hi[v]):
                for cj, q in enumerate(net.primitives):
                    if cj != ci and cj not in inq and v in (q.out, q.a, q.b):
                        queue.append(cj)
                        inq.add(cj)
    return lo, hi, -1


def _random_network(rng: np.random.Generator) -> Network:
    net = Network()
    names = ["a", "b", "c", "d"]
    for n in names:
        lo = rng.uniform(-3, 3)
        net.var(n, lo, lo + rng.uniform(0.1, 4))
    exprs = ["a + b", "a * b", "b - c", "sin(c)", "cos(d) * a", "sqr(d) - b", "c / (a + 5)",
             "atan2(a, b)", "exp(c) - d"]
    for _ in range(int(rng.integers(2, 5))):
        lhs = names[int(rng.integers(0, 4))]
        net.add(f"{lhs} = {exprs[int(rng.integers(0, len(exprs)))]}")
    return net


@pytest.mark.parametrize("seed", range(25))
def test_compiled_kernels_match_python_reference(seed: int) -> None:
    rng = np.random.default_rng(seed)
    net = _random_network(rng)
    lo, hi, bad = ref_fbp(net)
    r = net.contract("fbp", inplace=False)
    assert r.consistent == (bad < 0)
    if r.consistent:
        assert [r[n] for n in net.names] == list(zip(lo, hi, strict=True))
    else:
        assert r.emptied_primitive == bad
    lo, hi, bad = ref_waltz(net, 1e-3)
    r = net.contract("waltz", tol=1e-3, inplace=False)
    assert r.consistent == (bad < 0)
    if r.consistent:
        assert [r[n] for n in net.names] == list(zip(lo, hi, strict=True))


def test_batch_matches_single_box_contraction() -> None:
    rng = np.random.default_rng(3)
    net = Network()
    for n in ("u", "v", "psi", "e", "nn"):
        net.var(n)
    net.add("e = u * cos(psi) - v * sin(psi)")
    net.add("nn = v * cos(psi) + u * sin(psi)")
    nbox = 200
    lo = np.empty((nbox, len(net.names)))
    hi = np.empty_like(lo)
    for i in range(nbox):
        for n, (c, w) in {"u": (10, 0.5), "v": (0, 0.3), "psi": (rng.uniform(-3, 3), 0.1),
                          "e": (0, 20), "nn": (0, 20)}.items():
            j = net.index(n)
            lo[i, j], hi[i, j] = c - w, c + w
        for j, n in enumerate(net.names):
            if n.startswith("_"):
                lo[i, j], hi[i, j] = -INF, INF
    for method in ("fbp", "waltz"):
        blo, bhi = lo.copy(), hi.copy()
        st = net.contract_batch(blo, bhi, method=method)
        assert (st["emptied_variable"] == -1).all()
        for i in range(0, nbox, 20):
            for j, n in enumerate(net.names):
                net.var(n, float(lo[i, j]), float(hi[i, j]))
            r = net.contract(method, inplace=False)
            assert [r[n] for n in net.names] == list(zip(blo[i], bhi[i], strict=True))
