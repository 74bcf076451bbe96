"""What ``dynamic_margins`` returns: :class:`DynamicResult` (one mode's results).

``to_dict()`` is the ``modes.<mode>`` block of dynamic.json (schema in
docs/dynamic-method.md), ``to_frame()`` the margins table, ``plot(ax=None)`` the
margins against the averaging time on log-log axes with the stationary band.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.constants import G_HI, G_LO, ROUND_REL
from imubounds.dynamic.estimator import smoother as SM
from imubounds.dynamic.estimator.budget import CHANNELS, UNITS

SCHEMA_VERSION = "imubounds-dynamic/3"
PAPER_CHANNELS = ("accel_x", "accel_y", "gyro_z")

GUARANTEE_FULL = (
    "guaranteed: with probability at least {p:.4g} over the whole trip (every stated "
    "probabilistic bound holds at once, Bonferroni), every interval below contains the "
    "true value, provided the deterministic assumptions listed hold"
)
WITHDRAWN_FULL = (
    "NOT guaranteed: {n} check(s) of the stated assumptions failed (see violations); over "
    "their spans the intervals below are the estimator's output under assumptions the data "
    "contradict, not a guarantee (with every assumption true they would hold with "
    "probability at least {p:.4g})"
)
NOT_GUARANTEED = (
    "not guaranteed: the paper's method (per-step k*sigma_c bounds, per-step GPS boxes); "
    "its intervals are not proven to contain the truth"
)


def _pct(x: np.ndarray, q: float) -> float | None:
    x = x[np.isfinite(x)]
    return float(np.percentile(x, q)) if x.size else None


def truth_at(drive: Any, t_abs: np.ndarray, origin: tuple[float, float, float] | None) -> Any:
    """The drive's truth at absolute times ``t_abs`` in the estimator's ENU frame:
    dict of east, north (m), psi (model heading, rad, unwrapped), u, v (m/s) and the
    extra series (bias_<ch>, ...); NaN outside the truth's span and between two truth
    rows one of which has no value (an empty cell, a short row).

    Positions go through the geodetic coordinates at the truth's own height (its
    ``up_m`` over its origin, the origin's ``origin_alt_m``; the GNSS origin's altitude
    where the truth does not give one), so that a trip at 1,600 m is not projected onto
    the ellipsoid."""
    tr = drive.truth
    if tr is None:
        return None
    tt = np.asarray(tr.t, dtype=float)
    inside = (t_abs >= tt[0] - 1e-9) & (t_abs <= tt[-1] + 1e-9)

    def at(x: np.ndarray | None) -> np.ndarray | None:
        if x is None:
            return None
        x = np.asarray(x, dtype=float)
        fin = np.isfinite(x)
        if not fin.any():
            return np.full(t_abs.shape, np.nan)
        y = np.interp(t_abs, tt[fin], x[fin])
        both = np.interp(t_abs, tt, fin.astype(float)) >= 1.0 - 1e-12
        return np.where(inside & both, y, np.nan)

    e, n = np.asarray(tr.east_m, float), np.asarray(tr.north_m, float)
    if origin is not None and all(math.isfinite(v) for v in tr.origin[:2]):
        t_org = (tr.origin[0], tr.origin[1],
                 tr.origin[2] if math.isfinite(tr.origin[2]) else origin[2])
        if tuple(origin) != t_org:
            from imubounds.geodesy import enu_to_geodetic_3d, geodetic_to_enu

            up = tr.extra.get("up_m")
            up = np.zeros_like(e) if up is None else np.asarray(up, float)
            fin_up = np.isfinite(up)
            if fin_up.any() and not fin_up.all():  # a row without a height (a short row):
                up = np.interp(tt, tt[fin_up], up[fin_up])  # its neighbours' (mm horizontally)
            up = np.nan_to_num(up)
            lat, lon, alt = enu_to_geodetic_3d(e, n, up, t_org)
            e, n, _ = geodetic_to_enu(lat, lon, alt, origin=(origin[0], origin[1], origin[2]))
    elif origin is None:
        # no GNSS: positions relative to the state at the first requested time
        e = e - np.interp(t_abs[0], tt, e)
        n = n - np.interp(t_abs[0], tt, n)
    out: dict[str, Any] = {"east": at(e), "north": at(n)}
    if tr.heading_rad is not None:
        h = np.asarray(tr.heading_rad, float)
        psi = np.full(h.shape, np.nan)
        fin = np.isfinite(h)  # unwrapped over the rows that have a heading (a NaN poisons
        psi[fin] = np.unwrap(0.5 * math.pi - h[fin])  # everything after it otherwise)
        out["psi"] = at(psi)
    out["u"] = at(tr.u_mps)
    out["v"] = at(tr.v_mps)
    for k, v in tr.extra.items():
        out[k] = at(v)
    return out


def _inside_angle(lo: np.ndarray, hi: np.ndarray, x: np.ndarray) -> np.ndarray:
    """x (rad) inside [lo, hi] modulo 2 pi (an unbounded interval contains everything)."""
    fin = np.isfinite(lo) & np.isfinite(hi)
    mid = np.where(fin, 0.5 * (np.where(fin, lo, 0) + np.where(fin, hi, 0)), x)
    m = np.round((mid - x) / (2 * math.pi))
    xx = x + 2 * math.pi * m
    return np.asarray(~fin & (lo <= hi) | ((lo <= xx) & (xx <= hi)), dtype=bool)


@dataclass
class DynamicResult:
    """The results of one mode of the dynamic analysis.

    Attributes
    ----------
    mode:
        ``"full"`` (guaranteed margins, the default) or ``"paper"``.
    summary:
        The dynamic.json block of this mode (see :meth:`to_dict`).
    full, paper:
        The underlying computations (:class:`~imubounds.dynamic.estimator.full.FullRun`
        or the paper estimator's result).
    """

    mode: str
    summary: dict[str, Any]
    full: Any = None
    paper: Any = None
    extra: dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        g = "guaranteed" if self.summary.get("guaranteed") else "not guaranteed"
        return f"DynamicResult(mode={self.mode!r}, {g}, verdicts={self.verdicts})"

    def to_dict(self) -> dict[str, Any]:
        """The ``modes.<mode>`` block of dynamic.json as plain JSON types (numpy numbers
        become Python numbers, nan/inf become None), as ``imubounds dynamic`` writes it."""
        from imubounds.io.outputs import to_jsonable

        out: dict[str, Any] = to_jsonable(self.summary)
        return out

    def to_frame(self) -> Any:
        """The margins table: one row per channel and averaging time (SI units)."""
        import pandas as pd

        rows = []
        for ch, lst in self.summary.get("margins", {}).items():
            for r in lst:
                rows.append({"channel": ch, **r})
        return pd.DataFrame(rows)

    @property
    def verdicts(self) -> dict[str, str]:
        """Channel -> verdict (``consistent``, ``exceeds`` or ``undecided``)."""
        return dict(self.summary.get("verdict", {}))

    def states_frame(self) -> Any:
        """Mode full: the smoother's state intervals at its epochs (``states.csv``):
        ``time_s`` and ``<state>_lo_<unit>``, ``<state>_hi_<unit>`` for east and north
        (m), heading (rad), body velocities u, v and speed (m/s), and roll, pitch (rad)
        where the attitude states ran (docs/dynamic-method.md section 3b)."""
        import pandas as pd

        from imubounds.errors import AnalysisError

        run = self.full
        if run is None or run.smoother is None:
            raise AnalysisError(
                "no state intervals: they come from mode full's whole-trip smoother"
            )
        sm = run.smoother
        from imubounds.dynamic.estimator.violations import epoch_mask

        t_abs = sm.te + run.ctx.imu.t0
        df = pd.DataFrame({"time_s": t_abs})
        for name, ((lo, hi), unit) in state_intervals(run.ctx, sm).items():
            u = unit.replace("/", "p")
            df[f"{name}_lo_{u}"] = lo
            df[f"{name}_hi_{u}"] = hi
        viol = self.summary.get("violations", [])
        df["guaranteed"] = (~epoch_mask(viol, t_abs)).astype(int)
        return df

    def plot(self, ax: Any = None) -> Any:
        """Margins against tau (log-log): median and max half-width of the guaranteed
        interval of the window-mean error, and the stationary band, per channel (accel in
        m/s^2 on the left axes, gyro in deg/s on the right). Returns the Figure."""
        from imubounds.report.dynamic_plots import plot_margins

        return plot_margins(self.summary, ax=ax)


# -------------------------------------------------------------------------- full


def heading_sensor(heading: Any) -> dict[str, Any] | None:
    """The heading sensor's errors against the GNSS course (compass frame, clockwise,
    deg): ``model``, the compass error model estimated from ``d = heading - course``
    (``course_check.estimate_heading_model``: constant offset and harmonics 1 and 2, each
    with an interval, the detected ones taken off the headings, ``applied``, and the
    remainder bound that replaces the stated deviation bound); ``offset``, its constant
    term (or, without a model, the signed mean of ``d`` +- the check's limit of
    ``course_check.check_against_course``); ``course_check_passed``, the check of the
    corrected heading (a failure withdraws the guarantee; docs/dynamic-method.md, 5b)."""
    if heading is None or not heading.t.size:
        return None
    cc = heading.course_check or {}
    model = getattr(heading, "model", None)
    applied = bool(model and model.get("applied"))
    out: dict[str, Any] = {
        "source": heading.source,
        "deviation_bound_deg": math.degrees(heading.deviation_bound_rad),
        "deviation_source": (
            "remainder of the compass error model (estimated against the GNSS course)"
            if applied else heading.deviation_source),
        "noise_sigma_deg": math.degrees(heading.noise_sigma_rad),
        "independent_of_gnss": bool(heading.independent_of_gnss),
        "course_check_passed": cc.get("passed"),
        "offset": None,
        "model": model,
        "modelled": (
            "constant offset and harmonics 1-2 estimated against the GNSS course, the "
            "detected ones applied (their interval half-widths in the deviation bound); "
            "the rest within the stated deviation bound (an assumption, tested)"
            if model else
            "offset within the deviation bound (an assumption, tested); one-cycle "
            "deviation by the calibration; higher harmonics within the deviation bound or "
            "the heading clock allowance"),
    }
    if model:
        c0 = model["coefficients"][0]
        out["offset"] = {
            "estimate_deg": c0["estimate_deg"],
            "interval_deg": list(c0["interval_deg"]),
            "epochs": int(model["epochs"]),
            "method": "constant term of the compass error model " + model["method"],
            "applied": bool(c0["applied"]),
        }
    elif cc.get("limit_deg") is not None and cc.get("mean_diff_deg") is not None:
        m, lim = float(cc["mean_diff_deg"]), float(cc["limit_deg"])
        out["offset"] = {
            "estimate_deg": m,
            "interval_deg": [m - lim, m + lim],
            "epochs": int(cc.get("n", 0)),
            "method": "signed mean of heading - GNSS course over the epochs >= the check's "
            "speed, +- the check's limit (deviation bound + mean sideslip bound + the heading "
            "clock allowance x mean |yaw rate| + k sigma of the mean)",
            "applied": False,
        }
    return out


def full_summary(run: Any, drive: Any) -> dict[str, Any]:
    """dynamic.json block of mode full from a :class:`~imubounds.dynamic.estimator.full.FullRun`."""
    from imubounds.dynamic.estimator.full import noise_budget_rows
    from imubounds.dynamic.estimator.violations import collect

    ctx = run.ctx
    ag = ctx.aiding
    sm = run.smoother
    p = 1.0 - ctx.alpha.alpha
    span = (
        (float(sm.te[0] + ctx.imu.t0), float(sm.te[-1] + ctx.imu.t0))
        if sm is not None and sm.te.size
        else (float(ctx.te[0] + ctx.imu.t0), float(ctx.te[-1] + ctx.imu.t0))
    )
    viol = collect(run, span)
    checks: dict[str, Any] = {}
    if sm is not None:
        from imubounds.dynamic.estimator.residual_checks import residual_checks
        from imubounds.dynamic.estimator.violations import CHECK_SHARE

        rv, checks = residual_checks(ctx, sm, ctx.alpha.alpha * CHECK_SHARE, span)
        viol += rv
    out: dict[str, Any] = {
        "mode": "full",
        "guaranteed": not viol,
        "statement": (
            GUARANTEE_FULL.format(p=p) if not viol else WITHDRAWN_FULL.format(n=len(viol), p=p)
        ),
        "violations": [v.to_dict() for v in viol],
        "residual_checks": checks,
        "timing": {k: v.to_dict() for k, v in ctx.timing.items()},
        "heading_sensor": heading_sensor(ctx.heading),
        "alpha": ctx.alpha.to_dict(),
        "assumptions": _assumptions(ctx),
        "notes": ctx.notes + run.notes,
    }
    out["budget"] = {ch: [t.to_dict() for t in noise_budget_rows(ctx, ch)] for ch in CHANNELS}
    out["aiding_budget"] = {k: [t.to_dict() for t in v] for k, v in ag.budget.items()}
    out["vehicle"] = {
        "kind": ctx.vehicle.kind,
        "max_speed_mps": ctx.vehicle.max_speed,
        "max_accel_mps2": ctx.vehicle.max_accel,
        "max_jerk_mps3": ctx.vehicle.max_jerk,
        "max_rate_dps": ctx.vehicle.max_rate * 180 / math.pi,
        "max_ang_accel_dps2": ctx.vehicle.max_ang_accel * 180 / math.pi,
        "max_tilt_deg": ctx.vehicle.max_tilt * 180 / math.pi,
        "lateral_speed_bound_mps": ctx.vehicle.lateral_speed_bound_mps,
        "vertical_speed_bound_mps": ctx.vehicle.vertical_bound,
        "sources": ctx.vehicle.sources,
        "pitch": _pitch_source(ctx),
    }
    from imubounds.dynamic.estimator.attitude.report import attitude_summary

    att = attitude_summary(ctx, drive)
    if att is not None:
        out["attitude"] = att
    out["margins"] = {}
    out["verdict"] = {}
    out["verdict_detail"] = {}
    out["channels_not_analysed"] = {}
    for ch in CHANNELS:
        m = run.margins.get(ch)
        plan = ctx.plans.get(ch)
        if m is None or not m.levels:
            reason = plan.reason if plan is not None and plan.reason else "no windows"
            out["channels_not_analysed"][ch] = reason
            if ch in PAPER_CHANNELS:
                out["verdict"][ch] = "undecided"
                out["verdict_detail"][ch] = {"reason": reason}
                out["margins"][ch] = []
            continue
        out["margins"][ch] = [
            {**row, "unit": UNITS[ch]} for row in m.table()
        ]
        out["verdict"][ch] = m.verdict
        out["verdict_detail"][ch] = m.to_dict()
    # verdicts resting on a margin within 5 % of the band (verdicts.fragility): not decided
    out["fragile_verdicts"] = [ch for ch, d in out["verdict_detail"].items() if d.get("fragile")]
    # bias intervals
    k_to = ctx.alpha.k("imu_turn_on")
    bias: dict[str, Any] = {}
    rows = {"accel_x": 0, "accel_y": 1, "gyro_z": 2}
    for ch in CHANNELS:
        cn = ctx.noise[ch]
        # the in-run wander at every sample: the model's (flicker + K, R) or the stated
        # drift bound's (its window mean + the sample's deviation), budget.Wander
        wd = ctx.wander[ch]
        wander = float(wd.pick(ctx.k_ps * cn.flicker_sigma() + wd.kr, wd.point))
        if sm is not None and ch in rows:
            lo, hi = (float(x) for x in sm.beta[rows[ch]])
            src = "contracted by the windows and the smoother"
            if hi - lo >= 2 * cn.turn_on_bound(k_to) * (1 - 1e-9):
                src = "turn-on prior (the windows and the smoother did not contract it)"
        else:
            b = cn.turn_on_bound(k_to)
            lo, hi = -b, b
            src = "turn-on prior (not contracted)"
        bias[ch] = {
            "unit": UNITS[ch],
            "constant_part": [lo, hi],
            "over_trip": [float(np.nextafter(lo - wander, -np.inf)),
                          float(np.nextafter(hi + wander, np.inf))],
            "wander_bound": wander,
            "wander_rule": wd.rule,
            "constant_part_prior": [-cn.turn_on_bound(k_to), cn.turn_on_bound(k_to)],
            "source": src,
        }
    out["bias"] = bias
    if sm is not None:
        out["smoother"] = {
            "epochs": int(sm.te.size),
            "rounds": sm.rounds,
            "sweeps": sm.sweeps,
            "tolerance": float(ctx.opts.tol),
            "links_dropped": int(np.sum(~sm.link)),
            "note": sm.beta_note,
        }
        out["empty_intersections"] = {
            "count": len(sm.dropped),
            "rule": "q-relaxed intersection (q = 1) of each epoch's measurement and the "
            "predictions from the past and from the future; the odd one is dropped",
            "dropped": [d.to_dict() for d in sm.dropped[:500]],
            "by_sensor": _count_by(sm.dropped),
        }
        out["contracted_aiding"] = _contracted(ctx, sm)
        states = state_intervals(ctx, sm)
        out["states_summary"] = {
            k: {"median_halfwidth": _pct(0.5 * (v[1] - v[0]), 50), "unit": u}
            for k, (v, u) in states.items()
        }
        if drive.truth is not None:
            out["enclosure"] = _enclosure(ctx, sm, drive, states, bias)
    if drive.truth is not None:
        out["margins_truth"] = _margins_truth(run, drive)
    return out


def _count_by(dropped: list[Any]) -> dict[str, int]:
    c: dict[str, int] = {}
    for d in dropped:
        c[d.sensor] = c.get(d.sensor, 0) + 1
    return c


def _pitch_source(ctx: Any) -> dict[str, Any]:
    """Where the pitch intervals of the gravity terms come from."""
    ag = ctx.aiding
    m = ctx.vehicle.max_tilt * 180 / math.pi
    if ag.has_attitude:
        return {"source": f"attitude stream ({ag.att_source})"}
    if ag.pitch is not None:
        return {
            "source": "GNSS altitude, gyros and non-holonomic bounds (pitch_gnss.py)",
            "median_halfwidth_deg": ag.pitch.median_halfwidth * 180 / math.pi,
            "max_tilt_deg": m,
        }
    return {"source": f"max tilt ({ctx.vehicle.sources.get('max_tilt', 'default')})",
            "median_halfwidth_deg": m}


def _assumptions(ctx: Any) -> list[str]:
    v = ctx.vehicle
    a = [
        "one clock for every stream; IMU samples are the means of the true signal over "
        f"their periods (time stamp at the {ctx.imu.stamp} of the period)",
        "the IMU error model of the budget (turn-on bias, flicker bias instability, white "
        "noise, quantization, rate random walk, scale and misalignment within their bounds)",
        f"the vehicle: speed <= {v.max_speed:g} m/s, horizontal acceleration <= "
        f"{v.max_accel:g} m/s^2, jerk <= {v.max_jerk:g} m/s^3, angular rate <= "
        f"{v.max_rate * 180 / math.pi:g} deg/s, angular acceleration <= "
        f"{v.max_ang_accel * 180 / math.pi:g} deg/s^2, tilt <= {v.max_tilt * 180 / math.pi:g} deg",
        f"local gravity between {G_LO:g} and {G_HI:g} m/s^2; Earth rate and Coriolis bounded",
        "the accelerometer windows use the gyros only as magnitude bounds in second-order "
        "(transport) terms, never the channel they judge",
    ]
    if v.kind == "ground":
        src = v.sources.get("vertical_bound", "default")
        a.append(
            f"ground vehicle: |vertical body velocity w| <= {v.vertical_bound:g} m/s "
            "(suspension heave, speed x the IMU's pitch against the path; "
            + ("default: state vehicle.vertical_speed_bound_mps or --vertical-speed-bound)"
               if src.startswith("default") else f"{src})")
        )
    if v.lateral_speed_bound_mps is not None:
        a.append(f"non-holonomic: |lateral body velocity| <= {v.lateral_speed_bound_mps:g} m/s")
    if not ctx.aiding.has_gnss:
        a.append("no GNSS: positions are relative to the start point (0, 0)")
    else:
        a.append(
            "GNSS errors: isotropic Gaussian, independent from fix to fix, horizontal "
            "position error per axis sigma = DRMS / sqrt 2 (radius from the Rayleigh law), "
            "velocity error per component sigma = gnss.vel_sigma_mps; the residual checks "
            "test the runs and the tails of this model (residual_checks)"
        )
    if ctx.aiding.head_from_course:
        a.append(
            "the vehicle does not reverse (horizontal velocity pointing forward): heading "
            "from the GNSS course within asin(lateral bound / speed) (--reverses turns it off)"
        )
    lever = ctx.drive.settings.lever_arm_m
    if lever is None:
        a.append("GNSS antenna at the IMU (no lever arm given)")
    else:
        a.append(
            "GNSS lever arm: its horizontal length is added to the position radius and, times "
            "the yaw-rate bound, to the velocity radius"
        )
    a.append(
        "change test: the in-run bias (flicker) changes between adjacent windows as its "
        "model says (the Allan statistic); the turn-on bias cancels"
    )
    return a + list(ctx.assumptions)


def state_intervals(ctx: Any, sm: Any) -> dict[str, Any]:
    """State intervals at the smoother's epochs: name -> ((lo, hi), unit) for east,
    north, heading, body velocities u, v (from the horizontal ones) and speed."""
    from imubounds.interval import IntervalArray as IA
    from imubounds.interval import cos, sin

    X = sm.X
    veh = ctx.vehicle
    rl, rh, pl, ph = ctx.aiding.tilt(sm.te, veh)
    sr, cr = sin(IA(rl, rh)), cos(IA(rl, rh))
    sp, cp = sin(IA(pl, ph)), cos(IA(pl, ph))
    uh = IA(X[:, SM.UH, 0], X[:, SM.UH, 1])
    vh = IA(X[:, SM.VH, 0], X[:, SM.VH, 1])
    wb = veh.vertical_bound
    w = IA(np.full(sm.te.size, -wb), np.full(sm.te.size, wb))
    v = (vh + sr * w) / cr
    if veh.lateral_speed_bound_mps is not None:
        lb = veh.lateral_speed_bound_mps
        v = v & IA(np.full(v.shape, -lb), np.full(v.shape, lb))
    u = (uh + sr * sp * v + cr * sp * w) / cp
    S2 = IA(X[:, SM.VE, 0], X[:, SM.VE, 1]) ** 2 + IA(X[:, SM.VN, 0], X[:, SM.VN, 1]) ** 2
    from imubounds.interval import sqrt

    S = sqrt(S2)
    out: dict[str, Any] = {
        "east": ((X[:, SM.E, 0], X[:, SM.E, 1]), "m"),
        "north": ((X[:, SM.N, 0], X[:, SM.N, 1]), "m"),
        "heading": ((X[:, SM.PSI, 0], X[:, SM.PSI, 1]), "rad"),
        "u": ((u.lo, u.hi), "m/s"),
        "v": ((v.lo, v.hi), "m/s"),
        "speed": ((S.lo, S.hi), "m/s"),
    }
    st = getattr(ctx, "attitude", None)
    if st is not None and st.te.size == sm.te.size:  # the attitude states' nodes
        for ax in ("roll", "pitch"):
            x = st.angle(ax, "full").nodes
            out[ax] = ((x.lo, x.hi), "rad")
    return out


def _enclosure(ctx: Any, sm: Any, drive: Any, states: dict[str, Any], bias: Any) -> dict[str, Any]:
    te_abs = sm.te + ctx.imu.t0
    tr = truth_at(drive, te_abs, ctx.aiding.origin)
    enc: dict[str, Any] = {}
    first_miss: dict[str, Any] = {}

    def share(name: str, ok: np.ndarray, valid: np.ndarray) -> None:
        if valid.any():
            enc[name] = float(np.mean(ok[valid]))
            bad = np.flatnonzero(valid & ~ok)
            if bad.size:
                first_miss[name] = float(te_abs[bad[0]])

    (el, eh), _ = states["east"]
    (nl, nh), _ = states["north"]
    te_ok = np.isfinite(tr["east"]) & np.isfinite(tr["north"])
    ok = (el <= tr["east"]) & (tr["east"] <= eh) & (nl <= tr["north"]) & (tr["north"] <= nh)
    share("position", ok, te_ok)
    if tr.get("psi") is not None:
        (pl, ph), _ = states["heading"]
        valid = np.isfinite(tr["psi"])
        share("heading", _inside_angle(pl, ph, np.nan_to_num(tr["psi"])), valid)
    for q in ("u", "v"):
        if tr.get(q) is not None:
            (lo, hi), _ = states[q]
            x = tr[q]
            share(q, (lo <= x) & (x <= hi), np.isfinite(x))
    if tr.get("u") is not None:
        (lo, hi), _ = states["speed"]
        x = np.hypot(tr["u"], tr["v"] if tr.get("v") is not None else 0.0)
        x = x * np.cos(tr["pitch_rad"]) if tr.get("pitch_rad") is not None else x
        share("speed", (lo <= x * (1 + ROUND_REL)) & (x <= hi * (1 + ROUND_REL)), np.isfinite(x))
    # biases: the truth's bias series at the IMU rate, inside the over-trip interval
    tt = np.asarray(drive.truth.t, dtype=float)
    for ch in CHANNELS:
        key = f"bias_{ch}"
        if key in drive.truth.extra:
            x = np.asarray(drive.truth.extra[key], dtype=float)
            lo, hi = bias[ch]["over_trip"]
            valid = np.isfinite(x)
            ok = (lo <= x) & (x <= hi)
            if valid.any():
                enc[key] = float(np.mean(ok[valid]))
                bad = np.flatnonzero(valid & ~ok)
                if bad.size:
                    first_miss[key] = float(tt[bad[0]])
    enc["epochs"] = int(np.sum(te_ok))
    enc["first_miss_t_s"] = first_miss
    return enc


def _contracted(ctx: Any, sm: Any) -> dict[str, Any]:
    """Input half-width vs contracted half-width of each aiding sensor (median, p95)."""
    ag = ctx.aiding
    te = sm.te
    X = sm.X
    out: dict[str, Any] = {}

    def stats(inp: np.ndarray, con: np.ndarray, unit: str) -> dict[str, Any]:
        return {
            "unit": unit,
            "input_halfwidth_median": _pct(inp, 50),
            "input_halfwidth_p95": _pct(inp, 95),
            "contracted_halfwidth_median": _pct(con, 50),
            "contracted_halfwidth_p95": _pct(con, 95),
            "epochs": int(np.sum(np.isfinite(inp))),
        }

    if ag.has_gnss:
        i = np.searchsorted(te, ag.gnss_t).clip(0, te.size - 1)
        ok = te[i] == ag.gnss_t
        con = 0.5 * np.maximum(X[i, SM.E, 1] - X[i, SM.E, 0], X[i, SM.N, 1] - X[i, SM.N, 0])
        out["position"] = stats(ag.gnss_h[ok], con[ok], "m")
        if ag.has_gvel:
            okv = ok & ag.gvel_ok
            con = 0.5 * np.maximum(
                X[i, SM.VE, 1] - X[i, SM.VE, 0], X[i, SM.VN, 1] - X[i, SM.VN, 0]
            )
            out["velocity"] = stats(ag.gvel_hi[okv], con[okv], "m/s")
    if ag.has_heading:
        i = np.searchsorted(te, ag.head_t).clip(0, te.size - 1)
        ok = te[i] == ag.head_t
        con = 0.5 * (X[i, SM.PSI, 1] - X[i, SM.PSI, 0])
        out["heading"] = stats(ag.head_h[ok] * 180 / math.pi, con[ok] * 180 / math.pi, "deg")
    if ag.has_bvel:
        i = np.searchsorted(te, ag.bvel_t).clip(0, te.size - 1)
        ok = te[i] == ag.bvel_t
        con = 0.5 * (X[i, SM.UH, 1] - X[i, SM.UH, 0])
        out["speed"] = stats(ag.bvel_h[ok], con[ok], "m/s")
    elif ag.has_gvel:
        i = np.searchsorted(te, ag.gnss_t).clip(0, te.size - 1)
        ok = (te[i] == ag.gnss_t) & ag.gvel_ok
        from imubounds.interval import IntervalArray as IA
        from imubounds.interval import sqrt

        hv = ag.gvel_hi[ok]
        ve = IA(ag.gvel_e[ok] - hv, ag.gvel_e[ok] + hv)
        vn = IA(ag.gvel_n[ok] - hv, ag.gvel_n[ok] + hv)
        s_in = sqrt(ve**2 + vn**2)
        s_co = sqrt(
            IA(X[i[ok], SM.VE, 0], X[i[ok], SM.VE, 1]) ** 2
            + IA(X[i[ok], SM.VN, 0], X[i[ok], SM.VN, 1]) ** 2
        )
        out["speed"] = stats(s_in.radius(), s_co.radius(), "m/s")
    return out


def _margins_truth(run: Any, drive: Any) -> dict[str, Any]:
    """Share of windows whose aided interval [x_W] contains the true kernel mean, when
    the truth carries the true signal's sample means at the IMU samples (truth.extra
    ``true_<ch>``, or ``<ch>`` on the IMU's time stamps)."""
    out: dict[str, Any] = {}
    ex = drive.truth.extra
    ctx = run.ctx
    from imubounds.dynamic.estimator.inputs import PiecewiseSignal

    imu_t = np.asarray(drive.imu.t, dtype=float)
    tt = np.asarray(drive.truth.t, dtype=float)
    same_t = tt.size == imu_t.size and bool(np.allclose(tt, imu_t, rtol=0, atol=1e-9))
    for ch, m in run.margins.items():
        key = f"true_{ch}" if f"true_{ch}" in ex else (ch if ch in ex and same_t else None)
        if key is None:
            continue
        x = np.asarray(ex[key], dtype=float)
        if x.size != ctx.imu.n or ctx.imu.n_gaps:
            continue
        sig = PiecewiseSignal(ctx.imu.bnd, x)
        n_ok = n_all = 0
        worst = 0.0
        for lv, lp in zip(m.levels, [p for p in ctx.plans[ch].levels if p.n], strict=False):
            tm = sig.kernel_mean(lp.a1, lp.b1, lp.a2, lp.b2, lp.tau)
            ok = (lv.x_lo <= tm.hi) & (tm.lo <= lv.x_hi)
            n_ok += int(ok.sum())
            n_all += ok.size
            if (~ok).any():
                miss = np.maximum(lv.x_lo - tm.hi, tm.lo - lv.x_hi)
                worst = max(worst, float(np.max(miss[~ok])))
        out[ch] = {"windows": n_all, "enclosed_fraction": n_ok / n_all if n_all else None,
                   "worst_miss": worst}
    return out


