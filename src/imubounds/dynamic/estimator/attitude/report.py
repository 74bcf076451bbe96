"""The attitude states in the output (docs/dynamic-method.md, section 3b, "Checks" and
section 7, ``attitude``): failed checks as violations, the notes and budget rows, the
summary block of dynamic.json and the comparison with a truth."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from imubounds.dynamic.estimator.attitude.states import USES, VARIANT_OF, AttitudeStates
from imubounds.dynamic.estimator.budget import Term
from imubounds.units import DEG

#: name of the failed checks (violations)
TEST_WINDOW = "attitude: accelerometer window against the gyro-carried roll/pitch"
TEST_CHAIN = "attitude: roll/pitch nodes against the gyro increments between them"


def _spans(t: np.ndarray, bad: np.ndarray) -> list[tuple[float, float]]:
    idx = np.flatnonzero(bad)
    out: list[tuple[float, float]] = []
    if idx.size == 0:
        return out
    start = prev = int(idx[0])
    for i in idx[1:]:
        if i > prev + 1:
            out.append((float(t[start]), float(t[prev])))
            start = int(i)
        prev = int(i)
    out.append((float(t[start]), float(t[prev])))
    return out


def _hw_deg(x: Any) -> np.ndarray:
    return np.asarray(0.5 * (x.hi - x.lo) / DEG)


def attitude_checks(ctx: Any) -> None:
    """Violations of the states' checks, their budget rows and notes."""
    from imubounds.dynamic.estimator import violations as V
    from imubounds.dynamic.estimator.attitude.mount import mount_checks

    ctx.attitude_mount = mount_checks(ctx)

    st: AttitudeStates = ctx.attitude
    t0 = float(ctx.imu.t0)
    for ax, a, b in st.empty:
        ctx.violations.append(V.Violation(
            "imu", a + t0, b + t0, TEST_WINDOW,
            f"no {ax} within the prior makes this accelerometer window's mean (its budget, "
            "the aiding's kinematics) agree with the gyro-carried change of the angle "
            "inside the window: the accelerometer or gyro budget, the aiding bounds or the "
            "vehicle's max tilt fail there; the window is not used",
        ))
    for bad in st.chain_bad.values():
        for a, b in _spans(st.te, bad):
            ctx.violations.append(V.Violation(
                "imu", a + t0, b + t0, TEST_CHAIN,
                "the roll/pitch nodes there cannot be joined by the gyro increments within "
                "their bounds: the gyro budget, the accelerometer windows or the prior "
                "fail; those nodes keep their own intervals",
            ))
    r, p = st.roll["full"], st.pitch["full"]
    gw = st.windows
    ctx.aiding.budget["attitude_states"] = [
        Term("roll median half-width", float(np.median(_hw_deg(r.pieces))), "deg", "computed",
             f"{gw['roll'].n} accel_y windows (vector matching), gyro_x/gyro_z between; "
             f"prior {float(np.median(_hw_deg(st.prior_roll))):.3g} deg"),
        Term("pitch median half-width", float(np.median(_hw_deg(p.pieces))), "deg",
             "computed", f"{gw['pitch'].n} accel_x windows, gyro_y/gyro_z between; prior "
             f"{float(np.median(_hw_deg(st.prior_pitch))):.3g} deg"),
    ]
    ctx.notes.append(
        "attitude states (docs/dynamic-method.md section 3b): roll "
        f"{float(np.median(_hw_deg(r.pieces))):.3g} deg, pitch "
        f"{float(np.median(_hw_deg(p.pieces))):.3g} deg median half-width (prior "
        f"{float(np.median(_hw_deg(st.prior_roll))):.3g} / "
        f"{float(np.median(_hw_deg(st.prior_pitch))):.3g} deg); each channel's margins "
        "read the variant built without its own samples (dynamic.json attitude.variants)"
    )
    ctx.assumptions.append(
        "attitude states: accel_x's and accel_y's windows bound roll and pitch with their "
        "stationary bands (their budgets as stated) and the gyros carry the angles between "
        "(their budgets): the margins of accel_z, gyro_x, gyro_y and gyro_z and the "
        "smoother rest on those budgets, and so do the roll and pitch printed (states.csv, "
        "dynamic.json attitude: the full variant); accel_x's own pitch and accel_y's own "
        "roll are never taken from themselves (a constant bias and a constant tilt are "
        "confounded). The data check those budgets through accel_x's and accel_y's "
        "verdicts and change tests (3b.9) only: a bias step smaller than their change "
        "intervals moves the printed roll/pitch unseen"
    )


