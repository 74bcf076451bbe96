"""Vehicle bounds from the aiding sensors' own intervals (docs/dynamic-method.md, section 1,
"Vehicle bounds from the data").

The windows and the smoother need bounds of the vehicle's speed and tilt over the whole
trip. Where the drive has a sensor that bounds the quantity, the bound comes from that
sensor's intervals (on the same bounded events as the sensor's own intervals, so with
its share of alpha and no new one):

* **tilt** (roll and pitch): the attitude stream, ``max(|roll|, |pitch|) + bound +
  max_ang_accel gap^2/8`` between samples, ``+ max_rate x`` the time the IMU runs
  outside the stream;
* **horizontal speed**: the GNSS velocity (``|V_m| + R`` at each fix), the GNSS
  positions (chord speed ``(|dP| + sqrt(2)(h1 + h2))/gap``) or a body-velocity sensor
  measuring both components, each ``+ max_accel gap/2`` between epochs (``|V(t) -
  mean V| <= A gap/2`` for a horizontal acceleration bounded by A) and ``+ max_accel x``
  the time outside the sensor's span; the smallest of them.

A stated bound that the data contradict (an attitude beyond the stated maximum tilt) is
replaced by the data's, with a note: a guaranteed interval cannot rest on a bound the
drive itself shows false; a stated bound the data do not contradict is kept. An attitude
stream beyond 85 deg of roll or pitch is refused with an InputError naming the mount. A
default stays only where nothing in the data bounds the quantity, and is then listed by
:func:`assumed_defaults`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from imubounds.constants import G_HI, ROUND_REL
from imubounds.dynamic.estimator.inputs import Aiding, ImuSeries, Vehicle
from imubounds.dynamic.sensors import build_aiding
from imubounds.errors import InputError
from imubounds.units import DEG

if TYPE_CHECKING:
    from imubounds.dynamic.estimator.options import FullOptions

#: an attitude stream beyond this tilt is refused (Euler angles near their singularity)
TILT_LIMIT = 85.0 * DEG
#: the largest tilt bound used (the 1/cos terms of the constraints stay finite)
TILT_CAP = 89.0 * DEG


def tilt_from_attitude(ag: Aiding, veh: Vehicle, span: tuple[float, float]) -> float | None:
    """Bound of |roll| and |pitch| over ``span`` (relative s) from the attitude stream."""
    if not ag.has_attitude or ag.att_t is None or ag.att_roll is None or ag.att_pitch is None:
        return None
    at = np.asarray(ag.att_t, dtype=float)
    if at.size == 0:
        return None
    m = float(max(np.max(np.abs(ag.att_roll)), np.max(np.abs(ag.att_pitch))))
    gap = float(np.max(np.diff(at))) if at.size > 1 else 0.0
    far = max(float(at[0]) - span[0], 0.0) + max(span[1] - float(at[-1]), 0.0)
    b = m + ag.att_bound + veh.max_ang_accel * gap * gap / 8.0 + veh.max_rate * far
    return float(np.nextafter(b * (1 + ROUND_REL), np.inf))


def _grown(t: np.ndarray, s: np.ndarray, accel: float, span: tuple[float, float]) -> float:
    """Largest speed over the span, speeds ``s`` (upper bounds) at epochs ``t``: each
    gap adds ``accel gap/2`` to the larger end, the time outside the epochs ``accel x``
    that time."""
    far = max(float(t[0]) - span[0], 0.0) + max(span[1] - float(t[-1]), 0.0)
    best = float(np.max(s)) + accel * far
    if t.size > 1:
        g = np.diff(t)
        best = max(best, float(np.max(np.maximum(s[:-1], s[1:]) + accel * g / 2.0)))
    return best


def speed_from_aiding(
    ag: Aiding, veh: Vehicle, span: tuple[float, float]
) -> tuple[float, str] | None:
    """The smallest horizontal-speed bound over ``span`` the aiding gives, and its
    sensor; None without speed aiding."""
    cands: list[tuple[float, str]] = []
    a = veh.max_accel
    if ag.has_gvel:
        ok = ag.gvel_ok
        t = ag.gnss_t[ok]
        if t.size:
            s = np.hypot(ag.gvel_e[ok], ag.gvel_n[ok]) + ag.gvel_hi[ok]
            cands.append((_grown(t, s, a, span), "GNSS velocity"))
    if ag.has_gnss and ag.gnss_t.size >= 2:
        t = ag.gnss_t
        far = max(float(t[0]) - span[0], 0.0) + max(span[1] - float(t[-1]), 0.0)
        # chords over k fix gaps: the position error counts once per chord, the
        # acceleration k gaps; every k gives a bound, the smallest is kept
        for k in range(1, min(5, t.size)):
            g = t[k:] - t[:-k]
            d = np.hypot(ag.gnss_e[k:] - ag.gnss_e[:-k], ag.gnss_n[k:] - ag.gnss_n[:-k])
            chord = (d + math.sqrt(2) * (ag.gnss_h[k:] + ag.gnss_h[:-k])) / g + a * g / 2.0
            edge = float(max(chord[0], chord[-1])) + a * far
            cands.append((max(float(np.max(chord)), edge), "GNSS positions"))
    if ag.has_bvel and ag.bvel_v is not None and np.all(np.isfinite(ag.bvel_v)):
        t = ag.bvel_t
        if t.size:
            s = np.abs(ag.bvel_u) + np.abs(ag.bvel_v) + 2 * ag.bvel_h
            cands.append((_grown(t, s, a, span), f"body velocity ({ag.bvel_kind})"))
    cands = [c for c in cands if math.isfinite(c[0])]
    if not cands:
        return None
    v, src = min(cands)
    return float(np.nextafter(v * (1 + ROUND_REL), np.inf)), src


def bound_vehicle(
    veh: Vehicle, ag: Aiding, span: tuple[float, float]
) -> tuple[bool, list[str]]:
    """Replace the vehicle's speed and tilt bounds by the data's where the data bound
    them (in place); returns whether anything changed and the notes."""
    notes: list[str] = []
    changed = False
    tilt = tilt_from_attitude(ag, veh, span)
    if tilt is not None:
        stated = not veh.sources.get("max_tilt", "default").startswith("default")
        assert ag.att_roll is not None and ag.att_pitch is not None
        seen = float(max(np.max(np.abs(ag.att_roll)), np.max(np.abs(ag.att_pitch))))
        if seen - ag.att_bound > TILT_LIMIT:
            raise InputError(
                f"the attitude stream reaches {seen / DEG:.1f} deg of roll or pitch: beyond "
                f"{TILT_LIMIT / DEG:.0f} deg the roll/pitch constraints of the windows do not "
                "hold (Euler angles near their singularity); check the IMU mount (imu_axes "
                "in drive.yaml or --imu-axes) and the attitude stream's frame"
            )
        # between samples the growth terms may pass the limit: hold the bound below 90 deg
        # (the 1/cos terms stay finite; they only widen)
        tilt = min(tilt, TILT_CAP)
        contradicted = seen - ag.att_bound > veh.max_tilt
        if stated and contradicted:
            notes.append(
                f"the attitude stream exceeds the stated maximum tilt "
                f"({(seen - ag.att_bound) / DEG:.2f} > {veh.max_tilt / DEG:g} deg): the "
                "tilt bound is the stream's"
            )
        if (not stated or contradicted) and tilt != veh.max_tilt:
            veh.max_tilt = tilt
            veh.sources["max_tilt"] = "data: attitude stream"
            changed = True
    sp = speed_from_aiding(ag, veh, span)
    if sp is not None:
        v, src = sp
        stated = not veh.sources.get("max_speed", "default").startswith("default")
        if not stated or v < veh.max_speed:
            veh.max_speed = v
            veh.sources["max_speed"] = f"data: {src}"
            changed = True
    return changed, notes


def assumed_defaults(veh: Vehicle) -> list[str]:
    """The vehicle bounds still taken from the defaults (nothing in the data bounds
    them), named with their values."""
    names = {
        "max_speed": ("speed", veh.max_speed, "m/s", 1.0),
        "max_accel": ("horizontal acceleration", veh.max_accel, "m/s^2", 1.0),
        "max_jerk": ("jerk", veh.max_jerk, "m/s^3", 1.0),
        "max_rate": ("angular rate", veh.max_rate, "deg/s", DEG),
        "max_ang_accel": ("angular acceleration", veh.max_ang_accel, "deg/s^2", DEG),
        "max_tilt": ("tilt", veh.max_tilt, "deg", DEG),
    }
    out = []
    for key, (what, val, unit, fac) in names.items():
        if veh.sources.get(key, "default").startswith("default"):
            out.append(f"{what} <= {val / fac:g} {unit}")
    return out


def refine_vehicle(
    drive: Any,
    veh: Vehicle,
    imu: ImuSeries,
    aiding: Aiding,
    alpha: Any,
    opts: FullOptions,
    heading: Any,
) -> tuple[ImuSeries, Aiding, list[str]]:
    """:func:`bound_vehicle` on the built inputs; the IMU series and the aiding (whose
    unknown-sample bounds, course heading and outlier test read the vehicle bounds)
    are built again when a bound changed. Returns them and the notes."""
    span = (float(imu.bnd[0]), float(imu.bnd[-1]))
    changed, notes = bound_vehicle(veh, aiding, span)
    if changed:
        imu = ImuSeries.from_drive(drive, imu.stamp, veh)
        aiding = build_aiding(drive, imu.t0, veh, alpha, opts, heading)
    left = assumed_defaults(veh)
    if left:
        notes.append(
            "vehicle bounds nothing in the data bounds, taken from the defaults "
            "(assumed; state them in drive.yaml vehicle: or by option): " + ", ".join(left)
        )
    return imu, aiding, notes


def dominant_default(
    ch: str, veh: Vehicle, halfwidth: float | None, tau_s: float,
    pitch_halfwidth: float | None = None,
) -> str | None:
    """A note when an assumed default dominates an accelerometer's aided interval at its
    longest averaging time: the gravity through the default maximum tilt. accel_x's
    gravity term follows the pitch: where the data bounded it (``pitch_halfwidth``, the
    median half-width of the pitch from GNSS altitude, rad) the default does not
    dominate it unless g sin of that half-width still does."""
    if halfwidth is None or not ch.startswith("accel_") or ch == "accel_z":
        return None
    if not veh.sources.get("max_tilt", "default").startswith("default"):
        return None
    tilt = veh.max_tilt
    if ch == "accel_x" and pitch_halfwidth is not None:
        tilt = min(tilt, pitch_halfwidth)
    grav = G_HI * math.sin(tilt)
    if grav < 0.5 * halfwidth:
        return None
    if tilt < veh.max_tilt:
        return (
            f"the pitch from GNSS altitude (median +-{tilt / DEG:.3g} deg, within the "
            f"assumed default maximum tilt {veh.max_tilt / DEG:g} deg) dominates: gravity "
            f"through it is +-{grav:.3g} m/s^2 of the +-{halfwidth:.3g} m/s^2 at tau "
            f"{tau_s:.3g} s (docs/dynamic-method.md section 3a)"
        )
    return (
        f"the assumed default maximum tilt ({veh.max_tilt / DEG:g} deg; nothing in the data "
        f"bounds roll and pitch) dominates: gravity through it is +-{grav:.3g} m/s^2 of the "
        f"+-{halfwidth:.3g} m/s^2 at tau {tau_s:.3g} s; an attitude stream or "
        "vehicle.max_tilt_deg in drive.yaml (or --max-tilt) tightens it (the drive's GNSS "
        "and speed cannot: the IMU's mount pitch on the vehicle adds to f_x what an "
        "accelerometer bias adds; docs/dynamic-method.md section 3a)"
    )


def dominant_transport(
    ch: str, veh: Vehicle, halfwidth: float | None, tau_s: float, mean_abs_r: float
) -> str | None:
    """A note when accel_x's transport term ``max|v| mean|r|`` dominates its aided interval
    because no lateral-velocity bound is stated (|v| then only bounded by the speed bound);
    ``mean_abs_r`` is the trip's mean |gyro_z| (an estimate of the term, for the note)."""
    if halfwidth is None or ch != "accel_x" or veh.lateral_speed_bound_mps is not None:
        return None
    est = veh.max_speed * mean_abs_r
    if not est >= 0.5 * halfwidth:
        return None
    return (
        f"no lateral-velocity bound is stated: the transport term |v| x mean|r| takes the "
        f"speed bound ({veh.max_speed:.3g} m/s, {veh.sources.get('max_speed', 'default')}) "
        f"x the mean yaw rate (~{mean_abs_r:.3g} rad/s) ~ {est:.3g} m/s^2 against the "
        f"+-{halfwidth:.3g} m/s^2 at tau {tau_s:.3g} s; nothing in the data bounds the side "
        "slip: for a wheeled vehicle state vehicle.lateral_speed_bound_mps in drive.yaml "
        "(or --lateral-speed-bound)"
    )


