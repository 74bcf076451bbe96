"""Checks of a drive's IMU stream (part of :func:`imubounds.io.drive.validate.validate_drive`,
whose table lists them all), and the helpers the other streams' checks share: the file a
stream came from, a data row, a reference heading and the course of the GNSS positions.

Every problem is a one-line error naming the file, the column (body axis) and the row, or a
counted warning (:meth:`~imubounds.io.drive.Drive.warn`).
"""

from __future__ import annotations

import math

import numpy as np

from imubounds.errors import InputError, UnitsError
from imubounds.io.drive import Drive
from imubounds.units import DEG, G0

#: Largest full-scale range of MEMS gyros (2000 deg/s), rad/s.
GYRO_FULL_SCALE_RADS = 2000.0 * DEG
#: Largest full-scale range of MEMS accelerometers (400 g, impact sensors), m/s^2.
ACCEL_FULL_SCALE_MPS2 = 400.0 * G0
#: ``drive.meta`` key of the messages about samples beyond any MEMS range (corrupt
#: samples): ``convert`` keeps them with the warning, ``dynamic`` refuses them.
CORRUPT_SAMPLES = "corrupt_samples"


# ----------------------------------------------------------------------------- helpers


def file_label(drive: Drive, name: str) -> str:
    files = drive.meta.get("files", {})
    return str(files.get(name, f"{drive.source} ({name})"))


def data_row(t: np.ndarray, i: int) -> str:
    return f"data row {i + 1} (t={t[i]:.3f} s)"


def reference_heading(drive: Drive) -> tuple[np.ndarray, np.ndarray, str] | None:
    """A heading (t, unwrapped compass heading rad, label) to check the gyro against."""
    if drive.heading is not None and drive.heading.t.size >= 3:
        return drive.heading.t, np.unwrap(drive.heading.heading_rad), "heading"
    a = drive.attitude
    if a is not None and a.yaw_rad is not None and a.t.size >= 3:
        return a.t, np.unwrap(a.yaw_rad), "attitude yaw"
    g = drive.gnss
    if g is not None:
        course = position_course(drive)
        if course is not None and course[0].size >= 5:
            return course[0], np.unwrap(course[1]), "GNSS course over ground"
    return None


def position_course(drive: Drive, min_speed: float = 3.0) -> tuple[np.ndarray, ...] | None:
    """(t_mid, course rad clockwise from north, speed m/s) between usable consecutive fixes
    moving at least ``min_speed`` (from positions only)."""
    g = drive.gnss
    if g is None:
        return None
    ok = g.usable()
    if ok.sum() < 3:
        return None
    lat, lon, t = g.lat_deg[ok], g.lon_deg[ok], g.t[ok]
    if np.max(np.abs(lat)) > 90 or np.max(np.abs(lon)) > 180:
        return None
    e, n = local_en(lat, lon)
    de, dn, dt = np.diff(e), np.diff(n), np.diff(t)
    speed = np.hypot(de, dn) / dt
    keep = np.isfinite(speed) & (speed >= min_speed)
    tm = 0.5 * (t[1:] + t[:-1])
    return tm[keep], np.mod(np.arctan2(de, dn), 2 * math.pi)[keep], speed[keep]


