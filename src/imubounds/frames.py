"""Frames, axes and heading conventions: the one place where they are written down.

Conventions used everywhere inside imubounds (METHOD.md 3.2 and 4.3):

* **Body frame FLU**: x forward, y left, z up. Readers convert the sensor's own
  axes (often FRD: x forward, y right, z down) into FLU before anything else.
* **Navigation frame ENU**: local East-North-Up at the first fix.
* **Model heading** ``psi``: counter-clockwise from east (rad), the yaw of the
  body x axis in ENU. **Compass heading** ``psi_c``: clockwise from north
  (rad), what a compass, a GNSS course or an AHRS yaw prints;
  ``psi = pi/2 - psi_c``.
* **Yaw rate** ``r`` = gyro z in FLU, positive turning left (counter-clockwise
  seen from above), so ``r = d(psi)/dt = -d(psi_c)/dt``.
* **Roll** ``phi`` positive right side down, **pitch** ``theta`` positive nose
  up (the convention most AHRS print).
"""

from __future__ import annotations

import math

import numpy as np

TWO_PI = 2.0 * math.pi

#: Sign flips that take FRD axes (x forward, y right, z down) to FLU (x forward, y left, z up).
FRD_TO_FLU = np.array([1.0, -1.0, -1.0])


def frd_to_flu(a: np.ndarray) -> np.ndarray:
    """Vectors (..., 3) in FRD axes -> FLU axes (y and z negated)."""
    return np.asarray(a, dtype=float) * FRD_TO_FLU


def wrap_pi(angle: np.ndarray | float) -> np.ndarray | float:
    """Wrap angles (rad) to [-pi, pi)."""
    return (np.asarray(angle) + math.pi) % TWO_PI - math.pi


def compass_to_model(psi_c: np.ndarray | float) -> np.ndarray | float:
    """Compass heading (rad, clockwise from north) -> model heading (rad, CCW from east)."""
    return wrap_pi(0.5 * math.pi - np.asarray(psi_c))


def model_to_compass(psi: np.ndarray | float) -> np.ndarray | float:
    """Model heading (rad, CCW from east) -> compass heading in [0, 2pi) (clockwise from north)."""
    return (0.5 * math.pi - np.asarray(psi)) % TWO_PI


def quaternion_yaw_enu(x: np.ndarray, y: np.ndarray, z: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Yaw (rad, counter-clockwise from east) of ENU orientation quaternions (x, y, z, w)."""
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def enu_yaw_to_heading(yaw: np.ndarray) -> np.ndarray:
    """ENU yaw (CCW from east, rad) -> compass heading (clockwise from north, rad, in [0, 2pi))."""
    h = np.mod(0.5 * math.pi - np.asarray(yaw, dtype=float), TWO_PI)
    return np.where(h >= TWO_PI, 0.0, h)  # mod of -tiny is 2*pi
