"""The bound forms of the true-signal constraints, and how their probability is shared
(docs/dynamic-method.md, section 3, "Bound forms and their shares").

Where several forms bound the same term (accel_y's transport term ``mean(r u)``, the
kernel mean of |r| in both accelerometers' transport terms, gyro_z's mean |q|), each is
a :class:`BoundForm` in one table per channel and term (:mod:`.form_tables`), in order;
:func:`combine` evaluates the forms that apply and intersects their enclosures (or
takes the smallest of their upper bounds).

**The probability accounting, in one place.** A window's bounded event of probability
``p`` (the level's per-window share of the family ``imu_windows``) is split by
:data:`SHARES`: each form (or family of forms) that holds only on an event of its own
gets its named share of ``p``, a family's share split equally over the family's forms;
the part named :data:`REST` takes what the applying parts leave. By the union bound,
every form holds at once with probability ``>= 1 - p``, so the intersection of their
enclosures contains the true value with that probability: at least as tight as picking
the narrowest, and as sound (picking is sound only on the same joint event). A form
that needs no event of its own (a magnitude bound) has no share. Where the enclosures do
not meet (some event failed: a violation, not a margin), the narrowest is kept.

Which forms gave each window's bound is recorded (:class:`FormRecord`): margins.csv and
dynamic.json carry it (``bound_by``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.interval import IntervalArray as IA

#: the part of an event that takes what the applying parts leave
REST = "rest"

#: how each event's probability is shared, by name (docs/dynamic-method.md, (3.30)); a
#: family's share is split equally over its forms (``equal over ...``); every row sums to
#: at most 1 (:func:`check_shares`)
SHARES: dict[str, dict[str, float | str]] = {
    # gyro_z's window: the band and gyro_y's bound of the tilt coupling's mean |q|
    "gyro_z.window": {"band": 0.5, "mean_abs_q": 0.5},
    # the accelerometers' transport terms: the window's second bounded event (the gyros'
    # deviations; the first is the band's)
    "accel_y.transport": {
        "mean_abs_q": 0.1,  # tilt coupling q tan(phi) of r: a small term, a small share
        "weighted_speed": 0.3,  # boxcar windows with velocity epochs
        "fix_blocks": 0.35,  # positions only: the fix blocks (family)
        "gyro_shape": 0.1,  # positions only
        "mean_abs_r": REST,
    },
    "accel_x.transport": {"mean_abs_r": REST},
    # the speed part of accel_y's per-heading-gap form: the whole of its part
    "accel_y.gap_speed": {"weighted_speed": 1.0},
    # the bound of the kernel mean of |r| (or |q|): the window-centred form and the
    # heading blocks (family, equal over its block lengths)
    "mean_abs": {"centred_window": 0.5, "heading_blocks": 0.5},
    # the mean |r| over a positions-only window's support: the heading blocks alone
    "support_mean_abs": {"heading_blocks": 1.0},
    # the fix blocks: the support's mean |r| (psi's variation) and accel_x's white noise
    # in u's deviation (equal over the family's block lengths)
    "fix_blocks": {"accel_noise": 0.2, "psi_variation": REST},
    # accel_x's noise where it has a quantization part: its white and quantization parts
    "accel_noise": {"white": 0.5, "quantization": 0.5},
    # the gyro-shape form: the ramps' noise of r-bar, accel_x's white noise (one event for
    # D and D'), the gyro's mean square deviation MS, the split's two Gaussians
    "gyro_shape": {"mean_r": 0.4, "accel_noise": 0.2, "gyro_ms": 0.2, "split": 0.2},
    # the split's two Gaussians: the gyro's error on A's weights and on the clock's
    "split": {"accel_weights": 0.5, "clock_weights": 0.5},
}


def check_shares() -> None:
    """Every row of :data:`SHARES` sums to at most 1 (``REST`` counted as 0)."""
    for ev, row in SHARES.items():
        tot = sum(v for v in row.values() if not isinstance(v, str))
        if tot > 1.0 + 1e-12:
            raise ValueError(f"SHARES[{ev!r}] sums to {tot} > 1")


def share(event: str, part: str) -> float:
    """The named share ``SHARES[event][part]`` (a number; ``REST`` is :func:`allot`'s)."""
    v = SHARES[event][part]
    if isinstance(v, str):
        raise ValueError(f"SHARES[{event!r}][{part!r}] is {v!r}: use allot()")
    return float(v)


def allot(p: float, event: str, applying: Sequence[str]) -> dict[str, float]:
    """``p`` of ``event`` over its parts that apply (``applying``, in the row's order):
    each its named share of ``p``; the ``REST`` part ``(1 - s_1 - (s_2 + ... + s_n)) p``
    (``s_i`` the applying shares in the row's order); parts that do not apply get 0."""
    row = SHARES[event]
    out = {k: 0.0 for k in row}
    nums = [float(v) for k, v in row.items() if k in applying and not isinstance(v, str)]
    for k, v in row.items():
        if k in applying and not isinstance(v, str):
            out[k] = float(v) * p
    rest = (1.0 - nums[0]) - sum(nums[1:]) if nums else 1.0
    for k, v in row.items():
        if isinstance(v, str):
            out[k] = rest * p
    return out


@dataclass(frozen=True)
class BoundForm:
    """One form of a term's bound: ``name``, the equation of docs/dynamic-method.md it
    implements (``eq``, e.g. ``"3.20"``), ``share``: the path of :data:`SHARES` parts its
    own probability comes from (``(("accel_y.transport", "fix_blocks"), ("fix_blocks",
    "accel_noise"))``: that share of that share of the term's event; empty: it holds
    without an event of its own), ``family`` (forms sharing the last part equally, e.g.
    the block lengths; empty: none), ``applies(inputs)`` and ``compute(inputs, p)`` (an
    enclosure, or an upper bound for ``kind="upper"``; ``p`` the form's own
    probability). ``screened``: ``compute(inputs, p, within)`` also takes the
    intersection of the forms before it in the table (an enclosure term) and may skip its
    costly parts where it provably contains it (returning ``(-inf, inf)`` there: the
    intersection is the same)."""

    name: str
    eq: str
    share: tuple[tuple[str, str], ...]
    applies: Callable[[Any], bool]
    compute: Callable[..., Any]
    family: str = ""
    screened: bool = False


def form_probability(form: BoundForm, p: float, family_size: int = 1) -> float:
    """The probability of ``form`` out of its term's event ``p``: the shares along its
    path, then split equally over its family's ``family_size`` applying forms."""
    if not form.share:
        return 0.0
    q = p
    for ev, part in form.share:
        q = share(ev, part) * q
    return q / family_size if form.family else q


@dataclass
class FormRecord:
    """Which forms gave the bound of each window of a level, per term: ``codes[term]``
    indexes ``names[term]`` (``lo * n + hi``: the forms giving the lower and upper end;
    for an upper bound both the same)."""

    names: dict[str, tuple[str, ...]] = field(default_factory=dict)
    codes: dict[str, np.ndarray] = field(default_factory=dict)

    def clear(self) -> None:
        self.names.clear()
        self.codes.clear()

    def put(self, term: str, names: tuple[str, ...], lo: np.ndarray, hi: np.ndarray) -> None:
        self.names[term] = names
        self.codes[term] = lo.astype(np.int64) * len(names) + hi.astype(np.int64)

    def sides(self, term: str) -> tuple[np.ndarray, np.ndarray]:
        """The names of the forms giving each window's lower and upper end (object
        arrays; empty where ``term`` was not recorded)."""
        if term not in self.codes:
            return np.zeros(0, dtype=object), np.zeros(0, dtype=object)
        names = np.array(self.names[term], dtype=object)
        lo, hi = np.divmod(self.codes[term], len(names))
        return names[lo], names[hi]


def side_labels(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``name`` where both ends come from one form, else ``lo_name|hi_name``."""
    out = np.array(lo, dtype=object)
    diff = lo != hi
    if np.any(diff):
        out[diff] = [f"{a}|{b}" for a, b in zip(lo[diff], hi[diff], strict=True)]
    return out


def label_counts(labels: np.ndarray) -> str:
    """``"name n, name n"`` by count (largest first): the forms of a level's windows."""
    if labels.size == 0:
        return ""
    u, c = np.unique(labels.astype(str), return_counts=True)
    order = np.lexsort((u, -c))
    return ", ".join(f"{u[k]} {int(c[k])}" for k in order)


#: set by the tools that study the forms (benchmarks/form_wins.py): called by
#: :func:`combine` with ``(term, names, candidates, kind)``; None in normal runs. While
#: it is set no form is screened (every candidate computed whole, so a form's wins are
#: not hidden by the forms before it)
OBSERVER: Callable[[str, tuple[str, ...], list[Any], str], None] | None = None


def combine(
    term: str,
    table: Sequence[BoundForm],
    inputs: Any,
    p: float,
    record: FormRecord | None = None,
    kind: str = "enclosure",
) -> Any:
    """The forms of ``table`` that apply, each at its probability out of the term's event
    ``p`` (:func:`form_probability`), combined: ``kind="enclosure"``: the intersection
    of the enclosures (the narrowest where they do not meet); ``"upper"``: the smallest
    upper bound (non-finite values ignored). Records the forms giving each end in ``record``."""
    forms = [f for f in table if f.applies(inputs)]
    fam: dict[str, int] = {}
    for f in forms:
        if f.family:
            fam[f.family] = fam.get(f.family, 0) + 1
    cands: list[Any] = []
    for f in forms:
        pf = form_probability(f, p, fam.get(f.family, 1))
        if f.screened and kind == "enclosure" and cands and OBSERVER is None:
            within = IA(np.max(np.stack([c.lo for c in cands]), axis=0),
                        np.min(np.stack([c.hi for c in cands]), axis=0))
            cands.append(f.compute(inputs, pf, within))
        else:
            cands.append(f.compute(inputs, pf))
    names = tuple(f.name for f in forms)
    if OBSERVER is not None:
        OBSERVER(term, names, cands, kind)
    if kind == "upper":
        vals = np.stack([np.where(np.isfinite(c), c, np.inf) for c in cands])
        k = np.argmin(vals, axis=0)
        if record is not None:
            record.put(term, names, k, k)
        return np.take_along_axis(vals, k[None, :], axis=0)[0]
    lo = np.stack([c.lo for c in cands])
    hi = np.stack([c.hi for c in cands])
    ilo, ihi = np.argmax(lo, axis=0), np.argmin(hi, axis=0)
    col = np.arange(lo.shape[1])
    x_lo, x_hi = lo[ilo, col], hi[ihi, col]
    empty = x_lo > x_hi
    if np.any(empty):
        inarrow = np.argmin(hi - lo, axis=0)
        ilo = np.where(empty, inarrow, ilo)
        ihi = np.where(empty, inarrow, ihi)
        x_lo, x_hi = lo[ilo, col], hi[ihi, col]
    if record is not None:
        record.put(term, names, ilo, ihi)
    return IA(x_lo, x_hi)