def heave_note(ch: str, veh: Vehicle, levels: list[Any]) -> str | None:
    """A note when accel_z exceeds on a ground vehicle: how large the vertical body-velocity
    bound W' would have to be at least for every exceeding window to be consistent (a
    window's interval widens by at most ``2 (W' - W)/tau``, the mean of w' over it). A
    small W' (tenths of m/s) means a heave beyond the stated W (a harder bump, the IMU's
    pitch against the path x speed) may explain the finding instead of an IMU fault."""
    if ch != "accel_z" or veh.kind != "ground":
        return None
    need = 0.0
    taus: list[float] = []
    for lv in levels:
        if lv.kind != "aided":
            continue
        ex = lv.exceeds
        if not np.any(ex):
            continue
        over = np.maximum(lv.e_lo - lv.band, -lv.band - lv.e_hi)[ex]
        need = max(need, float(np.max(over * lv.tau[ex] / 2.0)))
        taus.append(lv.tau_s)
    if not taus:
        return None
    W = veh.vertical_bound
    return (
        f"accel_z exceeds at tau {', '.join(f'{t:.3g}' for t in taus)} s; for those "
        f"windows to be consistent the vertical body velocity bound would have to be at "
        f"least {W + need:.3g} m/s instead of {W:g} m/s "
        f"({veh.sources.get('vertical_bound', 'default')}): if the vehicle can heave that "
        "much (road bumps, the IMU's pitch against the path x speed), state "
        "vehicle.vertical_speed_bound_mps (--vertical-speed-bound) and run again"
    )
