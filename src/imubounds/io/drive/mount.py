"""Shared by the drive readers: nearest-time matching of two streams, the IMU mount
(``imu_axes``/``mag_axes`` applied to a :class:`~imubounds.io.drive.Drive`) and the
check of the body axes against the truth.

The format readers (:mod:`.nmea`, :mod:`.rosbag`, :mod:`.ulog`) and
:mod:`.readers` import these from here, so that no reader imports the drive
assembly back.
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np

from imubounds.frames import axes_matrix, is_identity_axes, mount_attitude, rotate_axes
from imubounds.io.drive import Drive


def match_times(
    t_src: np.ndarray, t_query: np.ndarray, tol_s: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """For each query time the index of the nearest source time, and whether it is within
    ``tol_s`` (default: half the median query period, at most 0.5 s). Sorted inputs."""
    t_src = np.asarray(t_src, dtype=float)
    t_query = np.asarray(t_query, dtype=float)
    if tol_s is None:
        tol_s = 0.5 * float(np.median(np.diff(t_query))) if t_query.size > 1 else 0.5
        tol_s = min(tol_s, 0.5)
    if t_src.size == 0:
        return np.zeros(t_query.size, int), np.zeros(t_query.size, bool)
    k = np.clip(np.searchsorted(t_src, t_query), 0, t_src.size - 1)
    prev = np.clip(k - 1, 0, t_src.size - 1)
    use_prev = np.abs(t_src[prev] - t_query) < np.abs(t_src[k] - t_query)
    k = np.where(use_prev, prev, k)
    return k, np.abs(t_src[k] - t_query) <= tol_s


# ----------------------------------------------------------------------------- mount


def apply_mount(drive: Drive, *, attitude_of_sensor: bool = False) -> None:
    """Rotate the IMU (and magnetometer) of ``drive`` from sensor to body axes by its
    ``imu_axes`` (``mag_axes``); with ``attitude_of_sensor`` the attitude stream (an
    AHRS in the same unit) is turned into the body's attitude too."""
    s = drive.settings
    rot = axes_matrix(s.imu_axes)
    mag_rot = axes_matrix(s.mag_axes) if s.mag_axes is not None else rot
    if drive.imu is not None:
        drive.imu.accel = rotate_axes(drive.imu.accel, rot)
        drive.imu.gyro = rotate_axes(drive.imu.gyro, rot)
    if drive.mag is not None:
        drive.mag.mag = rotate_axes(drive.mag.mag, mag_rot)
    a = drive.attitude
    if attitude_of_sensor and a is not None and not is_identity_axes(s.imu_axes):
        a.roll_rad, a.pitch_rad, a.yaw_rad = mount_attitude(a.roll_rad, a.pitch_rad,
                                                            a.yaw_rad, rot)
    if not is_identity_axes(s.imu_axes):
        drive.notes.append(
            f"IMU mount: imu_axes {list(s.imu_axes)} applied (sensor axes rotated into the body "
            "frame x forward, y left, z up)"
        )


_ROTATIONS: list[tuple[str, str, str]] = []


def proper_axes() -> list[tuple[str, str, str]]:
    """The 24 signed axis permutations that are rotations (every possible ``imu_axes``)."""
    if not _ROTATIONS:
        for perm in itertools.permutations("xyz"):
            for signs in itertools.product(("", "-"), repeat=3):
                axes = tuple(sg + a for sg, a in zip(signs, perm, strict=True))
                m = np.zeros((3, 3))
                for i, a in enumerate(axes):
                    m[i, "xyz".index(a[-1])] = -1.0 if a.startswith("-") else 1.0
                if np.isclose(np.linalg.det(m), 1.0):
                    _ROTATIONS.append(axes)  # type: ignore[arg-type]
    return list(_ROTATIONS)


def mount_check(drive: Drive) -> dict[str, Any] | None:
    """Check the IMU's body axes against the truth: the gyro z against the true yaw rate,
    the accelerometer x against the true forward acceleration, z against gravity.

    Returns ``{"score", "best_axes", "best_score"}`` (scores in [-3, 3]; the
    best of the 24 rotations of the current body axes), or None without truth
    heading and speed. :func:`read_drive` warns when another mapping fits
    clearly better.
    """
    tr, imu = drive.truth, drive.imu
    if tr is None or imu is None or tr.heading_rad is None or tr.u_mps is None:
        return None
    lo, hi = max(tr.t[0], imu.t[0]), min(tr.t[-1], imu.t[-1])
    if hi - lo < 5.0 or not np.isfinite(imu.gyro).all() or not np.isfinite(imu.accel).all():
        return None
    grid = np.arange(lo, hi, 0.25)
    yaw_rate = -np.gradient(np.interp(grid, tr.t, np.unwrap(tr.heading_rad)), grid)
    fwd_acc = np.gradient(np.interp(grid, tr.t, tr.u_mps), grid)

    def mean_at(arr: np.ndarray) -> np.ndarray:
        cum = np.concatenate(([0.0], np.cumsum(0.5 * (arr[1:] + arr[:-1]) * np.diff(imu.t))))
        mid = np.interp(grid, imu.t, cum)
        out = np.gradient(mid, grid)
        return np.asarray(out)

    gyro = np.column_stack([mean_at(imu.gyro[:, k]) for k in range(3)])
    acc = np.column_stack([mean_at(imu.accel[:, k]) for k in range(3)])

    def corr(a: np.ndarray, b: np.ndarray) -> float:
        if np.std(a) == 0 or np.std(b) == 0:
            return 0.0
        return float(np.corrcoef(a, b)[0, 1])

    def score(axes: tuple[str, str, str]) -> float:
        m = axes_matrix(axes)
        g, a = gyro @ m.T, acc @ m.T
        up = float(np.clip(np.median(a[:, 2]) / 9.8, -1.0, 1.0))
        return corr(g[:, 2], yaw_rate) + corr(a[:, 0], fwd_acc) + up

    here = score(("x", "y", "z"))
    scores = {axes: score(axes) for axes in proper_axes()}
    best = max(scores, key=lambda k: scores[k])
    return {"score": here, "best_axes": list(best), "best_score": scores[best]}


def warn_mount(drive: Drive) -> None:
    chk = mount_check(drive)
    if chk is None:
        return
    drive.meta["mount_check"] = chk
    if chk["best_axes"] != ["x", "y", "z"] and chk["best_score"] > chk["score"] + 0.5:
        drive.warn(
            "mount_mismatch",
            1,
            f"{drive.source}: the IMU axes disagree with the truth (score {chk['score']:.2f} of "
            f"3); rotating them by {chk['best_axes']} fits it (score {chk['best_score']:.2f}): "
            "check imu_axes",
        )
