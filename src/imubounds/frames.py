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


# ----------------------------------------------------------------------------- mounts
_AXIS_INDEX = {"x": 0, "y": 1, "z": 2}


def axes_matrix(imu_axes: tuple[str, ...] | list[str]) -> np.ndarray:
    """The 3x3 signed permutation R taking sensor axes to body axes, ``v_body = R @ v_sensor``.

    ``imu_axes[i]`` names the signed sensor axis that points along body axis i
    (x forward, y left, z up): ``["x", "-z", "y"]`` means body x = sensor x,
    body y = -sensor z, body z = sensor y (a unit on its side with gravity on
    +y). The result must be a proper rotation (each axis once, right-handed);
    anything else is an :class:`imubounds.errors.InputError` naming the entry.
    """
    from imubounds.errors import InputError

    if len(imu_axes) != 3:
        raise InputError(f"imu_axes must name 3 axes, e.g. [x, -z, y]; got {list(imu_axes)}")
    m = np.zeros((3, 3))
    for i, a in enumerate(imu_axes):
        text = str(a).strip().lower()
        sign = -1.0 if text.startswith("-") else 1.0
        name = text.lstrip("+-")
        if name not in _AXIS_INDEX:
            raise InputError(f"imu_axes entry {a!r}: use x, y, z with an optional sign")
        m[i, _AXIS_INDEX[name]] = sign
    if not np.allclose(m @ m.T, np.eye(3)) or not math.isclose(np.linalg.det(m), 1.0):
        raise InputError(
            f"imu_axes {list(imu_axes)} is not a rotation (each IMU axis once, right-handed)"
        )
    return m


def rotate_axes(v: np.ndarray, r_body_sensor: np.ndarray) -> np.ndarray:
    """Sensor-axis vectors (n, 3) -> body axes for a signed permutation from
    :func:`axes_matrix`, by indexing (no products, so one infinite or NaN component stays
    in its own axis instead of spreading to the others)."""
    v = np.asarray(v, dtype=float)
    m = np.asarray(r_body_sensor, dtype=float)
    out = np.empty_like(v)
    for i in range(3):
        j = int(np.flatnonzero(m[i])[0])
        out[:, i] = m[i, j] * v[:, j]
    return out


def is_identity_axes(imu_axes: tuple[str, ...] | list[str]) -> bool:
    """True if ``imu_axes`` maps every sensor axis onto the same body axis."""
    return bool(np.array_equal(axes_matrix(imu_axes), np.eye(3)))


# ----------------------------------------------------------------------------- attitude
# Body FLU -> ENU rotation of an attitude (roll phi right side down +, pitch theta nose
# up +, compass yaw psi_c clockwise from north): C_nb = Rz(pi/2 - psi_c) Ry(-theta) Rx(phi).


def rpy_to_matrix(roll: np.ndarray, pitch: np.ndarray, yaw_c: np.ndarray) -> np.ndarray:
    """Attitudes (rad; roll right side down +, pitch nose up +, yaw clockwise from north)
    -> body (FLU) to ENU rotation matrices, shape (n, 3, 3)."""
    phi = np.atleast_1d(np.asarray(roll, dtype=float))
    th = np.atleast_1d(np.asarray(pitch, dtype=float))
    psi = 0.5 * math.pi - np.atleast_1d(np.asarray(yaw_c, dtype=float))
    cf, sf = np.cos(phi), np.sin(phi)
    ct, st = np.cos(th), np.sin(th)
    cp, sp = np.cos(psi), np.sin(psi)
    m = np.empty((phi.size, 3, 3))
    # Rz(psi) @ Ry(-theta) @ Rx(phi)
    m[:, 0, 0] = cp * ct
    m[:, 0, 1] = -cp * st * sf - sp * cf
    m[:, 0, 2] = -cp * st * cf + sp * sf
    m[:, 1, 0] = sp * ct
    m[:, 1, 1] = -sp * st * sf + cp * cf
    m[:, 1, 2] = -sp * st * cf - cp * sf
    m[:, 2, 0] = st
    m[:, 2, 1] = ct * sf
    m[:, 2, 2] = ct * cf
    return m