def local_en(lat: np.ndarray, lon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Equirectangular east/north metres about the first point (enough for checks)."""
    r = 6_371_000.0
    lat0 = math.radians(float(lat[0]))
    e = np.radians(lon - lon[0]) * r * math.cos(lat0)
    n = np.radians(lat - lat[0]) * r
    return e, n


# ----------------------------------------------------------------------------- IMU


def check_imu(drive: Drive) -> None:
    imu = drive.imu
    assert imu is not None
    f = file_label(drive, "imu")
    t = imu.t
    if t.size < 2:
        raise InputError(f"{f}: the IMU has {t.size} sample(s); at least 2 are needed")
    for kind, arr in (("gyro", imu.gyro), ("accel", imu.accel)):
        for j, ax in enumerate("xyz"):
            col = arr[:, j]
            fin = np.isfinite(col)
            if not fin.any() or fin.all():
                continue  # an absent axis is all NaN; a present one must be finite
            i = int(np.flatnonzero(~fin)[0])
            n_bad = int((~fin).sum())
            raise InputError(
                f"{f}: {kind}_{ax} (body axes) is {col[i]} at {data_row(t, i)}"
                f"{f' and {n_bad - 1} more row(s)' if n_bad > 1 else ''}; "
                "repair or remove these rows (an IMU sample cannot be skipped)"
            )
    dt = np.diff(t)
    med = float(np.median(dt))
    _check_imu_rate(f, t, med)
    gaps = np.flatnonzero(dt > 5.0 * med)
    if gaps.size:
        k = int(gaps[np.argmax(dt[gaps])])
        drive.warn(
            "imu_gaps",
            int(gaps.size),
            f"{f}: {gaps.size} gap(s) in the IMU time stamps longer than 5 sample periods "
            f"(largest {dt[k]:.3f} s after t={t[k]:.3f} s)",
        )
    _check_gyro_spikes(drive, f)
    _check_gyro_units(drive, f)
    _check_accel_units(drive, f)
    _check_axis_units(drive, f)
    _check_stuck(drive, f)


#: IMU rates (Hz) a drive log can have; outside, time_s is in another unit than s.
IMU_RATE_RANGE_HZ = (0.5, 1.0e5)
TIME_SCALES = (("ms", 1e3), ("us", 1e6), ("ns", 1e9))


def _check_imu_rate(f: str, t: np.ndarray, med: float) -> None:
    lo, hi = IMU_RATE_RANGE_HZ
    if not med > 0:
        return
    rate = 1.0 / med
    if lo <= rate <= hi:
        return
    fits = next((u for u, k in TIME_SCALES if lo <= rate * k <= hi), None)
    hint = (f"time_s looks like {fits} ({rate * dict(TIME_SCALES)[fits]:.4g} Hz then); "
            f"convert it to seconds" if fits else "check time_s (seconds on one clock)")
    raise InputError(
        f"{f}: the IMU's median time step {med:.4g} s means {rate:.4g} Hz, a rate no IMU log "
        f"has ({lo:g}..{hi:g} Hz): {hint}"
    )


def _runs(mask: np.ndarray, min_len: int = 1) -> list[tuple[int, int]]:
    """(first, last) indices of the runs of True in ``mask`` at least ``min_len`` long."""
    m = np.concatenate(([False], mask, [False])).astype(np.int8)
    d = np.diff(m)
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1
    long = ends - starts + 1 >= min_len
    return list(zip(starts[long].tolist(), ends[long].tolist(), strict=True))


def _check_gyro_spikes(drive: Drive, f: str) -> None:
    """A few samples beyond any MEMS range (a 1e300 sample) while the rest is plausible:
    a counted warning per axis naming the epochs (the units checks handle whole logs);
    the messages are kept in ``drive.meta[CORRUPT_SAMPLES]``."""
    imu = drive.imu
    assert imu is not None
    t = imu.t
    for kind, arr, top, shown in (
        ("gyro", imu.gyro, GYRO_FULL_SCALE_RADS, "2000 deg/s range of any MEMS gyro"),
        ("accel", imu.accel, ACCEL_FULL_SCALE_MPS2,
         "400 g range of any MEMS accelerometer"),
    ):
        for j, ax in enumerate("xyz"):
            col = arr[:, j]
            if not np.isfinite(col).all():
                continue
            big = np.abs(col) > top
            nb = int(big.sum())
            if nb == 0 or nb > max(1, col.size // 1000):
                continue  # none, or too many for spikes: the unit checks speak
            idx = np.flatnonzero(big)
            peak = float(np.max(np.abs(col[idx])))
            value = (f"{math.degrees(peak):.3g} deg/s" if kind == "gyro"
                     else f"{peak:.3g} m/s^2")  # fmt: skip
            what = (
                f"{f}: {kind}_{ax} (body axes) has {nb} sample(s) beyond the {shown} (up "
                f"to {value}) between t={t[idx[0]]:.3f} and t={t[idx[-1]]:.3f} s (first at "
                f"data row {idx[0] + 1})"
            )
            drive.warn(f"{kind}_spikes", nb, f"{what}: corrupt samples; repair or remove them "
                       "(every margin and bound that spans them is inflated)")
            drive.meta.setdefault(CORRUPT_SAMPLES, []).append(what)


#: Units between which one axis can be mislabelled: (ratio of their numbers, the unit of
#: the larger numbers, of the smaller, the conversion to the SI one) and the p99 of
#: |value - median| in SI beyond which a vehicle's roll and pitch (a horizontal
#: acceleration) cannot go: 100 deg/s, 30 m/s^2.
_AXIS_UNITS = {
    "gyro": (180.0 / math.pi, "deg/s", "rad/s", "x pi/180", 100.0 * DEG),
    "accel": (G0, "m/s^2", "g", "x 9.80665", 30.0),
}


def _noise_floor(x: np.ndarray) -> float:
    """Sample-to-sample noise of a channel: the robust spread of its second differences
    (the smooth motion of a vehicle hardly enters them), per sample."""
    with np.errstate(over="ignore", invalid="ignore"):  # a corrupt 1e308 sample
        d2 = x[2:] - 2.0 * x[1:-1] + x[:-2]
        if d2.size < 20:
            return 0.0
        return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


def _axis_unit_words(kind: str, larger: bool, read_as: str) -> tuple[str, bool]:
    """What an axis whose numbers are ``factor`` x too large (``larger``) or too small
    against the z axis is likely in, and whether that is a unit (else a conversion made
    twice)."""
    factor, big, small, _, _ = _AXIS_UNITS[kind]
    real = big if larger else small
    if real != read_as:
        return f"to be in {real} while read as {read_as}", True
    how = "too large" if larger else "too small"
    return f"{factor:.3g}x {how} for {read_as} (converted twice?)", False


def _check_axis_units(drive: Drive, f: str) -> None:
    """Each x and y axis against the z axis of the same sensor (checked against the heading
    for the gyro): one IMU's axes have noise floors within a few times of each other (real
    drives: up to 9x, from vibration), so a floor about 57x (1/57) the z axis's says the
    axis's numbers are deg/s (rad/s), 9.8x (1/9.8) m/s^2 (g), against what the z axis
    and the column names say. With values beyond what a vehicle's roll and pitch (its
    horizontal acceleration) do, it is an error; else a counted warning."""
    imu = drive.imu
    assert imu is not None
    for kind, arr in (("gyro", imu.gyro), ("accel", imu.accel)):
        factor, big, small, _, beyond = _AXIS_UNITS[kind]
        read_as = {"rad/s": "rad/s", "deg/s": "deg/s", "g": "g"}.get(
            imu.input_units.get(kind, ""), "rad/s" if kind == "gyro" else "m/s^2")
        si = "rad/s" if kind == "gyro" else "m/s^2"
        z = arr[:, 2]
        fz = _noise_floor(z) if np.isfinite(z).all() else 0.0
        if not fz > 0:
            continue
        for j, ax in enumerate("xy"):
            col = arr[:, j]
            if not np.isfinite(col).all():
                continue
            r = _noise_floor(col) / fz
            larger = factor / 3.0 <= r <= factor * 3.0
            if not (larger or 1.0 / (factor * 3.0) <= r <= 3.0 / factor):
                continue
            words, is_unit = _axis_unit_words(kind, larger, read_as)
            shown = f"{r:.0f}x" if larger else f"1/{1 / r:.0f} of"
            msg = (f"{f}: {kind}_{ax}'s sample-to-sample noise is {shown} {kind}_z's (one "
                   f"IMU's axes differ a few times at most; {big} against {small} gives "
                   f"{factor:.3g}x): {kind}_{ax} looks {words}")
            p99 = float(np.percentile(np.abs(col - np.median(col)), 99))
            if larger and is_unit and p99 > beyond:
                raise UnitsError(
                    f"{msg}, and its values go far beyond what a vehicle does; convert "
                    f"{kind}_{ax} to {si} like {kind}_z"
                )
            fix = f"convert it to {si}" if is_unit else "undo the second conversion"
            drive.warn(f"{kind}_axis_units", 1, f"{msg}; {fix} if so")


def _check_stuck(drive: Drive, f: str) -> None:
    """A gyro axis that repeats one value for a long run (>= 5 s and 100 samples): counted
    warning naming the axis, the value and the span (and how far the heading turned)."""
    imu = drive.imu
    assert imu is not None
    t = imu.t
    if t.size < 100:
        return
    ref = reference_heading(drive)
    for j, ax in enumerate("xyz"):
        col = imu.gyro[:, j]
        if not np.isfinite(col).all():
            continue
        same = np.diff(col) == 0
        best = None
        for a, b in _runs(same, min_len=99):
            n = b - a + 2  # samples in the run
            span = float(t[b + 1] - t[a])
            if n >= 100 and span >= 5.0 and (best is None or span > best[2]):
                best = (a, b + 1, span)
        if best is None:
            continue
        a, b, span = best
        turn = ""
        if ref is not None:
            psi = np.interp([t[a], t[b]], ref[0], ref[1])
            turned = abs(math.degrees(float(psi[1] - psi[0])))
            if turned >= 1.0:
                turn = f" while the {ref[2]} turns {turned:.0f} deg"
        drive.warn(
            "gyro_stuck",
            b - a + 1,
            f"{f}: gyro_{ax} (body axes) repeats {math.degrees(float(col[a])):.6g} deg/s for "
            f"{b - a + 1} samples from t={t[a]:.3f} to t={t[b]:.3f} s{turn}: the channel is "
            "stuck or dropped out there; check the sensor",
        )


def _check_gyro_units(drive: Drive, f: str) -> None:
    imu = drive.imu
    assert imu is not None
    g = imu.gyro
    present = [j for j in range(3) if np.isfinite(g[:, j]).all()]
    if not present:
        return
    mag = np.abs(g[:, present])
    top = float(np.percentile(mag, 99.9))
    unit = imu.input_units.get("gyro", "") or "rad/s"
    if top > GYRO_FULL_SCALE_RADS:
        raise UnitsError(
            f"{f}: gyro values reach {top:.1f} rad/s ({math.degrees(top):.0f} deg/s), beyond "
            f"any MEMS gyro's range (2000 deg/s): the columns (read as {unit}) are probably in "
            "deg/s; name them gyro_*_dps"
        )
    if 2 not in present:
        return
    ref = reference_heading(drive)
    if ref is None:
        return
    slope, r2, turned = rate_slope(imu.t, -g[:, 2], *ref[:2])
    if slope is None or r2 < 0.5 or turned < math.radians(90.0):
        return
    deg = 180.0 / math.pi
    if 0.6 * deg < slope < 1.5 * deg:
        raise UnitsError(
            f"{f}: gyro_z turns {slope:.0f}x faster than the {ref[2]} (about 57x): the gyro "
            f"columns (read as {unit}) are in deg/s; name them gyro_*_dps"
        )
    if 0.6 / deg < slope < 1.5 / deg:
        raise UnitsError(
            f"{f}: gyro_z turns {1 / slope:.0f}x slower than the {ref[2]} (about 1/57): the gyro "
            f"columns (read as {unit}) are in rad/s; name them gyro_*_rads"
        )
    if -1.5 < slope < -0.6:
        also = (
            " (or the GNSS file has latitude and longitude swapped, or a sign lost)"
            if ref[2].startswith("GNSS") else ""
        )
        raise InputError(
            f"{f}: gyro_z turns against the {ref[2]} (rate ratio {slope:.2f}): the body z axis "
            f"points down; fix the mount with imu_axes (e.g. [x, -y, -z] for an FRD unit){also}"
        )
    drive.meta["gyro_heading_rate_ratio"] = slope


def rate_slope(
    t_imu: np.ndarray, rate: np.ndarray, t_ref: np.ndarray, psi_ref: np.ndarray,
    min_step: float = 0.5,
) -> tuple[float | None, float, float]:
    """Slope (through the origin) of the IMU's clockwise rate against a reference heading's
    rate over intervals of at least 0.5 s, the fit's R^2, and the total turn (rad) of the
    reference. A constant gyro bias only perturbs the slope."""
    lo, hi = max(t_imu[0], t_ref[0]), min(t_imu[-1], t_ref[-1])
    if hi - lo < 5.0:
        return None, 0.0, 0.0
    step = max(min_step, float(np.median(np.diff(t_ref))))
    grid = np.arange(lo, hi, step)
    if grid.size < 6:
        return None, 0.0, 0.0
    psi = np.interp(grid, t_ref, psi_ref)
    ref_rate = np.diff(psi) / step
    cum = np.concatenate(([0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t_imu))))
    imu_rate = np.diff(np.interp(grid, t_imu, cum)) / step
    turned = float(np.sum(np.abs(np.diff(psi))))
    with np.errstate(over="ignore", invalid="ignore"):  # a corrupt 1e300 sample
        den = float(np.sum(ref_rate**2))
        tot = float(np.sum(imu_rate**2))
        if den == 0 or tot == 0 or not math.isfinite(tot):
            return None, 0.0, turned
        slope = float(np.sum(ref_rate * imu_rate) / den)
        r2 = 1.0 - float(np.sum((imu_rate - slope * ref_rate) ** 2)) / tot
    if not (math.isfinite(slope) and math.isfinite(r2)):
        return None, 0.0, turned
    return slope, r2, turned


def _check_accel_units(drive: Drive, f: str) -> None:
    imu = drive.imu
    assert imu is not None
    a = imu.accel
    if not np.isfinite(a).all():
        return
    with np.errstate(over="ignore"):  # a corrupt 1e300 sample: inf, beyond the median
        norm = float(np.median(np.linalg.norm(a, axis=1)))
    unit = imu.input_units.get("accel", "") or "m/s^2"
    if 0.5 < norm < 2.0:
        raise UnitsError(
            f"{f}: the median |acceleration| is {norm:.2f} (read as {unit}) where gravity alone "
            "gives 9.8 m/s^2: the columns are in g; name them accel_*_g"
        )
    if 50.0 < norm < 200.0:
        raise UnitsError(
            f"{f}: the median |acceleration| is {norm:.1f} m/s^2 (read as {unit}); the columns "
            "are in m/s^2, not g: name them accel_*_mps2"
        )
    if not 4.0 < norm < 25.0:
        drive.warn(
            "accel_implausible",
            1,
            f"{f}: the median |acceleration| is {norm:.3g} m/s^2, far from gravity (9.8); "
            "check the accelerometer unit",
        )


