"""Mode ``full``: the error budget, the window margins and the whole-trip smoother
(docs/dynamic-method.md). :func:`run_full` is called by
:func:`imubounds.dynamic.estimator.dynamic_margins`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imubounds.constants import EARTH_RATE, G_HI, G_LO, R_EARTH, ROUND_REL
from imubounds.dynamic.estimator import pitch_gnss as PG
from imubounds.dynamic.estimator import smoother as SM
from imubounds.dynamic.estimator import violations as V
from imubounds.dynamic.estimator.budget import (
    CHANNELS,
    TERM_UNITS,
    UNITS,
    AlphaPlan,
    ChannelNoise,
    Term,
    Wander,
    drift_rule,
    k_two_sided,
    kind_of,
    link_wander,
    resolve_noise,
    sample_bound,
    wander_of,
)
from imubounds.dynamic.estimator.inputs import (
    Aiding,
    ImuSeries,
    Vehicle,
    check_overlap,
    vehicle_from,
)
from imubounds.dynamic.estimator.options import FullOptions, check_options
from imubounds.dynamic.estimator.vehicle_bounds import refine_vehicle
from imubounds.dynamic.estimator.window_plan import epochs_near, plan_on_subset
from imubounds.dynamic.estimator.windows import (
    ChannelMargins,
    ChannelPlan,
    MarginBuilder,
    TiltSignals,
    build_tilt,
    plan_channel,
    tau_grid,
)
from imubounds.dynamic.sensors import build_aiding
from imubounds.dynamic.sensors import clocks as CK
from imubounds.dynamic.sensors.heading import HeadingInput
from imubounds.errors import InputError
from imubounds.units import DEG


@dataclass
class Context:
    """Everything mode full computes before the margins and the smoother."""

    drive: Any
    opts: FullOptions
    vehicle: Vehicle
    noise: dict[str, ChannelNoise]
    imu: ImuSeries
    heading: HeadingInput | None
    aiding: Aiding
    alpha: AlphaPlan
    E0: dict[str, float]
    D_KR: dict[str, float]
    k_ps: float
    #: the bound of each channel's in-run bias wander (budget.Wander)
    wander: dict[str, Wander]
    tilt: TiltSignals
    te: np.ndarray
    assumptions: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    plans: dict[str, ChannelPlan] = field(default_factory=dict)
    level_index: dict[tuple[str, int], int] = field(default_factory=dict)
    level_index_changes: dict[tuple[str, int], int] = field(default_factory=dict)
    #: failed checks of assumptions found while building the inputs (violations.py)
    violations: list[Any] = field(default_factory=list)
    #: clock offsets of the aiding streams (sensors/_timing.py)
    timing: dict[str, Any] = field(default_factory=dict)


def _epochs(drive: Any, heading: HeadingInput | None, t0: float, opts: FullOptions) -> Any:
    g = drive.gnss
    parts = []
    n_fix = n_vel = 0
    if g is not None and opts.use_gnss:
        ok = g.usable()
        parts.append(g.t[ok] - t0)
        n_fix = int(ok.sum())
        v = g.velocity_ne()
        if v is not None and opts.use_gnss_velocity:
            n_vel = int(np.sum(ok & np.isfinite(v[0]) & np.isfinite(v[1])))
    n_head = 0
    if heading is not None:
        parts.append(np.asarray(heading.t, float) - t0)
        n_head = int(heading.t.size)
    if drive.velocity is not None and opts.use_velocity:
        parts.append(np.asarray(drive.velocity.t, float) - t0)
    te = np.unique(np.concatenate(parts)) if parts else np.zeros(0)
    return te, n_fix, n_vel, n_head


def build_context(
    drive: Any, noise: Any, opts: FullOptions | Mapping[str, Any]
) -> Context:
    """Budget, inputs and window plans of mode full (see the module docstring); ``opts``
    a :class:`FullOptions`, or keywords checked here (:func:`check_options`)."""
    if drive.imu is None:
        raise InputError(f"{drive.source}: no IMU stream")
    o = check_options(opts, drive.settings)
    vehicle, vnotes = vehicle_from(drive.settings, o)
    base = Path(drive.source) if Path(str(drive.source)).is_dir() else None
    noise_terms, assumed = resolve_noise(drive.settings, noise, o, base)
    imu = ImuSeries.from_drive(drive, o.imu_stamp, vehicle)
    drive, heading, timing = CK.clock_offsets(drive, o, noise_terms)
    te, n_fix, n_vel, n_head = _epochs(drive, heading, imu.t0, o)
    te = te[(te >= imu.bnd[0]) & (te <= imu.bnd[-1])]
    if te.size < 2:
        raise InputError(
            f"{drive.source}: fewer than two aiding epochs inside the IMU's time span "
            f"({imu.bnd[0] + imu.t0:.3f}..{imu.bnd[-1] + imu.t0:.3f} s); check the clocks"
        )
    any_k = any(noise_terms[c].K > 0 or noise_terms[c].R > 0 for c in CHANNELS)
    # a stated drift bound: + each sample's flicker deviation from its window mean
    any_d = any(drift_rule(noise_terms[c]) != "model" for c in CHANNELS)
    # the pitch from GNSS altitude (pitch_gnss.py): each fix's altitude joins the GNSS
    # position family, the gyro_y noise over its chords the IMU intervals, and (unless a
    # stated drift bound gives it) gyro_y's per-sample flicker the IMU samples
    use_pitch = PG.applicable(drive, vehicle, o, imu.available, noise_terms)
    n_pitch = PG.interval_events(n_fix, imu.duration) if use_pitch else 0
    n_alt = n_fix if use_pitch else 0
    n_fl = imu.n * sum(drift_rule(noise_terms[c]) != "stated"
                       for c in ("gyro_x", "gyro_y", "gyro_z")) if use_pitch else 0
    alpha = AlphaPlan(
        float(o.alpha),
        {
            "imu_samples": imu.n * 6 * (2 if any_d else 1) + n_fl,
            "imu_windows": 1,
            "imu_changes": 1,
            # + the gyro z noise over the heading clock bound at each heading epoch
            "imu_intervals": 7 * (te.size - 1) + CK.clock_bound_events(heading, timing)
            + n_pitch,
            "imu_turn_on": 6,
            "imu_drift": 6 if any_k else 0,
            "gnss_position": n_fix + n_alt,
            "gnss_velocity": n_vel,
            # + the compass error model's coefficients (course_check.estimate_heading_model)
            "heading": n_head + CK.model_events(heading),
        },
        descriptions={
            "imu_samples": "each sample's error (per-sample bounds: magnitudes, bias over "
            "the trip)" + (" and, under a stated drift bound, each sample's flicker "
                           "deviation from its window mean" if any_d else ""),
            "imu_windows": "the noise of each window mean (split equally over the tau levels)",
            "imu_changes": "the noise change between each pair of adjacent windows (the "
            "change test; split equally over the tau levels)",
            "imu_intervals": "the noise integrated over each link of the smoother (flat and "
            "ramp weights, per channel) and, under the default heading clock bound, the gyro "
            "z noise over that bound at each heading epoch"
            + (" and, for the pitch from GNSS altitude, the gyro noise over each altitude "
               "chord's halves (reflection principle) and its rate-error magnitudes"
               if n_pitch else ""),
            "imu_turn_on": "the turn-on bias of each channel (prior of the bias state)",
            "imu_drift": "the rate random walk over the trip (reflection principle)",
            "gnss_position": "each fix's position error (Rayleigh radius)"
            + (" and its altitude error (pitch from GNSS altitude)" if n_alt else ""),
            "gnss_velocity": "each fix's velocity error (Rayleigh radius)",
            "heading": "each heading epoch's noise (and the coefficients of the compass "
            "error model estimated against the GNSS course)",
        },
    )
    from scipy.special import ndtri

    # the estimated clock offsets: finalized with the k of the family of the stream they
    # move (Bonferroni over its count + their intervals; the body velocity's in the IMU
    # intervals), the applied ones taken off the stamps before the aiding, the
    # windows and the smoother use them, and counted in that family
    def k_of(stream: str, n: int) -> float:
        fam = CK.ALPHA_FAMILY.get(stream)
        if fam is None:
            return float(-ndtri(alpha.share() / 2 / n))
        return k_two_sided(alpha.share(), alpha.counts.get(fam, 0) + n)

    n_model = CK.model_events(heading)
    drive, moved = CK.apply_offsets(drive, timing, k_of)
    joined: dict[str, int] = {}
    for name, est in timing.items():
        fam = CK.ALPHA_FAMILY.get(name)
        if fam is not None and est.applied and est.method != "drive.yaml":
            joined[fam] = joined.get(fam, 0) + 1 + len(est.parts)
            alpha.counts[fam] = alpha.counts.get(fam, 0) + 1 + len(est.parts)
    if moved:
        # the heading input again: its calibration and check against the GNSS course
        # see the shifted streams
        heading = CK.heading_stated(drive, o, timing)
        if heading is not None and (rel := CK.relative_offset(heading)) is not None:
            timing["heading_vs_gnss"] = rel
        te = _epochs(drive, heading, imu.t0, o)[0]
        te = te[(te >= imu.bnd[0]) & (te <= imu.bnd[-1])]
        alpha.counts["imu_intervals"] = (7 * (te.size - 1) + CK.clock_bound_events(heading, timing)
                                         + joined.get("imu_intervals", 0) + n_pitch)
        alpha.counts["heading"] += CK.model_events(heading) - n_model
    k_ps = alpha.k("imu_samples")
    T = imu.duration

    k_K = float(-ndtri(alpha.share() / (4 * 6))) if any_k else 0.0
    D_KR: dict[str, float] = {}
    E0: dict[str, float] = {}
    wander: dict[str, Wander] = {}
    dt = imu.dt
    for ch in CHANNELS:
        cn = noise_terms[ch]
        wander[ch] = wd = wander_of(cn, k_K, T, k_ps, dt)
        D_KR[ch] = wd.kr
        E0[ch] = sample_bound(cn, wd, k_ps, dt)
    # misalignment in the per-sample bound: other axes' largest measured magnitude
    for ch in CHANNELS:
        cn = noise_terms[ch]
        kind = kind_of(ch)
        extra = 0.0
        for other in CHANNELS:
            if other != ch and kind_of(other) == kind and imu.available[other]:
                extra += float(np.max(np.abs(imu.sig[other].y))) + E0[other]
        E0[ch] += cn.misalignment_rad * extra
    aiding = build_aiding(drive, imu.t0, vehicle, alpha, o, heading)
    imu, aiding, vnotes_data = refine_vehicle(drive, vehicle, imu, aiding, alpha, o, heading)
    # after refine_vehicle, which may rebuild the aiding
    CK.budget_timing(aiding, vehicle, timing)
    if aiding.has_gnss:
        assumed.append(
            "GNSS multipath: no step of a run of fixes (a bias shared by consecutive fixes) "
            "beyond the Gaussian error model; a step is tested (residual_checks: 'gnss "
            "position step' with the receiver's velocity, the runs of residuals otherwise) "
            "and one smaller than their steps_unnoticed (m) goes unnoticed and is NOT in "
            "the GNSS radius"
        )
    if CK.heading_clock_default(aiding, timing):
        assumed.append(CK.heading_clock_assumption(timing))
    check_overlap(imu, aiding, drive.source)
    ctx = Context(
        drive=drive,
        opts=o,
        vehicle=vehicle,
        noise=noise_terms,
        imu=imu,
        heading=heading,
        aiding=aiding,
        alpha=alpha,
        E0=E0,
        D_KR=D_KR,
        k_ps=k_ps,
        wander=wander,
        tilt=None,  # type: ignore[arg-type]
        te=te,
        assumptions=assumed + vnotes,
        notes=list(aiding.notes) + vnotes_data,
        timing=timing,
    )
    cc = heading.course_check if heading is not None else None
    if heading is not None and cc is not None and cc.get("passed") is False:
        span = (float(te[0] + imu.t0), float(te[-1] + imu.t0))
        ctx.violations.append(
            V.Violation(
                "heading",
                *span,
                V.TEST_HEADING_COURSE,
                "; ".join(n for n in heading.notes if n.startswith("check failed")) or str(cc),
            )
        )
    clock_note = CK.untested_clock(aiding, timing)
    if clock_note:
        ctx.violations.append(V.Violation("heading", float(te[0] + imu.t0),
                                          float(te[-1] + imu.t0), V.TEST_HEADING_CLOCK,
                                          clock_note))
    if use_pitch:
        _pitch_from_gnss(ctx)
    ctx.tilt = build_tilt(ctx)
    _plan_windows(ctx)
    return ctx


def _pitch_from_gnss(ctx: Context) -> None:
    """Pitch intervals from GNSS altitude (pitch_gnss.py), used where they narrow the
    max tilt; a chord with no feasible pitch is a violation."""
    pb = PG.pitch_boxes(ctx)
    if pb is None:
        return
    t0 = float(ctx.imu.t0)
    for a, b in pb.infeasible:
        ctx.violations.append(V.Violation(
            "gnss", a + t0, b + t0, PG.TEST_PITCH,
            "no pitch within the max tilt makes these GNSS altitude changes reachable with "
            "the gyro_y propagation and the vehicle's off-axis velocity bound: the altitude "
            "error (gnss.vertical_sigma_ratio), the gyro budget or the vehicle bounds fail; "
            "those spans keep +-max tilt",
        ))
    ag = ctx.aiding
    ag.budget["pitch_from_gnss"] = pb.budget
    st = ctx.drive.settings
    dflt = "gnss.vertical_sigma_ratio" in getattr(st, "defaulted", [])
    ctx.assumptions.append(
        "GNSS altitude (pitch from GNSS altitude): each fix's vertical error Gaussian with "
        f"1-sigma = {st.gnss.vertical_sigma_ratio:g} x its horizontal 1-sigma per axis ("
        + ("default: state gnss.vertical_sigma_ratio in drive.yaml" if dflt
           else "drive.yaml gnss.vertical_sigma_ratio")
        + "); no altitude step beyond that model (multipath)"
    )
    m = ctx.vehicle.max_tilt
    if not pb.narrows(m):
        ctx.notes.append(
            "pitch from GNSS altitude: nothing narrower than the max tilt "
            f"({m / DEG:g} deg; median half-width {pb.median_halfwidth / DEG:.3g} deg)"
        )
        return
    ag.pitch = pb
    ctx.notes.append(
        f"pitch from GNSS altitude, the gyros and the non-holonomic bounds: median "
        f"half-width {pb.median_halfwidth / DEG:.3g} deg (max tilt {m / DEG:g} deg); roll "
        "stays +-max tilt (docs/dynamic-method.md section 3a)"
    )


def _plan_windows(ctx: Context) -> None:
    mb = MarginBuilder(ctx)
    ag = ctx.aiding
    imu = ctx.imu
    cap = int(ctx.opts.max_windows)
    grid = tau_grid(imu.dt, imu.duration)
    bv = mb.body_velocity()
    plans: dict[str, ChannelPlan] = {}
    for ch in CHANNELS:
        if not imu.available[ch]:
            plans[ch] = ChannelPlan(ch, "none", np.zeros(0), False, reason="no samples")
            continue
        if ch in ("accel_x", "accel_y"):
            sel = epochs_near(bv["t"], ag.head_t) if bv is not None else None
            if bv is not None and ch == "accel_y" and sel is not None:
                src = f"{bv['src']} at the heading epochs"
                plans[ch] = plan_on_subset(ch, src, bv["t"], sel, imu.bnd, imu.dt, cap)
            elif bv is not None:
                plans[ch] = plan_channel(ch, bv["src"], bv["t"], False, imu.bnd, imu.dt, cap)
            elif ag.has_gnss and ag.gnss_t.size >= 3:
                plans[ch] = plan_channel(
                    ch, "GNSS positions (trapezoid kernel)", ag.gnss_t, True, imu.bnd, imu.dt, cap
                )
            else:
                plans[ch] = ChannelPlan(
                    ch, "none", np.zeros(0), False, reason="no velocity or position aiding"
                )
        elif ch == "gyro_z":
            if ag.has_heading:
                plans[ch] = plan_channel(
                    ch, f"heading ({ag.head_source})", ag.head_t, False, imu.bnd, imu.dt, cap
                )
                if not ag.head_independent_of_imu:
                    ctx.notes.append(
                        "the heading source is an AHRS output using this gyro: the gyro_z "
                        "margins are not independent of the channel they judge"
                    )
            else:
                plans[ch] = ChannelPlan(ch, "none", np.zeros(0), False, reason="no heading")
        else:
            if ag.has_attitude:
                assert ag.att_t is not None
                plans[ch] = plan_channel(
                    ch, f"attitude ({ag.att_source})", ag.att_t, False, imu.bnd, imu.dt, cap
                )
            else:
                plans[ch] = ChannelPlan(
                    ch,
                    "none",
                    np.zeros(0),
                    False,
                    reason="no attitude stream: the trip is analysed in the plane "
                    "(accel_z, gyro_x, gyro_y need roll and pitch)",
                )
    level_counts = [0] * len(grid)
    for ch, p in plans.items():
        for li, lp in enumerate(p.levels):
            gi = int(np.argmin([abs(math.log(lp.tau_s / g)) for g in grid]))
            ctx.level_index[(ch, li)] = gi
            # accelerometer windows carry two bounded events: the band's noise and the
            # gyro's deviation bound of the transport term
            level_counts[gi] += lp.n * (2 if ch in ("accel_x", "accel_y") else 1)
    ctx.alpha.counts["imu_windows"] = max(1, sum(level_counts))
    ctx.alpha.level_counts["imu_windows"] = level_counts
    # the change test between adjacent windows: one bounded event per pair
    change_counts = [0] * len(grid)
    for ch, p in plans.items():
        for li, lp in enumerate(p.levels):
            if lp.kind == "aided" and lp.n_pairs:
                gi = ctx.level_index[(ch, li)]
                ctx.level_index_changes[(ch, li)] = gi
                change_counts[gi] += lp.n_pairs
    ctx.alpha.counts["imu_changes"] = max(1, sum(change_counts))
    ctx.alpha.level_counts["imu_changes"] = change_counts
    ctx.plans = plans


# ----------------------------------------------------------------------- smoother


#: IMU segments per call of the preintegration (bounds its per-sample arrays)
PREINTEGRATE_CHUNK = 1 << 18


def _preintegrate(
    ctx: Context, br_mid: float, YR: np.ndarray, FH: np.ndarray, QH: np.ndarray, AA: np.ndarray
) -> None:
    """:func:`~.smoother.preintegrate` over the links in runs of about
    :data:`PREINTEGRATE_CHUNK` IMU segments: each run gets the interval samples and
    roll/pitch of its own segments only (every link reads only the segments it
    overlaps, so the results are those of one call over the whole trip)."""
    imu, veh, ag = ctx.imu, ctx.vehicle, ctx.aiding
    te = np.ascontiguousarray(ctx.te)
    bnd, nseg, sig = imu.bnd, imu.n, imu.sig

    def pt(ch: str, sl: slice, lo_unknown: float, hi_unknown: float) -> np.ndarray:
        s = sig[ch]
        out = np.stack([s.y[sl], s.y[sl]], -1)
        unk = s.unknown[sl]
        out[unk, 0] = lo_unknown
        out[unk, 1] = hi_unknown
        return np.ascontiguousarray(out)

    ax = veh.max_accel + G_HI * math.sin(veh.max_tilt)
    fz_lo, fz_hi = G_LO * math.cos(veh.max_tilt) - veh.max_accel, G_HI + veh.max_accel
    # the segment of each epoch: first k with bnd[k + 1] > t (where the kernel starts)
    first = np.clip(np.searchsorted(bnd, te, side="right") - 1, 0, nseg - 1)
    j0 = 0
    while j0 < te.size - 1:
        j1 = int(np.searchsorted(first, first[j0] + PREINTEGRATE_CHUNK, side="right")) - 1
        j1 = min(max(j1, j0 + 1), te.size - 1)
        ka = int(first[j0])
        # the links' last segment: the last k with bnd[k] < te[j1]
        kb = max(min(int(np.searchsorted(bnd, te[j1], side="left")), nseg), ka + 1)
        sl = slice(ka, kb)
        rl, rh, pl, ph = ag.tilt_range(bnd[ka:kb], bnd[ka + 1 : kb + 1], veh)
        SM.preintegrate(
            te[j0 : j1 + 1],
            bnd[ka : kb + 1],
            pt("accel_x", sl, -ax, ax),
            pt("accel_y", sl, -ax, ax),
            pt("accel_z", sl, fz_lo, fz_hi),
            pt("gyro_z", sl, -veh.max_rate, veh.max_rate),
            np.ascontiguousarray(rl),
            np.ascontiguousarray(rh),
            np.ascontiguousarray(pl),
            np.ascontiguousarray(ph),
            br_mid,
            YR[j0:j1],
            FH[j0:j1],
            QH[j0:j1],
            AA[j0:j1],
        )
        j0 = j1


def _link_errors(ctx: Context, beta0: np.ndarray) -> dict[str, np.ndarray]:
    """Preintegrated increments of every link with all errors but the bias states."""
    imu, veh, ag, tilt = ctx.imu, ctx.vehicle, ctx.aiding, ctx.tilt
    te = ctx.te
    n = te.size
    sig = imu.sig
    YR = np.empty((n - 1, 2))
    FH = np.empty((n - 1, 2, 2))
    QH = np.empty((n - 1, 2, 2))
    AA = np.empty((n - 1, 2))
    br_mid = 0.5 * (beta0[2, 0] + beta0[2, 1])
    _preintegrate(ctx, float(br_mid), YR, FH, QH, AA)
    a, b = te[:-1], te[1:]
    D = b - a
    cnt = imu.count(a, b)
    k_int = ctx.alpha.k("imu_intervals")
    scale = max(1.0, imu.max_len / imu.dt) * k_int

    def wander(ch: str, ramp: bool) -> np.ndarray:
        """The noise and the bias wander over each link (budget.link_wander)."""
        return link_wander(ctx.noise[ch], ctx.wander[ch], cnt, D, imu.dt, scale, ramp)

    def absint(ch: str) -> np.ndarray:
        cn = ctx.noise[ch]
        return (sig[ch].abs_integral(a, b) + ctx.E0[ch] * D) / (1.0 - cn.scale)

    edge = imu.edge(a) + imu.edge(b)

    def det(ch: str) -> np.ndarray:
        cn = ctx.noise[ch]
        out = cn.scale * absint(ch)
        kind = kind_of(ch)
        for other in CHANNELS:
            if other != ch and kind_of(other) == kind:
                out = out + cn.misalignment_rad * absint(other)
        return out + edge * imu.rate_bound[ch] * imu.max_len

    # tilt maxima over each link
    sp = tilt.hull("abs_sinp", a, b).hi
    sr = tilt.hull("abs_sinr", a, b).hi
    spr = sp * sr
    cpr = tilt.hull("cosp_over_cosr", a, b)
    # heading increment: psi' - r = r (cos r / cos p - 1) + q sin r / cos p
    r_abs = absint("gyro_z")
    q_abs = absint("gyro_y")
    inv_c = 1.0 / np.maximum(cpr.lo, 1e-9)
    c_dev = np.maximum(np.abs(inv_c - 1.0), np.abs(1.0 / np.maximum(cpr.hi, 1e-9) - 1.0))
    sec_p = 1.0 + tilt.hull("sec_p_minus_1", a, b).hi
    e_phi = (
        wander("gyro_z", False)
        + det("gyro_z")
        + r_abs * c_dev
        + q_abs * sr * sec_p
        + (EARTH_RATE + veh.max_speed / R_EARTH) * D
    )
    # heading-frame specific force errors (bias of x, y excluded: states)
    gx, gy, gz = wander("accel_x", False), wander("accel_y", False), wander("accel_z", False)
    rx, ry, rz = wander("accel_x", True), wander("accel_y", True), wander("accel_z", True)
    dx, dy, dz = det("accel_x"), det("accel_y"), det("accel_z")
    k_to = ctx.alpha.k("imu_turn_on")
    to_z = ctx.noise["accel_z"].turn_on_bound(k_to)
    bx = np.max(np.abs(beta0[0]))
    by = np.max(np.abs(beta0[1]))
    e_fwd = gx + dx + spr * (gy + dy + by * D) + sp * (gz + dz + to_z * D)
    e_left = gy + dy + sr * (gz + dz + to_z * D)
    q_fwd = rx + D * dx + spr * (ry + D * (dy + by * D)) + sp * (rz + D * (dz + to_z * D))
    q_left = ry + D * dy + sr * (rz + D * (dz + to_z * D))
    # rotation within the link: |phi| and |phi - phi_nominal|
    phi_max = AA[:, 1] + ctx.E0["gyro_z"] * D
    phi_err = ctx.E0["gyro_z"] * D + ctx.noise["gyro_z"].scale * r_abs + abs(br_mid) * D
    a_abs = AA[:, 0]
    c_min = math.cos(veh.max_tilt + ag.att_bound)
    bias_rot = D * (np.minimum(phi_max, 2.0) + (1 - c_min)) * (bx + by)
    cor = (2 * EARTH_RATE * veh.max_speed + veh.max_speed**2 / R_EARTH) * D
    rot = phi_err * a_abs
    ef0 = e_fwd + np.minimum(phi_max, 1.0) * e_left + rot + bias_rot + cor
    ef1 = e_left + np.minimum(phi_max, 1.0) * e_fwd + rot + bias_rot + cor
    eq0 = q_fwd + np.minimum(phi_max, 1.0) * q_left + D * (rot + bias_rot + cor)
    eq1 = q_left + np.minimum(phi_max, 1.0) * q_fwd + D * (rot + bias_rot + cor)

    def widen(x: np.ndarray, e: np.ndarray) -> None:
        e = np.nextafter(e * (1 + ROUND_REL), np.inf)
        x[:, 0] = np.nextafter(x[:, 0] - e, -np.inf)
        x[:, 1] = np.nextafter(x[:, 1] + e, np.inf)

    widen(YR, e_phi)
    widen(FH[:, 0], ef0)
    widen(FH[:, 1], ef1)
    widen(QH[:, 0], eq0)
    widen(QH[:, 1], eq1)
    return {"YR": YR, "FH": FH, "QH": QH, "e_phi": e_phi, "e_f": np.stack([ef0, ef1], -1)}


def _smoother_inputs(ctx: Context) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Priors, measurement boxes and their presence at the smoother's epochs."""
    from imubounds.interval import IntervalArray as IA
    from imubounds.interval import cos, sin

    te, ag, veh = ctx.te, ctx.aiding, ctx.vehicle
    n = te.size
    prior = np.empty((n, 7, 2))
    prior[..., 0] = -np.inf
    prior[..., 1] = np.inf
    vm = veh.max_speed
    for iv_ in (SM.VE, SM.VN, SM.UH):
        prior[:, iv_] = (-vm, vm)
    vl = veh.lateral_speed_bound_mps if veh.lateral_speed_bound_mps is not None else vm
    prior[:, SM.VH] = (-vl, vl)
    if not ag.has_gnss:
        prior[0, SM.E] = (0.0, 0.0)
        prior[0, SM.N] = (0.0, 0.0)
    meas = np.empty_like(prior)
    meas[..., 0] = -np.inf
    meas[..., 1] = np.inf
    has = np.zeros((n, 4), dtype=bool)
    if ag.has_gnss:
        idx = np.searchsorted(te, ag.gnss_t)
        ok = (idx < n) & (te[np.minimum(idx, n - 1)] == ag.gnss_t)
        i = idx[ok]
        h = ag.gnss_h[ok]  # the lever arm is in the aiding radius
        meas[i, SM.E] = np.stack([ag.gnss_e[ok] - h, ag.gnss_e[ok] + h], -1)
        meas[i, SM.N] = np.stack([ag.gnss_n[ok] - h, ag.gnss_n[ok] + h], -1)
        has[i, SM.G_POS] = True
        if ag.has_gvel:
            okv = ok & ag.gvel_ok
            iv = idx[okv]
            hv = ag.gvel_hi[okv]
            meas[iv, SM.VE] = np.stack([ag.gvel_e[okv] - hv, ag.gvel_e[okv] + hv], -1)
            meas[iv, SM.VN] = np.stack([ag.gvel_n[okv] - hv, ag.gvel_n[okv] + hv], -1)
            has[iv, SM.G_VEL] = True
    if ag.has_heading:
        idx = np.searchsorted(te, ag.head_t)
        ok = (idx < n) & (te[np.minimum(idx, n - 1)] == ag.head_t)
        i = idx[ok]
        meas[i, SM.PSI] = np.stack(
            [ag.head_c[ok] - ag.head_h[ok], ag.head_c[ok] + ag.head_h[ok]], -1
        )
        has[i, SM.G_HEAD] = True
    if ag.has_bvel:
        idx = np.searchsorted(te, ag.bvel_t)
        ok = (idx < n) & (te[np.minimum(idx, n - 1)] == ag.bvel_t)
        i = idx[ok]
        h = ag.bvel_h[ok]
        u = IA(ag.bvel_u[ok] - h, ag.bvel_u[ok] + h)
        v = (
            IA(ag.bvel_v[ok] - h, ag.bvel_v[ok] + h)
            if ag.bvel_v is not None and np.all(np.isfinite(ag.bvel_v))
            else IA(np.full(i.size, -vl), np.full(i.size, vl))
        )
        wb = veh.vertical_bound
        w = (
            IA(ag.bvel_w[ok] - h, ag.bvel_w[ok] + h)
            if ag.bvel_w is not None and np.all(np.isfinite(ag.bvel_w))
            else IA(np.full(i.size, -wb), np.full(i.size, wb))
        )
        rl, rh, pl, ph = ag.tilt(te[i], veh)
        roll, pitch = IA(rl, rh), IA(pl, ph)
        sr, cr, sp, cp = sin(roll), cos(roll), sin(pitch), cos(pitch)
        uh = cp * u - sr * sp * v - cr * sp * w
        vh = cr * v - sr * w
        meas[i, SM.UH] = np.stack([uh.lo, uh.hi], -1)
        meas[i, SM.VH] = np.stack([vh.lo, vh.hi], -1)
        has[i, SM.G_BODY] = True
    return prior, meas, has


