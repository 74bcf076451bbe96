"""A small constraint network contracted by forward-backward propagation.

Declare variables with their domains, add constraints either as primitives
or as equations written in Python syntax (``net.add("z = x*y + sin(w)")``),
which are decomposed into primitives with temporary variables. Then

* ``net.contract("fbp")`` runs ONE forward-backward pass per equation (the
  HC4-revise of each equation in the order added: forward over its
  primitives, then backward in reverse order) -- the paper's real-time
  choice;
* ``net.contract("waltz")`` propagates to a fixed point with the Waltz/AC3
  algorithm: a queue of primitives; after a revision, every other primitive
  sharing a variable whose domain shrank by more than ``tol`` (relative to
  its width) is queued again; stops when the queue is empty or after
  ``max_revisions`` revisions.

Both kernels are compiled (numba) and also exist in batch form,
:meth:`Network.contract_batch`, which contracts many boxes of the same
network at once. Inconsistency is data, not an exception: the result says
which constraint emptied which variable.

Equation syntax: names, numbers (decimal literals are enclosed, e.g. ``0.1``
becomes the interval around 1/10), ``pi``, ``+ - * /``, unary ``-``,
``**2``, ``**0.5``, and the functions ``sqr, sqrt, sin, cos, exp, log,
atan2(y, x)``. Unknown names become new variables with domain
``(-inf, inf)`` unless ``strict=True``.
"""

from __future__ import annotations

import ast
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from imubounds.errors import OptionError
from imubounds.interval import _ctc as k
from imubounds.interval.array import IntervalArray, from_decimal
from imubounds.interval.rounding import check_rounding

_INF = math.inf


@dataclass(frozen=True)
class Primitive:
    """One primitive constraint ``out = op(a[, b])`` (indices into the variables)."""

    op: int
    out: int
    a: int
    b: int  # -1 for unary primitives
    equation: int  # index of the equation (group) it belongs to

    @property
    def name(self) -> str:
        return k.OP_NAMES[self.op]


@dataclass
class ContractResult:
    """Outcome of a contraction.

    Attributes
    ----------
    consistent : bool
        False if some domain became empty (the box holds no solution).
    domains : dict[str, tuple[float, float]]
        Contracted domains (on inconsistency: the state when the empty set
        appeared, with the emptied variable as ``(inf, -inf)``).
    emptied_variable, emptied_equation, emptied_primitive : str, int, int or None
        Which variable became empty, in which equation (index and
        :attr:`equation_text`) and which primitive.
    revisions : int
        Number of primitive revisions performed.
    converged : bool
        False if the Waltz iteration cap stopped the propagation.
    """

    consistent: bool
    domains: dict[str, tuple[float, float]]
    emptied_variable: str | None = None
    emptied_equation: int | None = None
    emptied_primitive: int | None = None
    equation_text: str | None = None
    revisions: int = 0
    converged: bool = True
    method: str = "waltz"
    extra: dict[str, Any] = field(default_factory=dict)

    def __getitem__(self, name: str) -> tuple[float, float]:
        return self.domains[name]


# -- compiled kernels -----------------------------------------------------------


@njit(cache=True)
def _write(v, nlo, nhi, lo, hi):  # type: ignore[no-untyped-def]
    """Intersect domain ``v`` with ``[nlo, nhi]``; True if it became empty."""
    if nlo > lo[v]:
        lo[v] = nlo
    if nhi < hi[v]:
        hi[v] = nhi
    if not (lo[v] <= hi[v]):
        lo[v] = _INF
        hi[v] = -_INF
        return True
    return False


@njit(cache=True)
def _apply(ops, outs, aa, bb, ci, mode, lo, hi):  # type: ignore[no-untyped-def]
    """Revise primitive ``ci`` on the domain vectors; return the emptied var or -1."""
    o = outs[ci]
    a = aa[ci]
    b = bb[ci]
    blo = lo[b] if b >= 0 else 0.0
    bhi = hi[b] if b >= 0 else 0.0
    r = k.revise(ops[ci], lo[o], hi[o], lo[a], hi[a], blo, bhi, mode)
    if r[6] >= 0:
        v = o if r[6] == 0 else (a if r[6] == 1 else b)
        lo[v] = _INF
        hi[v] = -_INF
        return v
    # write back by intersection (handles a variable used twice)
    if _write(o, r[0], r[1], lo, hi):
        return o
    if _write(a, r[2], r[3], lo, hi):
        return a
    if b >= 0 and _write(b, r[4], r[5], lo, hi):
        return b
    return -1