def applied_corrections(s: dict[str, Any]) -> list[str]:
    """One line per correction mode ``full`` estimated from the data and applied: a
    stream's clock offset (``timing``; ``bounded:`` where the stamps stay and the data's
    interval is budgeted instead) and the compass error model (``heading_sensor``)."""
    out: list[str] = []
    for stream, tm in (s.get("timing") or {}).items():
        if isinstance(tm, dict) and tm.get("applied"):
            lo, hi = tm.get("interval_s") or (float("nan"), float("nan"))
            if tm.get("offset_s") == 0.0:  # the stamps stay, the data's interval is budgeted
                out.append(
                    f"bounded: {stream} clock offset within [{lo:+.3f}, {hi:+.3f}] s from the "
                    f"data, budgeted (stamps kept; timing.{stream}.note in dynamic.json)"
                )
                continue
            out.append(
                f"applied: {stream} clock offset {tm['offset_s']:+.3f} s [{lo:+.3f}, {hi:+.3f}] "
                f"estimated from the data (true time = stamp - offset; timing in dynamic.json)"
            )
    model = (s.get("heading_sensor") or {}).get("model") or {}
    if model.get("applied"):
        terms = ", ".join(
            ("offset" if c["cycle"] == 0 else f"{c['term']} {c['cycle']}psi")
            + f" {c['estimate_deg']:+.2f} [{c['interval_deg'][0]:+.2f}, "
            f"{c['interval_deg'][1]:+.2f}] deg"
            for c in model.get("coefficients", []) if c.get("applied"))
        out.append(
            f"applied: compass error estimated against the GNSS course and taken off ({terms}); "
            "heading.errors: stated in drive.yaml keeps the stated bound instead"
        )
    return out
