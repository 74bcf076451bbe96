"""The tables of bound forms, one per channel and term (docs/dynamic-method.md, section 3,
"Bound forms and their shares"), and the terms they bound.

Each table lists its :class:`~.forms.BoundForm` in order; :func:`~.forms.combine`
intersects the enclosures of those that apply (or takes the smallest upper bound), each
at its share of the term's event (:data:`~.forms.SHARES`). Adding a form to a term is
one entry here (its ``compute`` reads the term's inputs object); a new term is a table
and the function that builds its inputs:

* :data:`MEAN_ABS_R`: the kernel mean of |r| in the accelerometers' transport terms
  (:func:`mean_abs_r`);
* :data:`SUPPORT_MEAN_ABS_R`: the mean |r| over a positions-only window's support;
* :data:`MEAN_ABS_Q`: the kernel mean of |q| in the tilt coupling of gyro_z and
  accel_y (:func:`mean_abs_q`);
* :data:`GAP_SPEED`: the speed part of accel_y's per-heading-gap form;
* :data:`TRANSPORT_Y`: accel_y's transport term ``mean(r u)`` (:func:`transport_y`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.dynamic.estimator.aided.base import pm, up
from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.forms import BoundForm, allot, combine, share
from imubounds.dynamic.estimator.aided.heading import heading_at, heading_mean, r_from_psidot
from imubounds.dynamic.estimator.aided.pitch_rate import q_centred_applies, q_centred_window, q_det
from imubounds.dynamic.estimator.aided.transport import (
    centred_applies,
    centred_window,
    det_mean,
    support_plan,
)
from imubounds.dynamic.estimator.aided.transport_blocks import block_bound
from imubounds.dynamic.estimator.aided.transport_fixes import fix_block_form, psi_variation
from imubounds.dynamic.estimator.aided.transport_gaps import gap_parts, speed_levels
from imubounds.dynamic.estimator.aided.transport_gyro import transport_by_gyro
from imubounds.dynamic.estimator.aided.transport_weighted import weighted_speed
from imubounds.dynamic.estimator.window_plan import ChannelPlan, LevelPlan
from imubounds.interval import IntervalArray as IA


@dataclass
class TermInputs:
    """What the forms of a term read: the windows, the run's context and the term's own
    inputs (``extra``), with a cache of the quantities the forms share (``cache``)."""

    w: WindowContext
    lp: LevelPlan
    tau: np.ndarray
    extra: dict[str, Any] = field(default_factory=dict)
    cache: dict[str, Any] = field(default_factory=dict)

    def __getattr__(self, name: str) -> Any:
        try:
            return self.__dict__["extra"][name]
        except KeyError as exc:
            raise AttributeError(name) from exc


# ------------------------------------------------------------------ mean |r|, mean |q|

def _det_r(x: TermInputs) -> np.ndarray:
    if "det" not in x.cache:
        x.cache["det"] = det_mean(x.w, x.lp.a1, x.lp.b2)
    det: np.ndarray = x.cache["det"]
    return det


def _heading_blocks(k: int, ch: str, det: Any, event: str = "mean_abs") -> BoundForm:
    applies = centred_applies if ch == "gyro_z" else q_centred_applies
    return BoundForm(
        f"heading_blocks_{k}", "3.9", ((event, "heading_blocks"),),
        lambda x: applies(x.w),
        lambda x, p: block_bound(x.w, x.lp, x.tau, p, det(x), k, ch),
        family="heading_blocks",
    )


def _det_q(x: TermInputs) -> np.ndarray:
    if "det" not in x.cache:
        x.cache["det"] = q_det(x.w, x.lp.a1, x.lp.b2)
    det: np.ndarray = x.cache["det"]
    return det


#: the kernel mean of |r| (upper bounds, the smallest used)
MEAN_ABS_R: tuple[BoundForm, ...] = (
    BoundForm("gyro_magnitude", "3.7", (), lambda x: True,
              lambda x, p: x.w.kernel_mag("gyro_z", x.lp, x.tau)),
    BoundForm("centred_window", "3.8", (("mean_abs", "centred_window"),),
              lambda x: centred_applies(x.w),
              lambda x, p: centred_window(x.w, x.lp, x.tau, p, _det_r(x))),
    *(_heading_blocks(k, "gyro_z", _det_r) for k in (1, 2, 4, 8, 16)),
)

#: the mean |r| over the support of a positions-only window (a boxcar over it; the fix
#: blocks' ``int |psi'|``): :data:`MEAN_ABS_R` without the window-centred form and the
#: blocks of 16 heading gaps, never ahead there (benchmarks/form_wins.py; their share
#: goes to the blocks left, ``SHARES["support_mean_abs"]``)
SUPPORT_MEAN_ABS_R: tuple[BoundForm, ...] = (
    MEAN_ABS_R[0],
    *(_heading_blocks(k, "gyro_z", _det_r, "support_mean_abs") for k in (1, 2, 4, 8)),
)

#: the kernel mean of |q| (gyro_y; blocks of seconds); blocks of 2 heading gaps retired
#: (never ahead: benchmarks/form_wins.py)
MEAN_ABS_Q: tuple[BoundForm, ...] = (
    BoundForm("gyro_magnitude", "3.7", (), lambda x: True,
              lambda x, p: x.w.kernel_mag("gyro_y", x.lp, x.tau)),
    BoundForm("centred_window", "3.10", (("mean_abs", "centred_window"),),
              lambda x: q_centred_applies(x.w),
              lambda x, p: q_centred_window(x.w, x.lp, x.tau, p, _det_q(x))),
    *(_heading_blocks(k, "gyro_y", _det_q) for k in (1, 4, 8, 16)),
)


def mean_abs_r(
    w: WindowContext, lp: LevelPlan, tau: np.ndarray, p: float, term: str = "mean_abs_r",
    table: tuple[BoundForm, ...] = MEAN_ABS_R,
) -> np.ndarray:
    """Bound of the kernel mean of |r| (true yaw rate) over each window, holding with
    probability ``>= 1 - p`` per window (``table``: :data:`MEAN_ABS_R`, or
    :data:`SUPPORT_MEAN_ABS_R`); ``term`` names it in the windows' record of forms."""
    return combine(term, table, TermInputs(w, lp, tau), p, w.forms, kind="upper")