@njit(cache=True)
def _fbp_kernel(ops, outs, aa, bb, gstart, lo, hi):  # type: ignore[no-untyped-def]
    """One forward-backward pass per equation; returns (primitive, var, revisions)."""
    revs = 0
    for g in range(gstart.size - 1):
        for ci in range(gstart[g], gstart[g + 1]):
            v = _apply(ops, outs, aa, bb, ci, 1, lo, hi)
            revs += 1
            if v >= 0:
                return ci, v, revs
        for ci in range(gstart[g + 1] - 1, gstart[g] - 1, -1):
            v = _apply(ops, outs, aa, bb, ci, 2, lo, hi)
            revs += 1
            if v >= 0:
                return ci, v, revs
    return -1, -1, revs


@njit(cache=True)
def _significant(olo, ohi, nlo, nhi, tol):  # type: ignore[no-untyped-def]
    ow = ohi - olo
    if ow < _INF:
        shrink = (nlo - olo) + (ohi - nhi)
        return shrink > tol * ow
    if (olo == -_INF and nlo > -_INF) or (ohi == _INF and nhi < _INF):
        return True
    if nlo > olo and nlo - olo > tol * max(1.0, abs(olo)):
        return True
    if nhi < ohi and ohi - nhi > tol * max(1.0, abs(ohi)):
        return True
    return False


@njit(cache=True)
def _waltz_kernel(ops, outs, aa, bb, adj_ptr, adj_idx, lo, hi, tol, max_rev):  # type: ignore[no-untyped-def]
    """Waltz/AC3 propagation; returns (primitive, var, revisions, converged)."""
    nc = ops.size
    queue = np.empty(nc, dtype=np.int64)
    inq = np.ones(nc, dtype=np.bool_)
    for i in range(nc):
        queue[i] = i
    head = 0
    count = nc
    revs = 0
    while count > 0:
        if revs >= max_rev:
            return -1, -1, revs, False
        ci = queue[head]
        head = (head + 1) % nc
        count -= 1
        inq[ci] = False
        vs = (outs[ci], aa[ci], bb[ci])
        olo0 = lo[vs[0]]
        ohi0 = hi[vs[0]]
        olo1 = lo[vs[1]]
        ohi1 = hi[vs[1]]
        olo2 = lo[vs[2]] if vs[2] >= 0 else 0.0
        ohi2 = hi[vs[2]] if vs[2] >= 0 else 0.0
        v = _apply(ops, outs, aa, bb, ci, 3, lo, hi)
        revs += 1
        if v >= 0:
            return ci, v, revs, True
        for j in range(3):
            var = vs[j]
            if var < 0:
                continue
            if j == 0:
                sig = _significant(olo0, ohi0, lo[var], hi[var], tol)
            elif j == 1:
                sig = _significant(olo1, ohi1, lo[var], hi[var], tol)
            else:
                sig = _significant(olo2, ohi2, lo[var], hi[var], tol)
            if not sig:
                continue
            for p in range(adj_ptr[var], adj_ptr[var + 1]):
                cj = adj_idx[p]
                if cj != ci and not inq[cj]:
                    queue[(head + count) % nc] = cj
                    count += 1
                    inq[cj] = True
    return -1, -1, revs, True


