"""Validation of drive inputs: every problem is a one-line error or a counted warning.

:func:`existing_file` refuses special files (named pipes, devices, sockets) with
:func:`imubounds.io.validate.check_input_path` *before* anything opens them, so a pipe
given as a log cannot block a run.
:func:`validate_drive` checks a :class:`~imubounds.io.drive.Drive` that a
reader produced, in SI, after the mount rotation:

========================  =====================================================
IMU samples               NaN or infinite values: error naming the row and time
gyro units                beyond any MEMS range, or turning 57x (or 1/57x) the
                          heading/course rate: :class:`UnitsError` (deg/s named
                          rad/s, or the reverse); turning against the heading:
                          error (mount or ``imu_axes`` wrong)
accelerometer units       median |a| near 1 (g named m/s^2) or near 96 (m/s^2
                          named g): :class:`UnitsError`
GNSS positions            no finite latitude; degrees x 1e7 integers; out of
                          range; latitude/longitude swapped; radians given as
                          degrees: errors. Rows without a fix or with NaN
                          positions: skipped and counted
HDOP / h_acc_m            <= 0 or NaN: counted, treated as not reported (the
                          drive's default HDOP / CEP then applies)
speeds                    beyond ``vehicle.max_speed_mps`` (``--max-speed``):
                          the sample is dropped and counted; position jumps
                          faster than that are counted
heading, attitude, mag    NaN rows dropped and counted; angles out of range and
                          radians given as degrees: errors
time ranges               an aiding stream that does not overlap the IMU at
                          all: error naming both ranges
========================  =====================================================

Generic sample checks (finite values, monotonic time) are written here for the
drive streams; the generic IMU-stream validation of the static readers lives
in its own module, and both are meant to share one layer.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from imubounds.errors import InputError, UnitsError
from imubounds.io.drive import Drive
from imubounds.io.drive.validate_imu import (
    GYRO_FULL_SCALE_RADS,
    TIME_SCALES,
    check_imu,
    local_en,
    position_course,
    rate_slope,
)
from imubounds.io.drive.validate_imu import data_row as _where
from imubounds.io.drive.validate_imu import file_label as _file
from imubounds.io.validate import check_input_path

__all__ = ["GYRO_FULL_SCALE_RADS", "existing_file", "validate_drive"]


# ----------------------------------------------------------------------------- paths


def existing_file(d: Path, stem: str, suffixes: tuple[str, ...]) -> Path | None:
    """The first ``d/stem+suffix`` that exists, checked with
    :func:`imubounds.io.validate.check_input_path`.

    Unlike ``Path.is_file`` this does not silently skip a named pipe called
    ``imu.csv``: a special file is refused with an error.
    """
    for suffix in suffixes:
        p = d / f"{stem}{suffix}"
        if os.path.lexists(p):
            return check_input_path(p, what=f"the drive's {stem} table")
    return None


# ----------------------------------------------------------------------------- GNSS


def _check_gnss(drive: Drive, max_speed: float) -> None:
    g = drive.gnss
    assert g is not None
    f = _file(drive, "gnss")
    t = g.t
    n = t.size
    lat, lon = g.lat_deg, g.lon_deg
    fin = np.isfinite(lat) & np.isfinite(lon)
    if not fin.any():
        raise InputError(
            f"{f}: lat_deg/lon_deg have no finite value in {n} row(s): no usable GPS fix; "
            "check the position columns"
        )
    big = np.nanmax(np.abs(np.concatenate([lat[fin], lon[fin]])))
    if big > 1000.0:
        raise UnitsError(
            f"{f}: positions reach {big:.0f}: these look like degrees x 1e7 (integer "
            "latitude/longitude of PX4 or u-blox); divide lat/lon by 1e7"
        )
    bad_lat = fin & (np.abs(lat) > 90.0)
    bad_lon = fin & (np.abs(lon) > 180.0)
    if bad_lat.any():
        i = int(np.flatnonzero(bad_lat)[0])
        if np.all(np.abs(lon[fin]) <= 90.0) and np.all(np.abs(lat[fin]) <= 180.0):
            raise InputError(
                f"{f}: lat_deg is {lat[i]:g} at {_where(t, i)} (beyond +-90) while every "
                "lon_deg is within +-90: latitude and longitude are swapped"
            )
        raise InputError(f"{f}: lat_deg is {lat[i]:g} at {_where(t, i)}, outside -90..90")
    if bad_lon.any():
        i = int(np.flatnonzero(bad_lon)[0])
        raise InputError(f"{f}: lon_deg is {lon[i]:g} at {_where(t, i)}, outside -180..180")
    if g.fix is not None:
        nofix = int((~g.fix.astype(bool)).sum())
        if nofix == n:
            raise InputError(f"{f}: none of the {n} rows has a fix (fix = 0): no usable GPS fix")
        drive.warn(
            "gnss_no_fix", nofix, f"{f}: {nofix} of {n} row(s) without a fix (fix = 0) skipped"
        )
    with_fix = g.fix.astype(bool) if g.fix is not None else np.ones(n, bool)
    nan_rows = int((with_fix & ~fin).sum())
    drive.warn(
        "gnss_nan_position",
        nan_rows,
        f"{f}: {nan_rows} row(s) with a fix but no latitude/longitude (NaN) skipped",
    )
    usable = g.usable()
    for name in ("hdop", "h_acc_m"):
        v = getattr(g, name)
        if v is None:
            continue
        bad = usable & ~(np.isfinite(v) & (v > 0))
        nb = int(bad.sum())
        if nb:
            i = int(np.flatnonzero(bad)[0])
            what = "HDOP" if name == "hdop" else "h_acc_m"
            drive.warn(
                f"gnss_{name}_invalid",
                nb,
                f"{f}: {nb} fix(es) with {what} <= 0 or missing (first {v[i]:g} at "
                f"{_where(t, i)}): treated as not reported (the drive's default applies)",
            )
            v = v.astype(float, copy=True)
            v[~(np.isfinite(v) & (v > 0))] = np.nan
            setattr(g, name, v)
    _check_gnss_speed(drive, f, max_speed)
    _check_gnss_consistency(drive, f)
    _check_gnss_one_spot(drive, f)


def _check_gnss_one_spot(drive: Drive, f: str) -> None:
    """Every usable fix at exactly one position: a frozen receiver (counted warning)."""
    g = drive.gnss
    assert g is not None
    ok = g.usable()
    n = int(ok.sum())
    if n < 3:
        return
    lat, lon = g.lat_deg[ok], g.lon_deg[ok]
    if np.ptp(lat) == 0 and np.ptp(lon) == 0:
        drive.warn(
            "gnss_one_spot",
            n,
            f"{f}: all {n} fixes sit on one spot ({lat[0]:.7f}, {lon[0]:.7f}) over "
            f"{g.t[ok][-1] - g.t[ok][0]:.1f} s: the receiver repeated one fix; if the vehicle "
            "moved, these positions are wrong (remove gnss or its position columns)",
        )


def _track_fit(
    imu_t: np.ndarray, rate: np.ndarray, t: np.ndarray, e: np.ndarray, n: np.ndarray
) -> tuple[float | None, float, float]:
    """Slope, R^2 and total turn of the gyro's clockwise rate against the course of a
    track: the course over baselines of about 5 s (between 1 Hz fixes it is noisy, tens of
    degrees), turns compared over 5 s steps."""
    stride = max(1, round(5.0 / float(np.median(np.diff(t)))))
    e, n, t = e[::stride], n[::stride], t[::stride]
    de, dn, dt = np.diff(e), np.diff(n), np.diff(t)
    keep = np.hypot(de, dn) / dt >= 3.0
    if keep.sum() < 5:
        return None, 0.0, 0.0
    tm = (0.5 * (t[1:] + t[:-1]))[keep]
    course = np.unwrap(np.arctan2(de, dn)[keep])
    return rate_slope(imu_t, rate, tm, course, min_step=5.0)


def _check_track_turns(drive: Drive) -> None:
    """The track of the fixes turns against the gyro, or only fits it with latitude and
    longitude exchanged: the coordinates are swapped (or a sign lost). With a heading or
    yaw stream the gyro was checked against it first, so the fixes are the odd one out;
    without one, a gyro whose z axis points down looks the same and both are named."""
    g, imu = drive.gnss, drive.imu
    if g is None or imu is None or not np.isfinite(imu.gyro[:, 2]).all():
        return
    checked = drive.heading is not None or (
        drive.attitude is not None and drive.attitude.yaw_rad is not None
    )
    ok = g.usable()
    if ok.sum() < 10:
        return
    lat, lon, t = g.lat_deg[ok], g.lon_deg[ok], g.t[ok]
    if np.max(np.abs(lat)) > 90 or np.max(np.abs(lon)) > 180:
        return
    rate = -imu.gyro[:, 2]
    e, n = local_en(lat, lon)
    slope, r2, turned = _track_fit(imu.t, rate, t, e, n)
    if slope is None or turned < math.radians(90.0):
        return
    if 0.6 < slope < 1.5 and r2 > 0.5:
        return  # the track turns with the gyro
    f = _file(drive, "gnss")
    swapped_ok = False
    if np.max(np.abs(lon)) <= 90:
        es, ns = local_en(lon, lat)  # the other reading: lon_deg is the latitude
        s2, r2s, _ = _track_fit(imu.t, rate, t, es, ns)
        swapped_ok = s2 is not None and 0.6 < s2 < 1.5 and r2s > 0.5
    mirrored = slope < -0.3 and r2 > 0.1
    if checked and (swapped_ok or mirrored):
        fits = ", and fits them with lat_deg and lon_deg exchanged" if swapped_ok else ""
        raise InputError(
            f"{f}: the track of the fixes turns against the gyro and the heading (rate ratio "
            f"{slope:.2f}{fits}): lat_deg and lon_deg are swapped, or one has the wrong sign; "
            "fix the columns"
        )
    if swapped_ok or slope < -0.5:
        raise InputError(
            f"{f}: the track of the fixes turns against the gyro (rate ratio {slope:.2f}) and "
            "there is no heading to say which is wrong: lat_deg and lon_deg are swapped (or a "
            "sign lost), or the IMU's z axis points down (fix imu_axes)"
        )


def _check_gnss_speed(drive: Drive, f: str, max_speed: float) -> None:
    g = drive.gnss
    assert g is not None
    if g.speed_mps is not None:
        s = g.speed_mps
        bad = np.isfinite(s) & ((s > max_speed) | (s < 0))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            drive.warn(
                "gnss_speed_beyond_max",
                int(bad.sum()),
                f"{f}: {int(bad.sum())} GNSS speed(s) negative or beyond the vehicle's maximum "
                f"{max_speed:g} m/s (first {s[i]:g} m/s at {_where(g.t, i)}) dropped",
            )
            g.speed_mps = np.where(bad, np.nan, s)
            if g.course_rad is not None:
                g.course_rad = np.where(bad, np.nan, g.course_rad)
    if g.vel_n_mps is not None and g.vel_e_mps is not None:
        sp = np.hypot(g.vel_n_mps, g.vel_e_mps)
        bad = np.isfinite(sp) & (sp > max_speed)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            drive.warn(
                "gnss_velocity_beyond_max",
                int(bad.sum()),
                f"{f}: {int(bad.sum())} GNSS velocity sample(s) beyond the vehicle's maximum "
                f"{max_speed:g} m/s (first {sp[i]:g} m/s at {_where(g.t, i)}) dropped",
            )
            g.vel_n_mps = np.where(bad, np.nan, g.vel_n_mps)
            g.vel_e_mps = np.where(bad, np.nan, g.vel_e_mps)
    ok = g.usable()
    if ok.sum() >= 2:
        e, n = local_en(g.lat_deg[ok], g.lon_deg[ok])
        dt = np.diff(g.t[ok])
        dist = np.hypot(np.diff(e), np.diff(n))
        # the fixes' own errors move them too: allow 5 sigma of the difference of two
        # fixes (P = 4e-6 per pair for Rayleigh errors) beyond the distance at max speed
        sig = _fix_sigma(drive)[ok]
        allowance = 5.0 * np.hypot(sig[:-1], sig[1:])
        fast = np.flatnonzero(dist > max_speed * dt + allowance)
        if fast.size:
            k = int(fast[0])
            drive.warn(
                "gnss_position_jumps",
                int(fast.size),
                f"{f}: {fast.size} jump(s) between consecutive fixes beyond the vehicle's "
                f"maximum {max_speed:g} m/s and 5 sigma of the fixes' errors (first "
                f"{dist[k]:.1f} m in {dt[k]:.3g} s after t={g.t[ok][k]:.3f} s): kept "
                "(outliers for the estimator)",
            )


def _fix_sigma(drive: Drive) -> np.ndarray:
    """1-sigma error of each fix per horizontal axis (m): ``h_acc_m`` where given, else
    HDOP (or the default HDOP) x CEP / 1.1774 (CEP = 1.1774 sigma for circular errors)."""
    g = drive.gnss
    assert g is not None
    st = drive.settings.gnss
    hdop = np.full(g.t.size, st.default_hdop) if g.hdop is None else np.asarray(g.hdop, float)
    hdop = np.where(np.isfinite(hdop) & (hdop > 0), hdop, st.default_hdop)
    sig = hdop * st.cep_m / 1.1774
    if g.h_acc_m is not None:
        h = np.asarray(g.h_acc_m, float)
        sig = np.where(np.isfinite(h) & (h > 0), h, sig)
    return np.asarray(sig, dtype=float)


def _check_gnss_consistency(drive: Drive, f: str) -> None:
    """Radians given as degrees and swapped coordinates, from positions against velocities."""
    g = drive.gnss
    assert g is not None
    ok = g.usable()
    if ok.sum() < 5:
        return
    pc = position_course(drive, min_speed=0.0)
    assert pc is not None
    t_mid, course_pos, speed_pos = pc
    # reported speed: GNSS speed/velocity, else the body-velocity sensor
    rep_t: np.ndarray | None = None
    rep_speed: np.ndarray | None = None
    ne = g.velocity_ne()
    if ne is not None:
        rep_t, rep_speed = g.t, np.hypot(*ne)
    elif drive.velocity is not None:
        rep_t, rep_speed = drive.velocity.t, np.abs(drive.velocity.u_mps)
    if rep_t is not None and rep_speed is not None:
        good = np.isfinite(rep_speed)
        if good.sum() >= 3:
            rs = np.interp(t_mid, rep_t[good], rep_speed[good])
            moving = rs > 2.0
            if moving.sum() >= 3:
                ratio = float(np.median(speed_pos[moving] / rs[moving]))
                if 0.6 / 57.3 < ratio < 1.5 / 57.3:
                    raise UnitsError(
                        f"{f}: the fixes move {1 / ratio:.0f}x slower than the measured speed: "
                        "lat/lon are in radians; convert them to degrees"
                    )
    lat, lon = g.lat_deg[ok], g.lon_deg[ok]
    if rep_t is None and np.all(np.abs(lat) <= math.pi / 2) and np.all(np.abs(lon) <= math.pi):
        drive.warn(
            "gnss_near_null_island",
            1,
            f"{f}: every fix lies within 3.2 deg of 0N 0E: if lat/lon are in radians, "
            "convert them to degrees",
        )
    if g.course_rad is not None and g.speed_mps is not None:
        c = g.course_rad
        fin = np.isfinite(c) & np.isfinite(g.speed_mps) & (g.speed_mps > 3.0)
        pc3 = position_course(drive, min_speed=3.0)
        if fin.sum() >= 5 and pc3 is not None and pc3[0].size >= 5:
            span = float(np.ptp(np.unwrap(pc3[1])))
            if span > math.radians(60.0) and np.nanmax(np.abs(np.degrees(c[fin]))) <= 6.3:
                raise UnitsError(
                    f"{f}: course_deg stays within 0..6.3 while the track turns "
                    f"{math.degrees(span):.0f} deg: the course is in radians; convert it to degrees"
                )
            rep = np.interp(pc3[0], g.t[fin], np.unwrap(c[fin]))
            d = np.abs(np.angle(np.exp(1j * (rep - pc3[1]))))
            if np.median(d) > math.radians(45.0):
                # swapped lat/lon mirror the track about the NE diagonal: course -> 90 deg - course
                mirrored = np.abs(np.angle(np.exp(1j * (rep - (0.5 * math.pi - pc3[1])))))
                if np.median(mirrored) < math.radians(20.0):
                    raise InputError(
                        f"{f}: the track of the fixes is the mirror image of the reported course "
                        "(north and east exchanged): latitude and longitude are swapped"
                    )
                drive.warn(
                    "gnss_course_mismatch",
                    int((d > math.radians(45.0)).sum()),
                    f"{f}: the reported course differs from the track of the fixes by a median "
                    f"{math.degrees(float(np.median(d))):.0f} deg; check course_deg",
                )


# ----------------------------------------------------------------------------- others


def _check_velocity(drive: Drive, max_speed: float) -> None:
    v = drive.velocity
    assert v is not None
    f = _file(drive, "velocity")
    for name in ("u_mps", "v_mps", "w_mps"):
        a = getattr(v, name)
        if a is None:
            continue
        bad = np.isfinite(a) & (np.abs(a) > max_speed)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            drive.warn(
                "velocity_beyond_max",
                int(bad.sum()),
                f"{f}: {int(bad.sum())} {name} sample(s) beyond the vehicle's maximum "
                f"{max_speed:g} m/s (first {a[i]:g} at {_where(v.t, i)}) dropped",
            )
            setattr(v, name, np.where(bad, np.nan, a))
    keep = np.isfinite(v.u_mps)
    nb = int((~keep).sum())
    if nb == v.t.size:
        beyond = drive.counts.get("velocity_beyond_max", 0)
        why = f" ({beyond} beyond the maximum speed {max_speed:g} m/s)" if beyond else ""
        raise InputError(f"{f}: u_mps has no usable value in {v.t.size} row(s){why}")
    if nb:
        drive.warn("velocity_nan", nb, f"{f}: {nb} row(s) with NaN u_mps skipped")
        v.t = v.t[keep]
        v.u_mps = v.u_mps[keep]
        v.v_mps = None if v.v_mps is None else v.v_mps[keep]
        v.w_mps = None if v.w_mps is None else v.w_mps[keep]


def _check_heading(drive: Drive) -> None:
    h = drive.heading
    assert h is not None
    f = _file(drive, "heading")
    if h.t.size == 0:
        raise InputError(f"{f}: heading_deg has no finite value")
    ref = position_course(drive, min_speed=3.0)
    if ref is not None and ref[0].size >= 5:
        span = float(np.ptp(np.unwrap(ref[1])))
        spread = float(np.max(np.abs(np.angle(np.exp(1j * h.heading_rad)))))
        if span > math.radians(60.0) and spread <= math.radians(6.3):
            raise UnitsError(
                f"{f}: heading_deg stays within +-6.3 while the GNSS track turns "
                f"{math.degrees(span):.0f} deg: the heading is in radians; convert it to degrees"
            )


def _check_attitude(drive: Drive) -> None:
    a = drive.attitude
    assert a is not None
    f = _file(drive, "attitude")
    keep = np.isfinite(a.roll_rad) & np.isfinite(a.pitch_rad)
    nb = int((~keep).sum())
    if nb == a.t.size:
        raise InputError(f"{f}: roll/pitch have no finite value")
    if nb:
        drive.warn("attitude_nan", nb, f"{f}: {nb} row(s) with NaN roll or pitch skipped")
        a.t, a.roll_rad, a.pitch_rad = a.t[keep], a.roll_rad[keep], a.pitch_rad[keep]
        a.yaw_rad = None if a.yaw_rad is None else a.yaw_rad[keep]
    if a.yaw_rad is not None and not np.isfinite(a.yaw_rad).all():
        bad = ~np.isfinite(a.yaw_rad)
        nb = int(bad.sum())
        if nb == a.t.size:
            drive.warn("attitude_yaw_nan", nb, f"{f}: yaw has no finite value in {nb} row(s): "
                       "the attitude's yaw is not used (roll and pitch are)")
            a.yaw_rad = None
        else:
            drive.warn("attitude_yaw_nan", nb, f"{f}: {nb} row(s) with NaN yaw skipped")
            keep = ~bad
            a.t, a.roll_rad, a.pitch_rad = a.t[keep], a.roll_rad[keep], a.pitch_rad[keep]
            a.yaw_rad = a.yaw_rad[keep]
    if np.any(np.abs(a.pitch_rad) > math.pi / 2 + 1e-9):
        i = int(np.flatnonzero(np.abs(a.pitch_rad) > math.pi / 2)[0])
        raise InputError(
            f"{f}: pitch {math.degrees(a.pitch_rad[i]):g} deg at {_where(a.t, i)} is beyond "
            "+-90 deg; check the attitude columns and their unit (degrees)"
        )
    if np.any(np.abs(a.roll_rad) > math.pi + 1e-9):
        i = int(np.flatnonzero(np.abs(a.roll_rad) > math.pi)[0])
        raise InputError(
            f"{f}: roll {math.degrees(a.roll_rad[i]):g} deg at {_where(a.t, i)} is beyond "
            "+-180 deg; check the attitude columns and their unit (degrees)"
        )


def _check_mag(drive: Drive) -> None:
    m = drive.mag
    assert m is not None
    f = _file(drive, "heading")
    keep = np.isfinite(m.mag).all(axis=1)
    nb = int((~keep).sum())
    if nb == m.t.size:
        raise InputError(f"{f}: the magnetometer columns have no finite row")
    if nb:
        drive.warn("mag_nan", nb, f"{f}: {nb} magnetometer row(s) with NaN or inf skipped")
        m.t, m.mag = m.t[keep], m.mag[keep]
    if not np.any(np.linalg.norm(m.mag, axis=1) > 0):
        raise InputError(f"{f}: the magnetometer reads zero in every row")


def _time_unit_hint(t: np.ndarray, lo: float, hi: float) -> str | None:
    """``"ms"`` (``"us"``, ``"ns"``) when an aiding stream's steps are far too long for a
    sensor (over 5 s) and its span or its times are that factor times the IMU's: its
    time_s is in that unit, not s."""
    if t.size < 2:
        return None
    a, b = float(t[0]), float(t[-1])
    step = float(np.median(np.diff(t)))
    span, ref = b - a, hi - lo
    if not step > 5.0:
        return None
    for unit, k in TIME_SCALES:
        if ref > 0 and 0.3 * k <= span / ref <= 3.0 * k:
            return unit
        mid, rmid = 0.5 * (a + b), 0.5 * (lo + hi)
        if rmid > 0 and mid > 0 and 0.3 * k <= mid / rmid <= 3.0 * k and abs(rmid) > ref:
            return unit
    return None


def _check_truth(drive: Drive) -> None:
    """Truth rows out of time order: error (the truth check interpolates in time). Rows
    without a finite position (a short, ragged row): dropped and counted; rows with some
    other value empty or NaN (a short row cut after its position): counted, named, those
    values are left out of the truth check."""
    tr = drive.truth
    assert tr is not None
    f = _file(drive, "truth")
    back = np.flatnonzero(np.diff(tr.t) <= 0)
    if back.size:
        k = int(back[0])
        raise InputError(
            f"{f}: time_s is not strictly increasing at data row {k + 2} (t={tr.t[k]:.6f} "
            f"then {tr.t[k + 1]:.6f} s; {back.size} such row(s)): the rows are out of order or "
            "repeated; sort the file by time_s and drop duplicate rows"
        )
    keep = np.isfinite(tr.t) & np.isfinite(tr.east_m) & np.isfinite(tr.north_m)
    nb = int((~keep).sum())
    if nb == tr.t.size:
        raise InputError(f"{f}: no truth row has a finite position (east/north or lat/lon)")
    if nb:
        i = int(np.flatnonzero(~keep)[0])
        drive.warn("truth_nan", nb, f"{f}: {nb} row(s) with an empty or NaN position skipped "
                   f"(first at data row {i + 1}; a short row?)")
        tr.t, tr.east_m, tr.north_m = tr.t[keep], tr.east_m[keep], tr.north_m[keep]
        for name in ("heading_rad", "u_mps", "v_mps"):
            v = getattr(tr, name)
            if v is not None:
                setattr(tr, name, v[keep])
        tr.extra = {k: v[keep] for k, v in tr.extra.items()}
    cols = {"heading_deg": tr.heading_rad, "u_mps": tr.u_mps, "v_mps": tr.v_mps, **tr.extra}
    holes = {k: ~np.isfinite(v) for k, v in cols.items()
             if v is not None and np.isfinite(v).any() and not np.isfinite(v).all()}
    if holes:
        rows = np.logical_or.reduce(list(holes.values()))
        i = int(np.flatnonzero(rows)[0])
        names = [k for k, v in holes.items() if v[i]]
        drive.warn(
            "truth_nan", int(rows.sum()),
            f"{f}: {int(rows.sum())} row(s) with empty or NaN values (first at data row "
            f"{i + 1}: {', '.join(names[:4])}{', ...' if len(names) > 4 else ''}; a short "
            "row?): those values are left out of the truth check there",
        )


def _check_overlap(drive: Drive) -> None:
    imu = drive.time_range("imu")
    assert imu is not None
    lo, hi = imu
    epochs: dict[str, int] = {}
    for name in ("gnss", "velocity", "heading", "mag", "attitude"):
        r = drive.time_range(name)
        if r is None:
            continue
        a, b = r
        st = getattr(drive, name)
        unit = _time_unit_hint(st.t, lo, hi)
        if unit is not None:
            raise UnitsError(
                f"{_file(drive, name)}: the {name} times ({a:.6g}..{b:.6g}) are about "
                f"{dict(TIME_SCALES)[unit]:.0e}x the IMU's ({lo:.6g}..{hi:.6g} s): time_s is "
                f"in {unit}, not s; convert it to seconds"
            )
        inside = (st.t >= lo) & (st.t <= hi)
        epochs[name] = int(inside.sum())
        out = int(st.t.size - epochs[name])
        if name == "gnss" and out and epochs[name]:
            drive.warn(
                "gnss_outside_imu",
                out,
                f"{_file(drive, name)}: {out} of {st.t.size} fix(es) lie outside the IMU's time "
                f"range {lo:.3f}..{hi:.3f} s and are not used",
            )
        if b < lo or a > hi:
            raise InputError(
                f"{_file(drive, name)}: the {name} stream ({a:.3f}..{b:.3f} s) does not overlap "
                f"the IMU ({lo:.3f}..{hi:.3f} s) at all: the sensors are on different clocks; "
                "give the time offset or convert the times"
            )
        covered = (min(b, hi) - max(a, lo)) / max(hi - lo, 1e-12)
        if covered < 0.5:
            drive.notes.append(
                f"the {name} stream covers {100 * covered:.0f} % of the IMU's time range"
            )
    aiding = {k: v for k, v in epochs.items() if k != "attitude"}
    _warn_single_epoch(drive, epochs, lo, hi)
    if aiding and max(aiding.values()) < 2:
        n = drive.imu.t.size if drive.imu is not None else 0
        raise InputError(
            f"{_file(drive, 'imu')}: the IMU covers only {lo:.3f}..{hi:.3f} s ({n} samples), "
            f"which holds fewer than two epochs of any aiding stream "
            f"({', '.join(f'{k}: {v}' for k, v in aiding.items())}): the IMU log is too short "
            "or cut off; give the whole IMU log"
        )


_EPOCH_WORDS = {"gnss": "fix", "velocity": "velocity sample", "heading": "heading",
                "mag": "magnetometer sample", "attitude": "attitude sample"}


def _warn_single_epoch(drive: Drive, epochs: dict[str, int], lo: float, hi: float) -> None:
    """A stream with one epoch inside the IMU's time range beside streams with more (a
    single GNSS fix beside heading and velocity streams: a truncated or filtered file?)
    constrains the trip at one instant only: a counted warning naming it."""
    if max(epochs.values(), default=0) < 2:
        return  # nothing has two epochs: the error below names the IMU's span
    for name in epochs:
        st = getattr(drive, name)
        inside = (st.t >= lo) & (st.t <= hi)
        if name == "gnss":
            inside &= st.usable()
        if int(inside.sum()) != 1:
            continue
        t = float(st.t[inside][0])
        what = _EPOCH_WORDS[name]
        drive.warn(
            f"{name}_single_epoch", 1,
            f"{_file(drive, name)}: only one {what} (t={t:.3f} s) inside the IMU's "
            f"{hi - lo:.0f} s: the {name} stream constrains the trip at that instant only "
            "(a truncated or filtered file?)",
        )


def validate_drive(drive: Drive, *, max_speed_mps: float | None = None) -> Drive:
    """Check every stream of ``drive`` (in place) and return it.

    Errors (:class:`InputError`, :class:`UnitsError`) name the file, the row
    and time, and what to do; fixable problems are dropped or neutralised and
    counted (``drive.counts``, ``drive.warnings``). ``max_speed_mps`` overrides
    the drive's ``vehicle.max_speed_mps``.
    """
    drive.check()
    max_speed = (
        float(max_speed_mps)
        if max_speed_mps is not None
        else float(drive.settings.vehicle.max_speed_mps)
    )
    if not (math.isfinite(max_speed) and max_speed > 0):
        raise InputError(f"the maximum speed must be a positive number of m/s, got {max_speed}")
    if drive.gnss is not None:
        _check_gnss(drive, max_speed)
    if drive.velocity is not None:
        _check_velocity(drive, max_speed)
    if drive.heading is not None:
        _check_heading(drive)
    if drive.attitude is not None:
        _check_attitude(drive)
    if drive.mag is not None:
        _check_mag(drive)
    if drive.truth is not None:
        _check_truth(drive)
    check_imu(drive)
    _check_overlap(drive)
    _check_track_turns(drive)
    if drive.settings.lever_arm_m is not None and any(drive.settings.lever_arm_m):
        note = (
            f"lever arm {list(drive.settings.lever_arm_m)} m (GNSS antenna from the IMU) is "
            "ignored: positions are taken at the IMU"
        )
        if note not in drive.notes:
            drive.notes.append(note)
    return drive