def mean_abs_q(
    w: WindowContext, lp: LevelPlan, tau: np.ndarray, p: float, term: str = "mean_abs_q"
) -> np.ndarray:
    """Bound of the kernel mean of |q| (true pitch rate) over each window, holding with
    probability ``>= 1 - p`` per window (:data:`MEAN_ABS_Q`)."""
    if not w.imu.available["gyro_y"] or lp.a1.size == 0:
        return w.kernel_mag("gyro_y", lp, tau)
    return combine(term, MEAN_ABS_Q, TermInputs(w, lp, tau), p, w.forms, kind="upper")


# ------------------------------------------------------------------- accel_y mean(r u)

#: the speed part ``(1/tau) sum_k du_k int_k |r|`` of the per-heading-gap form
GAP_SPEED: tuple[BoundForm, ...] = (
    BoundForm("speed_levels", "3.17", (), lambda x: True,
              lambda x, p: speed_levels(x.parts, x.tau, x.r_mag)),
    BoundForm("weighted_speed", "3.18", (("accel_y.gap_speed", "weighted_speed"),),
              lambda x: x.weighted,
              lambda x, p: weighted_speed(x.w, x.lp, x.tau, x.bv, p,
                                          x.parts.floors(x.w, x.bv, x.lp), x.parts.earth)),
)


def mean_r_from_heading(
    w: WindowContext,
    lp: LevelPlan,
    tau: np.ndarray,
    trapezoid: bool,
    q_mean: np.ndarray | None = None,
) -> IA:
    """Kernel mean of the yaw rate r from the heading (docs/dynamic-method.md, (3.14));
    ``q_mean`` a bound of the kernel mean of |q| (else gyro_y's magnitude)."""
    if trapezoid:
        p1 = heading_mean(w, lp.a1, lp.b1)
        p2 = heading_mean(w, lp.a2, lp.b2)
    else:
        p1 = heading_at(w, lp.a1)
        p2 = heading_at(w, lp.a2)
    dpsi = (p2 - p1) / IA(tau)
    return r_from_psidot(w, dpsi, lp, tau, own_q=True, q_mean=q_mean)


