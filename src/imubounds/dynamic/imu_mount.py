"""Is the IMU mounted with its axes on the body axes? (docs/drive-layout.md, "The mount: imu_axes")

Over a drive (or at rest) the mean specific force is gravity, pointing along body +z (x
forward, y left, z up), plus the mean acceleration, small against g for a vehicle that
ends near its start speed. A mean that points more than :data:`MAX_ANGLE_DEG` away
from body +z means that the IMU's axes (after the drive's ``imu_axes``) are not the body
axes: :func:`mount_warning` says so and names the ``imu_axes`` that puts gravity on body
+z (keeping the forward axis where it can: gravity does not show which way is forward).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from imubounds.frames import axes_matrix

#: a mean specific force farther than this from body +z is a rotated mount
MAX_ANGLE_DEG = 30.0
#: the mean is judged only when its magnitude is gravity's to within these bounds (m/s^2)
G_RANGE = (7.0, 12.5)
_NAMES = ("x", "y", "z")


def _axis_name(row: np.ndarray) -> str:
    j = int(np.flatnonzero(row)[0])
    return ("-" if row[j] < 0 else "") + _NAMES[j]


def fitting_axes(mean_body: np.ndarray, imu_axes: tuple[str, ...]) -> tuple[str, str, str]:
    """The ``imu_axes`` that puts the mean specific force ``mean_body`` (in the body frame
    of the current ``imu_axes``) on body +z: body z = the axis nearest the mean, body x =
    the current body x unless that is the vertical (then the current body y)."""
    r = axes_matrix(imu_axes)  # body <- sensor
    k = int(np.argmax(np.abs(mean_body)))
    z_s = np.sign(mean_body[k]) * r[k]  # new body z in sensor axes
    x_s = r[0] if k != 0 else r[1]
    y_s = np.cross(z_s, x_s)
    return _axis_name(x_s), _axis_name(y_s), _axis_name(z_s)


def mean_specific_force(drive: Any) -> np.ndarray | None:
    """Mean accelerometer vector (m/s^2, body axes of the drive) over its finite samples."""
    imu = getattr(drive, "imu", None)
    if imu is None or getattr(imu, "accel", None) is None:
        return None
    a = np.asarray(imu.accel, dtype=float)
    if a.ndim != 2 or a.shape[1] != 3:
        return None
    ok = np.all(np.isfinite(a), axis=1)
    if not np.any(ok):
        return None
    return np.asarray(np.mean(a[ok], axis=0), dtype=float)


def mount_warning(drive: Any) -> str | None:
    """A warning naming the fitting ``imu_axes`` when gravity is not on body +z; None
    when the mount looks right or the mean is not gravity's size (nothing to judge)."""
    m = mean_specific_force(drive)
    if m is None:
        return None
    g = float(np.linalg.norm(m))
    if not G_RANGE[0] <= g <= G_RANGE[1]:
        return None
    angle = math.degrees(math.acos(max(-1.0, min(1.0, float(m[2]) / g))))
    if angle <= MAX_ANGLE_DEG:
        return None
    settings = getattr(drive, "settings", None)
    current = tuple(getattr(settings, "imu_axes", ("x", "y", "z")))
    fit = fitting_axes(m, current)
    k = int(np.argmax(np.abs(m)))
    along = ("-" if m[k] < 0 else "+") + _NAMES[k]
    forward = (
        "kept" if k != 0 else "taken from body y: gravity cannot show which way is forward"
    )
    return (
        f"{drive.source}: the mean specific force ({g:.2f} m/s^2) points along body {along}, "
        f"{angle:.0f} deg from up: the IMU's axes are not the body axes (x forward, y left, "
        f"z up) with imu_axes [{', '.join(current)}]; imu_axes [{', '.join(fit)}] puts "
        f"gravity on body +z (forward axis {forward}; check it): set it in drive.yaml or "
        "with --imu-axes"
    )