def _beta_from_windows(ctx: Context, margins: dict[str, ChannelMargins]) -> tuple[Any, list[str]]:
    """Bias intervals (accel_x, accel_y, gyro_z): the turn-on prior intersected with what
    every decidable window says, ``beta in [E_W] - [band without turn-on]``."""
    k_to = ctx.alpha.k("imu_turn_on")
    out = np.empty((3, 2))
    notes = []
    for r, ch in enumerate(("accel_x", "accel_y", "gyro_z")):
        b = ctx.noise[ch].turn_on_bound(k_to)
        lo, hi = -b, b
        m = margins.get(ch)
        cand_lo, cand_hi = [], []
        if m is not None:
            for lv in m.levels:
                if lv.kind != "aided":
                    continue
                cand_lo.append(lv.e_lo - lv.band_nto)
                cand_hi.append(lv.e_hi + lv.band_nto)
        if cand_lo:
            L = np.concatenate(cand_lo)
            H = np.concatenate(cand_hi)
            wl, wh = float(np.max(L)), float(np.min(H))
            if wl <= wh:
                lo, hi = max(lo, wl), min(hi, wh)
                if lo > hi:
                    notes.append(
                        f"{ch}: the windows put the bias outside its turn-on prior "
                        f"(+-{b:.3g} {UNITS[ch]}): prior kept"
                    )
                    lo, hi = -b, b
            else:
                notes.append(
                    f"{ch}: the windows disagree about one constant bias (a fault or a "
                    "too-tight budget): the bias is not contracted by the windows"
                )
        out[r] = (np.nextafter(lo, -np.inf), np.nextafter(hi, np.inf))
    return out, notes