def _speed_range(x: TermInputs, p: float) -> IA:
    """``u0 mean(r) +- du mean|r|`` (u0, du the centre and half-range of u's range)."""
    mean_r = mean_r_from_heading(x.w, x.lp, x.tau, x.plan.trapezoid, x.q_mean)
    u0 = 0.5 * (x.rng["u_lo"] + x.rng["u_hi"])
    du = up(0.5 * (x.rng["u_hi"] - x.rng["u_lo"]))
    return IA(u0) * mean_r + pm(du * x.r_mag)


def _heading_gaps(x: TermInputs, p: float) -> IA:
    """The per-heading-gap form, its speed part the :data:`GAP_SPEED` forms at ``p``."""
    if x.lp.a1.size == 0:
        return IA(np.zeros(0), np.zeros(0))
    parts = gap_parts(x.w, x.lp, x.tau, x.bv, x.q_mean)
    sx = TermInputs(x.w, x.lp, x.tau, {**x.extra, "parts": parts, "weighted": p > 0})
    speed = combine("accel_y.gap_speed", GAP_SPEED, sx, p, x.w.forms, kind="upper")
    return parts.enclosure(speed)


def _psi_var(x: TermInputs) -> np.ndarray:
    """``int |psi'|`` over the supports (:func:`.transport_fixes.psi_variation`), with the
    support's mean |r| at the fix blocks' ``psi_variation`` part: once per level."""
    if "psi_var" not in x.cache:
        p_fix = share("accel_y.transport", "fix_blocks") * x.p
        p_sup = allot(p_fix, "fix_blocks", ["accel_noise"])["psi_variation"]
        sup, L = support_plan(x.lp)
        r_sup = mean_abs_r(x.w, sup, L, p_sup, term="accel_y.support_mean_abs_r",
                           table=SUPPORT_MEAN_ABS_R)
        x.cache["psi_var"] = psi_variation(x.w, x.lp, r_sup)
    out: np.ndarray = x.cache["psi_var"]
    return out


def _fix_blocks(mb: int) -> BoundForm:
    return BoundForm(
        f"fix_blocks_{mb}", "3.20",
        (("accel_y.transport", "fix_blocks"), ("fix_blocks", "accel_noise")),
        lambda x: x.fixes,
        lambda x, p, within=None: fix_block_form(
            x.w, x.lp, x.tau, mb, x.r_mag, x.q_mean, _psi_var(x), p, within),
        family="fix_blocks", screened=True,
    )


#: the block lengths (fix gaps) of the fix-block forms; 24 and 32 retired: never ahead
#: of the others by more than 2.83 % and 0 % (benchmarks/form_wins.py over the sweeps,
#: the real drives and the simulator's trips); 8 (at most 0.44 % ahead there) stays: the
#: paper trip's widest accel_y window at tau 163.84 s is 0.8 % wider without it
FIX_BLOCKS = (4, 6, 8, 10, 12, 16)

#: accel_y's transport term ``mean(r u)`` (enclosures, intersected)
TRANSPORT_Y: tuple[BoundForm, ...] = (
    BoundForm("speed_range", "3.15", (), lambda x: True, _speed_range),
    BoundForm("heading_gaps", "3.16", (("accel_y.transport", "weighted_speed"),),
              lambda x: x.gaps, _heading_gaps),
    BoundForm("gyro_shape", "3.22", (("accel_y.transport", "gyro_shape"),),
              lambda x: x.fixes,
              lambda x, p: transport_by_gyro(x.w, x.lp, x.tau, x.rng["u_lo"], x.rng["u_hi"], p)),
    *(_fix_blocks(mb) for mb in FIX_BLOCKS),
)