@njit(cache=True)
def _batch_kernel(ops, outs, aa, bb, gstart, adj_ptr, adj_idx, lo, hi, method, tol, max_rev,
                  bad_prim, bad_var, revs, conv):  # type: ignore[no-untyped-def]
    for i in range(lo.shape[0]):
        dlo = lo[i]
        dhi = hi[i]
        if method == 0:
            p, v, r = _fbp_kernel(ops, outs, aa, bb, gstart, dlo, dhi)
            c = True
        else:
            p, v, r, c = _waltz_kernel(ops, outs, aa, bb, adj_ptr, adj_idx, dlo, dhi, tol,
                                       max_rev)
        bad_prim[i] = p
        bad_var[i] = v
        revs[i] = r
        conv[i] = c


# -- the network ----------------------------------------------------------------

_FUNCS1 = {"sqr": k.OP_SQR, "sqrt": k.OP_SQRT, "sin": k.OP_SIN, "cos": k.OP_COS,
           "exp": k.OP_EXP, "log": k.OP_LOG}


class Network:
    """Variables with interval domains and primitive constraints between them.

    Examples
    --------
    >>> net = Network()
    >>> net.var("x", 1, 2); net.var("y", 0, 5); net.var("z", 4, 6)
    >>> net.add("z = x + y")
    >>> net.contract("fbp")["y"]
    (2.0, 5.0)
    """

    def __init__(self) -> None:
        self.names: list[str] = []
        self._index: dict[str, int] = {}
        self.lo: list[float] = []
        self.hi: list[float] = []
        self.primitives: list[Primitive] = []
        self.equations: list[str] = []
        self._ntemp = 0
        self._consts: dict[str, int] = {}

    # -- variables -------------------------------------------------------------
    def var(self, name: str, lo: Any = -_INF, hi: Any = None) -> str:
        """Declare (or re-bound) variable ``name`` with domain ``[lo, hi]``.

        ``lo``/``hi`` may be numbers, decimal strings (enclosed) or an
        IntervalArray (0-d) for ``lo`` alone; ``hi`` defaults to ``+inf`` if
        ``lo`` is ``-inf``, else to ``lo``.
        """
        if not name.isidentifier():
            raise OptionError(f"variable name {name!r} is not an identifier")
        dlo, dhi = self._domain(lo, hi)
        if name in self._index:
            i = self._index[name]
            self.lo[i], self.hi[i] = dlo, dhi
        else:
            self._index[name] = len(self.names)
            self.names.append(name)
            self.lo.append(dlo)
            self.hi.append(dhi)
        return name

    @staticmethod
    def _domain(lo: Any, hi: Any) -> tuple[float, float]:
        if isinstance(lo, IntervalArray):
            return float(lo.lo), float(lo.hi)
        if isinstance(lo, tuple):
            lo, hi = lo
        if hi is None:
            hi = _INF if (isinstance(lo, float | int) and lo == -_INF) else lo
        a = float(from_decimal(lo).lo) if not isinstance(lo, float) else lo
        b = float(from_decimal(hi).hi) if not isinstance(hi, float) else hi
        if math.isnan(a) or math.isnan(b) or a > b:
            raise OptionError(f"domain [{lo!r}, {hi!r}] is not an interval (need lo <= hi)")
        return a, b

    def set_domain(self, name: str, lo: Any, hi: Any = None) -> None:
        """Change the domain of an existing variable."""
        if name not in self._index:
            raise OptionError(f"unknown variable {name!r}; declare it with var()")
        self.var(name, lo, hi)

    def domain(self, name: str) -> tuple[float, float]:
        """Current domain ``(lo, hi)`` of ``name``."""
        if name not in self._index:
            raise OptionError(f"unknown variable {name!r}")
        i = self._index[name]
        return self.lo[i], self.hi[i]

    def index(self, name: str) -> int:
        """Column of ``name`` in the domain vectors (for :meth:`contract_batch`)."""
        return self._index[name]

    def _temp(self) -> int:
        self._ntemp += 1
        name = f"_t{self._ntemp}"
        self.var(name)
        return self._index[name]

    def _const(self, text: str, lo: float, hi: float) -> int:
        key = f"_c[{text}]"
        if key not in self._consts:
            self._index[key] = len(self.names)
            self.names.append(key)
            self.lo.append(lo)
            self.hi.append(hi)
            self._consts[key] = self._index[key]
        return self._consts[key]

    # -- constraints -------------------------------------------------------------
    def add_primitive(self, op: str | int, out: str, a: str, b: str | None = None) -> int:
        """Add ``out = op(a[, b])`` as its own equation; returns the primitive index."""
        from imubounds.interval.contractors import op_code

        opc = op_code(op)
        names = [out, a] + ([b] if b is not None else [])
        for n in names:
            if n not in self._index:
                raise OptionError(f"unknown variable {n!r}; declare it with var()")
        if (k.OP_ARITY[opc] == 2) != (b is not None):
            raise OptionError(f"primitive {k.OP_NAMES[opc]!r} takes {k.OP_ARITY[opc]} argument(s)")
        g = len(self.equations)
        text = f"{out} = {k.OP_NAMES[opc]}({a}{', ' + b if b else ''})"
        self.equations.append(text)
        self.primitives.append(Primitive(opc, self._index[out], self._index[a],
                                         self._index[b] if b else -1, g))
        return len(self.primitives) - 1

    def add(self, equation: str, strict: bool = False) -> int:
        """Add an equation ``lhs = rhs`` (Python syntax); returns its index."""
        if "==" in equation:
            left, right = equation.split("==", 1)
        elif equation.count("=") == 1:
            left, right = equation.split("=", 1)
        else:
            raise OptionError(f"equation {equation!r} needs exactly one '='")
        try:
            lt = ast.parse(left.strip(), mode="eval").body
            rt = ast.parse(right.strip(), mode="eval").body
        except SyntaxError as exc:
            raise OptionError(f"cannot parse equation {equation!r}: {exc.msg}") from None
        g = len(self.equations)
        n_before = len(self.primitives)
        n_vars_before = len(self.names)
        self.equations.append(equation.strip())
        try:
            if isinstance(lt, ast.Name) and not isinstance(rt, ast.Name | ast.Constant):
                out = self._leaf(lt, left.strip(), strict)
                self._node(rt, right.strip(), g, strict, out)
            elif isinstance(rt, ast.Name) and not isinstance(lt, ast.Name | ast.Constant):
                out = self._leaf(rt, right.strip(), strict)
                self._node(lt, left.strip(), g, strict, out)
            else:
                a = self._node(lt, left.strip(), g, strict)
                b = self._node(rt, right.strip(), g, strict)
                self.primitives.append(Primitive(k.OP_EQ, a, b, -1, g))
        except OptionError:
            del self.primitives[n_before:]
            self.equations.pop()
            for name in self.names[n_vars_before:]:
                del self._index[name]
                self._consts.pop(name, None)
            del self.names[n_vars_before:], self.lo[n_vars_before:], self.hi[n_vars_before:]
            raise
        return g

    def _leaf(self, node: ast.Name, src: str, strict: bool) -> int:
        name = node.id
        if name == "pi":
            from imubounds.interval import _core as c

            return self._const("pi", c.PI_LO, c.PI_HI)
        if name not in self._index:
            if strict:
                raise OptionError(f"unknown variable {name!r} in {src!r}; declare it with var()")
            self.var(name)
        return self._index[name]

    def _emit(self, op: int, a: int, b: int, g: int, out: int | None) -> int:
        o = self._temp() if out is None else out
        self.primitives.append(Primitive(op, o, a, b, g))
        return o

    def _node(self, node: ast.AST, src: str, g: int, strict: bool, out: int | None = None) -> int:
        if isinstance(node, ast.Name):
            i = self._leaf(node, src, strict)
            if out is None:
                return i
            return self._emit(k.OP_EQ, i, -1, g, out)
        if isinstance(node, ast.Constant) and isinstance(node.value, int | float):
            text = ast.get_source_segment(src, node) or repr(node.value)
            iv = from_decimal(text)
            i = self._const(text, float(iv.lo), float(iv.hi))
            if out is None:
                return i
            return self._emit(k.OP_EQ, i, -1, g, out)
        if isinstance(node, ast.UnaryOp):
            a = self._node(node.operand, src, g, strict)
            if isinstance(node.op, ast.UAdd):
                return a if out is None else self._emit(k.OP_EQ, a, -1, g, out)
            if isinstance(node.op, ast.USub):
                return self._emit(k.OP_NEG, a, -1, g, out)
        if isinstance(node, ast.BinOp):
            if isinstance(node.op, ast.Pow) and isinstance(node.right, ast.Constant):
                a = self._node(node.left, src, g, strict)
                if node.right.value == 2:
                    return self._emit(k.OP_SQR, a, -1, g, out)
                if node.right.value == 0.5:
                    return self._emit(k.OP_SQRT, a, -1, g, out)
            ops = {ast.Add: k.OP_ADD, ast.Sub: k.OP_SUB, ast.Mult: k.OP_MUL, ast.Div: k.OP_DIV}
            if type(node.op) in ops:
                a = self._node(node.left, src, g, strict)
                b = self._node(node.right, src, g, strict)
                return self._emit(ops[type(node.op)], a, b, g, out)
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and not node.keywords:
            fn = node.func.id
            if fn in _FUNCS1 and len(node.args) == 1:
                a = self._node(node.args[0], src, g, strict)
                return self._emit(_FUNCS1[fn], a, -1, g, out)
            if fn == "atan2" and len(node.args) == 2:
                a = self._node(node.args[0], src, g, strict)
                b = self._node(node.args[1], src, g, strict)
                return self._emit(k.OP_ATAN2, a, b, g, out)
        seg = ast.get_source_segment(src, node) or ast.dump(node)
        raise OptionError(
            f"unsupported expression {seg!r} in {src!r}; use + - * / **2 **0.5 "
            "sqr sqrt sin cos exp log atan2"
        )

    # -- compiled form -------------------------------------------------------------
    def _arrays(self) -> tuple[np.ndarray, ...]:
        ps = self.primitives
        ops = np.array([p.op for p in ps], dtype=np.int64)
        outs = np.array([p.out for p in ps], dtype=np.int64)
        aa = np.array([p.a for p in ps], dtype=np.int64)
        bb = np.array([p.b for p in ps], dtype=np.int64)
        eq = np.array([p.equation for p in ps], dtype=np.int64)
        # group boundaries in primitive order (primitives of one equation are contiguous)
        gstart = np.flatnonzero(np.r_[True, eq[1:] != eq[:-1]]) if ps else np.zeros(0, np.int64)
        gstart = np.r_[gstart, len(ps)].astype(np.int64)
        nv = len(self.names)
        lists: list[list[int]] = [[] for _ in range(nv)]
        for ci, p in enumerate(ps):
            for v in {p.out, p.a, p.b}:
                if v >= 0:
                    lists[v].append(ci)
        adj_ptr = np.zeros(nv + 1, dtype=np.int64)
        adj_ptr[1:] = np.cumsum([len(x) for x in lists])
        adj_idx = np.array([c for x in lists for c in x], dtype=np.int64)
        return ops, outs, aa, bb, gstart, adj_ptr, adj_idx

    def _max_rev(self, max_revisions: int | None) -> int:
        if max_revisions is None:
            return 1000 * max(1, len(self.primitives))
        if max_revisions < 1:
            raise OptionError(f"max_revisions={max_revisions} must be >= 1")
        return int(max_revisions)

    # -- contraction ---------------------------------------------------------------
    def contract(
        self,
        method: str = "waltz",
        tol: float = 1e-3,
        max_revisions: int | None = None,
        inplace: bool = True,
    ) -> ContractResult:
        """Contract the current domains.

        Parameters
        ----------
        method : {"waltz", "fbp"}
            Propagation to a fixed point, or one forward-backward pass per
            equation (the paper's real-time choice).
        tol : float
            Waltz only: a variable re-queues its constraints when its width
            shrinks by more than ``tol`` times its previous width.
        max_revisions : int, optional
            Waltz only: cap on primitive revisions (default 1000 per primitive).
        inplace : bool
            Store the contracted domains in the network if consistent.
        """
        if method not in ("waltz", "fbp"):
            raise OptionError(f"unknown contraction method {method!r}; use 'waltz' or 'fbp'")
        if not (tol >= 0.0):
            raise OptionError(f"tol={tol!r} must be >= 0")
        check_rounding()
        ops, outs, aa, bb, gstart, adj_ptr, adj_idx = self._arrays()
        lo = np.array(self.lo, dtype=np.float64)
        hi = np.array(self.hi, dtype=np.float64)
        emp = np.flatnonzero(~(lo <= hi))
        if emp.size:
            i = int(emp[0])
            return self._result(False, lo, hi, -1, i, 0, True, method)
        if not self.primitives:
            return self._result(True, lo, hi, -1, -1, 0, True, method)
        if method == "fbp":
            p, v, r = _fbp_kernel(ops, outs, aa, bb, gstart, lo, hi)
            conv = True
        else:
            p, v, r, conv = _waltz_kernel(ops, outs, aa, bb, adj_ptr, adj_idx, lo, hi,
                                          float(tol), self._max_rev(max_revisions))
        res = self._result(v < 0, lo, hi, int(p), int(v), int(r), bool(conv), method)
        if inplace and res.consistent:
            self.lo = lo.tolist()
            self.hi = hi.tolist()
        return res

    def _result(self, ok: bool, lo: np.ndarray, hi: np.ndarray, p: int, v: int, r: int,
                conv: bool, method: str) -> ContractResult:
        doms = {n: (float(lo[i]), float(hi[i])) for i, n in enumerate(self.names)}
        if ok:
            return ContractResult(True, doms, revisions=r, converged=conv, method=method)
        g = self.primitives[p].equation if p >= 0 else None
        return ContractResult(
            False, doms, emptied_variable=self.names[v], emptied_equation=g,
            emptied_primitive=p if p >= 0 else None,
            equation_text=self.equations[g] if g is not None else "(initial domain)",
            revisions=r, converged=conv, method=method,
        )

    def contract_batch(
        self,
        lo: np.ndarray,
        hi: np.ndarray,
        method: str = "fbp",
        tol: float = 1e-3,
        max_revisions: int | None = None,
    ) -> dict[str, np.ndarray]:
        """Contract many boxes of this network at once (compiled loop).

        Parameters
        ----------
        lo, hi : ndarray, shape (n_boxes, n_variables)
            Domains, columns in the order of :attr:`names` (see :meth:`index`).
            Modified in place.

        Returns
        -------
        dict
            ``emptied_primitive`` and ``emptied_variable`` (int arrays, -1 if
            consistent), ``revisions`` and ``converged`` per box.
        """
        nv = len(self.names)
        for arr in (lo, hi):
            if (arr.dtype != np.float64 or arr.ndim != 2 or arr.shape[1] != nv
                    or not arr.flags.c_contiguous):
                raise OptionError(
                    f"contract_batch needs C-contiguous float64 arrays of shape (n, {nv})")
        if method not in ("waltz", "fbp"):
            raise OptionError(f"unknown contraction method {method!r}; use 'waltz' or 'fbp'")
        check_rounding()
        ops, outs, aa, bb, gstart, adj_ptr, adj_idx = self._arrays()
        n = lo.shape[0]
        bad_p = np.full(n, -1, dtype=np.int64)
        bad_v = np.full(n, -1, dtype=np.int64)
        revs = np.zeros(n, dtype=np.int64)
        conv = np.ones(n, dtype=np.bool_)
        if self.primitives:
            _batch_kernel(ops, outs, aa, bb, gstart, adj_ptr, adj_idx, lo, hi,
                          0 if method == "fbp" else 1, float(tol), self._max_rev(max_revisions),
                          bad_p, bad_v, revs, conv)
        return {"emptied_primitive": bad_p, "emptied_variable": bad_v, "revisions": revs,
                "converged": conv}

    def domains_array(self) -> tuple[np.ndarray, np.ndarray]:
        """Current domains as ``(lo, hi)`` float64 vectors in :attr:`names` order."""
        return np.array(self.lo, dtype=np.float64), np.array(self.hi, dtype=np.float64)