# ------------------------------------------------------------------------ result


@dataclass
class FullRun:
    ctx: Context
    margins: dict[str, ChannelMargins]
    smoother: SM.SmootherResult | None
    links: dict[str, np.ndarray] | None
    notes: list[str]
    #: (stream, test, detail, evidence span or None) of every failed check of the run
    check_failures: list[tuple[str, str, str, tuple[float, float] | None]] = field(
        default_factory=list
    )


def _smooth(ctx: Context, links: dict[str, np.ndarray], beta0: np.ndarray) -> Any:
    prior, meas, has = _smoother_inputs(ctx)
    vl = ctx.vehicle.lateral_speed_bound_mps
    return SM.smooth(
        ctx.te,
        prior,
        meas,
        has,
        links["YR"],
        links["FH"],
        links["QH"],
        beta0,
        math.inf if vl is None else float(vl),
        tol=float(ctx.opts.tol),
        max_sweeps=int(ctx.opts.max_sweeps),
        t_offset=ctx.imu.t0,
    )


def run_full(
    drive: Any,
    noise: Any = None,
    options: FullOptions | Mapping[str, Any] | None = None,
    *,
    progress: Callable[[str, int, int], None] | None = None,
) -> FullRun:
    """Mode full on a drive (see :func:`imubounds.dynamic.estimator.dynamic_margins`);
    ``progress(stage, done, total)`` hears of each channel's windows and the smoother."""
    ctx = build_context(drive, noise, {} if options is None else options)
    mb = MarginBuilder(ctx)
    order = ["gyro_z"] + [ch for ch in ctx.plans if ch != "gyro_z"]
    tell = progress if progress is not None else (lambda stage, done, total: None)
    margins: dict[str, ChannelMargins] = {}
    notes: list[str] = []
    fails: list[tuple[str, str, str, tuple[float, float] | None]] = []
    for i, ch in enumerate(order):
        tell(f"windows of {ch}", i, len(order))
        margins[ch] = mb.evaluate(ctx.plans[ch])
        if ch == "gyro_z" and margins[ch].raw_verdict == "exceeds":
            mb.fine_r = False
            notes.append(
                "gyro_z exceeds its stationary band: the accelerometers' transport terms use "
                "the gyro's per-sample error bound, not its window-centred bound"
            )
    margins = {ch: margins[ch] for ch in ctx.plans}
    bv = mb.body_velocity()
    if bv is not None and bv["dropped"]:
        msg = (
            f"{bv['dropped']} velocity epoch(s) contradict the vehicle bounds and are not "
            "used by the windows"
        )
        notes.append(msg)
        fails.append(("velocity", V.TEST_VEHICLE, msg, None))
    beta0, bnotes = _beta_from_windows(ctx, margins)
    notes += bnotes
    for bn in bnotes:
        fails.append((bn.split(":", 1)[0], V.TEST_BIAS_WINDOWS, bn, None))
    links = _link_errors(ctx, beta0)
    CK.heading_clock_allowance(ctx, beta0)
    tell("smoother", 0, 1)
    res = _smooth(ctx, links, beta0)
    if res.beta_note:
        notes.append(res.beta_note)
    for t_s, miss in ctx.aiding.gnss_rejected:
        res.dropped.insert(
            0,
            SM.Dropped(
                t_s,
                "gnss position",
                miss,
                "m",
                "GNSS-only check: farther than 4 DRMS from every interpolation of its "
                "neighbours (the miss is beyond that threshold)",
            ),
        )
    return FullRun(ctx, margins, res, links, notes, fails)