#: every table, by channel and term (the forms that bound each)
TABLES: dict[tuple[str, str], tuple[BoundForm, ...]] = {
    ("accel_x", "mean_abs_r"): MEAN_ABS_R,
    ("accel_y", "transport"): TRANSPORT_Y,
    ("accel_y", "gap_speed"): GAP_SPEED,
    ("accel_y", "mean_abs_r"): MEAN_ABS_R,
    ("accel_y", "support_mean_abs_r"): SUPPORT_MEAN_ABS_R,
    ("accel_y", "mean_abs_q"): MEAN_ABS_Q,
    ("gyro_z", "mean_abs_q"): MEAN_ABS_Q,
}


def shared_bounds(
    w: WindowContext, lp: LevelPlan, tau: np.ndarray, applying: list[str], p: float
) -> tuple[np.ndarray, np.ndarray]:
    """The bounds of mean |r| and mean |q| that :data:`TRANSPORT_Y`'s forms share, at their
    parts of the window's event ``p`` with the forms ``applying`` (``mean_abs_q`` always;
    ``weighted_speed`` or ``fix_blocks`` and ``gyro_shape``; :data:`~.forms.SHARES`
    ``["accel_y.transport"]``)."""
    parts = allot(p, "accel_y.transport", ["mean_abs_q", *applying])
    r_mag = mean_abs_r(w, lp, tau, parts["mean_abs_r"], term="accel_y.mean_abs_r")
    q_mean = mean_abs_q(w, lp, tau, parts["mean_abs_q"], term="accel_y.mean_abs_q")
    return r_mag, q_mean


def transport_by_fixes(
    w: WindowContext, lp: LevelPlan, tau: np.ndarray, r_mag: np.ndarray,
    q_mean: np.ndarray | None, p: float,
) -> IA:
    """The fix-block forms of :data:`TRANSPORT_Y` alone, intersected (``p`` the window's
    event, of which they take their share)."""
    x = TermInputs(w, lp, tau, {"fixes": True, "r_mag": r_mag, "q_mean": q_mean, "p": p})
    fam = tuple(f for f in TRANSPORT_Y if f.family == "fix_blocks")
    return combine("accel_y.fix_blocks", fam, x, p)


def transport_inputs(
    w: WindowContext, plan: ChannelPlan, lp: LevelPlan, tau: np.ndarray, rng: Any, bv: Any
) -> TermInputs:
    """The inputs of :data:`TRANSPORT_Y`'s forms: which apply (velocity epochs and a
    heading: the heading gaps; positions only: the fix blocks and the gyro shape), and
    the shared bounds of mean |q| and mean |r| at their parts of the window's event
    (``w.p_window``; :data:`~.forms.SHARES` ``["accel_y.transport"]``)."""
    fixes = plan.trapezoid and w.ag.has_heading and w.ag.gnss_t.size > 2
    gaps = not plan.trapezoid and bv is not None and w.ag.has_heading
    applying = (["weighted_speed"] if gaps else []) + (
        ["fix_blocks", "gyro_shape"] if fixes else [])
    p = w.p_window
    r_mag, q_mean = shared_bounds(w, lp, tau, applying, p)
    return TermInputs(w, lp, tau, {"plan": plan, "rng": rng, "bv": bv, "fixes": fixes,
                                   "gaps": gaps, "r_mag": r_mag, "q_mean": q_mean, "p": p})


def transport_y(x: TermInputs) -> IA:
    """accel_y's ``mean(r u)``: the :data:`TRANSPORT_Y` forms intersected."""
    return combine("accel_y.transport", TRANSPORT_Y, x, x.p, x.w.forms)


__all__ = [
    "FIX_BLOCKS", "GAP_SPEED", "MEAN_ABS_Q", "MEAN_ABS_R", "SUPPORT_MEAN_ABS_R", "TABLES",
    "TRANSPORT_Y", "TermInputs", "mean_abs_q", "mean_abs_r", "mean_r_from_heading",
    "shared_bounds", "transport_by_fixes", "transport_inputs", "transport_y",
]