def attitude_summary(ctx: Any, drive: Any) -> dict[str, Any] | None:
    """The ``attitude`` block of dynamic.json (None when the states did not run)."""
    st: AttitudeStates | None = getattr(ctx, "attitude", None)
    if st is None:
        return None
    out: dict[str, Any] = {
        "method": "vector matching of every accelerometer window against the aiding, the "
        "gyros between the epochs, the prior (max tilt, pitch from GNSS altitude, attitude "
        "stream) intersected; docs/dynamic-method.md section 3b",
        "epochs": int(st.te.size),
        "unit": "deg",
    }
    for ax in ("roll", "pitch"):
        res = st.angle(ax, "full")
        prior = st.prior_roll if ax == "roll" else st.prior_pitch
        hw = _hw_deg(res.pieces)
        hn = _hw_deg(res.nodes)
        out[ax] = {
            "median_halfwidth": float(np.median(hn)),
            "p90_halfwidth": float(np.percentile(hn, 90)),
            "pieces_median_halfwidth": float(np.median(hw)),
            "prior_median_halfwidth": float(np.median(_hw_deg(prior))),
            "windows": st.windows[ax].n,
        }
    out["variants"] = {
        ch: {"roll": v[0], "pitch": v[1],
             "uses": sorted(set(USES[v[0]]) | set(USES[v[1]]))}
        for ch, v in VARIANT_OF.items()
    }
    out["variants"]["others"] = {"roll": "full", "pitch": "full", "uses": list(USES["full"])}
    out["assumes"] = [
        "accel_x and accel_y within their stated budgets (their windows' bands): checked "
        "only by their verdicts and change tests",
        "gyro_x, gyro_y and gyro_z within their stated budgets between the epochs",
        "the prior: the vehicle's max tilt, the pitch from GNSS altitude where used",
    ]
    mount = getattr(ctx, "attitude_mount", None)
    if mount is not None:
        out["mount"] = mount
    out["checks"] = {"empty_windows": len(st.empty),
                     "chain_conflicts": int(sum(int(b.sum()) for b in st.chain_bad.values()))}
    if drive is not None and getattr(drive, "truth", None) is not None:
        enc = truth_enclosure(ctx, drive)
        if enc:
            out["enclosure"] = enc
    return out


def truth_enclosure(ctx: Any, drive: Any) -> dict[str, Any]:
    """Share of the truth's roll and pitch samples inside the full variant's pieces (and
    at the epochs), the first miss (absolute s) and the largest miss (deg)."""
    st: AttitudeStates = ctx.attitude
    tr = drive.truth
    ex = tr.extra
    tt = np.asarray(tr.t, dtype=float) - ctx.imu.t0
    te = st.te
    out: dict[str, Any] = {}
    for ax, key in (("roll", "roll_rad"), ("pitch", "pitch_rad")):
        if key not in ex:
            continue
        x = np.asarray(ex[key], dtype=float)
        k = np.searchsorted(te, tt, side="right") - 1
        ok_t = np.isfinite(x) & (k >= 0) & (k < te.size - 1)
        res = st.angle(ax, "full")
        kk = np.clip(k, 0, te.size - 2)
        lo, hi = res.pieces.lo[kk], res.pieces.hi[kk]
        inside = (lo <= x) & (x <= hi)
        miss = np.maximum(np.maximum(lo - x, x - hi), 0.0)
        if not ok_t.any():
            continue
        row: dict[str, Any] = {"share": float(np.mean(inside[ok_t])), "samples": int(ok_t.sum())}
        bad = np.flatnonzero(ok_t & ~inside)
        if bad.size:
            row["first_miss_t_s"] = float(tt[bad[0]] + ctx.imu.t0)
            row["max_miss"] = float(np.max(miss[ok_t]) / DEG)
        err = np.abs(x - 0.5 * (lo + hi))[ok_t] / DEG
        row["truth_error_median"] = float(np.median(err))
        row["halfwidth_over_error_median"] = float(
            np.median(_hw_deg(res.pieces)[kk][ok_t]) / max(float(np.median(err)), 1e-12))
        out[ax] = row
    if out:
        out["unit"] = "deg"
    return out


def check_finite(x: float) -> float | None:
    return x if math.isfinite(x) else None