def matrix_to_rpy(m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body (FLU) to ENU rotation matrices (n, 3, 3) -> roll, pitch (rad) and compass yaw
    (rad, clockwise from north, in [0, 2 pi))."""
    m = np.asarray(m, dtype=float).reshape(-1, 3, 3)
    pitch = np.arcsin(np.clip(m[:, 2, 0], -1.0, 1.0))
    roll = np.arctan2(m[:, 2, 1], m[:, 2, 2])
    yaw = enu_yaw_to_heading(np.arctan2(m[:, 1, 0], m[:, 0, 0]))
    return roll, pitch, yaw


def quaternion_to_rpy(q_wxyz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body (FLU) -> ENU quaternions (n, 4) as (w, x, y, z) -> roll, pitch, compass yaw (rad)."""
    q = np.asarray(q_wxyz, dtype=float).reshape(-1, 4)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    m = np.empty((q.shape[0], 3, 3))
    m[:, 0, 0] = 1 - 2 * (y * y + z * z)
    m[:, 0, 1] = 2 * (x * y - w * z)
    m[:, 0, 2] = 2 * (x * z + w * y)
    m[:, 1, 0] = 2 * (x * y + w * z)
    m[:, 1, 1] = 1 - 2 * (x * x + z * z)
    m[:, 1, 2] = 2 * (y * z - w * x)
    m[:, 2, 0] = 2 * (x * z - w * y)
    m[:, 2, 1] = 2 * (y * z + w * x)
    m[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return matrix_to_rpy(m)


def ned_quaternion_to_rpy(q_wxyz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body (FRD) -> NED quaternions (PX4, VectorNav) as (w, x, y, z) -> roll (right side
    down +), pitch (nose up +) and compass yaw (clockwise from north, [0, 2 pi)), rad.

    The aerospace Euler angles of an FRD/NED attitude are already in the
    convention above, so no frame change is needed beyond reading them off.
    """
    q = np.asarray(q_wxyz, dtype=float).reshape(-1, 4)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = np.mod(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)), TWO_PI)
    return roll, pitch, np.where(yaw >= TWO_PI, 0.0, yaw)


def level_vectors(v: np.ndarray, roll: np.ndarray, pitch: np.ndarray) -> np.ndarray:
    """Body (FLU) vectors (n, 3) -> the level frame of the same heading: x forward and y
    left in the horizontal plane, z up (tilt compensation of a magnetometer)."""
    v = np.asarray(v, dtype=float)
    phi = np.asarray(roll, dtype=float)
    th = np.asarray(pitch, dtype=float)
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    # Rx(phi), then Ry(-theta)
    y1 = np.cos(phi) * y - np.sin(phi) * z
    z1 = np.sin(phi) * y + np.cos(phi) * z
    x2 = np.cos(th) * x - np.sin(th) * z1
    z2 = np.sin(th) * x + np.cos(th) * z1
    return np.column_stack([x2, y1, z2])


def mount_attitude(
    roll: np.ndarray, pitch: np.ndarray, yaw_c: np.ndarray | None, r_body_sensor: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Attitude of a sensor's own axes -> attitude of the vehicle body, for the mount
    ``v_body = R @ v_sensor`` (see :func:`axes_matrix`). Without a yaw the sensor yaw
    is taken as 0 and no body yaw is returned."""
    y = np.zeros_like(np.asarray(roll, dtype=float)) if yaw_c is None else yaw_c
    c_ns = rpy_to_matrix(roll, pitch, y)
    r, p, yy = matrix_to_rpy(c_ns @ np.asarray(r_body_sensor, dtype=float).T)
    return r, p, (None if yaw_c is None else yy)