def noise_budget_rows(ctx: Context, ch: str) -> list[Term]:
    """The budget table of one IMU channel."""
    cn = ctx.noise[ch]
    kind = kind_of(ch)
    tu = TERM_UNITS[kind]
    unit = UNITS[ch]
    src = cn.sources
    k_to = ctx.alpha.k("imu_turn_on")
    rows = [
        Term("white noise density N", cn.N, tu["N"], src["N"], "Gaussian white noise"),
        Term(
            "per-sample white sigma N/sqrt(dt)",
            cn.N / math.sqrt(ctx.imu.dt),
            unit,
            "computed",
            f"at the sample rate {1 / ctx.imu.dt:.4g} Hz",
        ),
        Term(
            "bias instability B",
            cn.B,
            tu["B"],
            src["B"],
            f"flicker over {cn.flicker_tau_range_s[0]:g}..{cn.flicker_tau_range_s[1]:g} s "
            f"(sum of Gauss-Markov processes, marginal sigma {cn.flicker_sigma():.3g} {unit})",
        ),
        Term("quantization Q", cn.Q, tu["Q"], src["Q"], "white in the integral"),
        Term("rate random walk K", cn.K, tu["K"], src["K"], "random walk from the trip start"),
        Term("rate ramp R", cn.R, tu["R"], src["R"], "deterministic drift from the start"),
        Term(
            "turn-on bias" + (" bound" if cn.turn_on_kind == "bound" else " (1 sigma)"),
            cn.turn_on,
            unit,
            src["turn_on"],
            "constant over the trip"
            + ("" if cn.turn_on_kind == "bound" else ", Gaussian across switch-ons"),
        ),
        Term(
            "turn-on bias bound used",
            cn.turn_on_bound(k_to),
            unit,
            "computed" if cn.turn_on_kind == "sigma" else src["turn_on"],
            (f"k = {k_to:.3g} x sigma; " if cn.turn_on_kind == "sigma" else "")
            + "prior of the bias state",
        ),
        Term(
            "bias drift bound",
            cn.drift_bound if cn.drift_bound is not None else float("nan"),
            unit,
            src.get("drift_bound", "not stated"),
            f"mean in-run wander over any window of at least {cn.drift_window_s:g} s "
            "(used instead of the flicker model for windows that long, where smaller)",
        ),
        Term(
            "drift bound k_K K sqrt(T) + R T",
            ctx.D_KR[ch],
            unit,
            "computed",
            f"over T = {ctx.imu.duration:.1f} s",
        ),
        Term(
            "bias wander at a sample under the drift bound D_s + k sigma_dev",
            ctx.wander[ch].point if ctx.wander[ch].rule != "model" else float("nan"),
            unit,
            "computed",
            f"rule {ctx.wander[ch].rule} (model: flicker + K, R; stated: the drift bound "
            "alone, no K given; both: the smaller), docs/dynamic-method.md section 1",
        ),
        Term(
            "scale-factor error",
            cn.scale,
            "fraction",
            src["scale"],
            "bound, times the mean |signal| of a window",
        ),
        Term(
            "misalignment",
            cn.misalignment_rad / DEG,
            "deg",
            src["misalignment_rad"],
            "bound, times the mean |signal| of the other two axes",
        ),
        Term(
            "per-sample error bound",
            ctx.E0[ch],
            unit,
            "computed",
            f"k = {ctx.k_ps:.3g} over every sample of every channel (used in magnitude terms)",
        ),
        Term(
            "sample-model edge error",
            ctx.imu.rate_bound[ch],
            unit + "/s",
            ctx.vehicle.sources.get("max_jerk" if kind == "accel" else "max_ang_accel", ""),
            "a window end cutting a sample: at most (cut length) x (rate bound) x dt",
        ),
    ]
    return rows
