"""What the per-step (``paper`` mode) estimator still needs from the simulator.

Until that estimator reads a :class:`~imubounds.io.drive.Drive`, it reads the
simulator's directory through :func:`imubounds.io.drive_readers.read_sim` and
takes its bounds from ``scenario.json: estimator`` (:func:`estimator_block`).
``truth_model="paper"``/``"full"`` make the (planar) truth follow that
estimator's discrete recursion exactly (METHOD.md 3.2), for its tests.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from imubounds.dynamic.scenario.config import ScenarioConfig

Array = np.ndarray


def discrete_truth(tru: dict[str, Array], mean: Array, mode: str, dt: float) -> None:
    """Replace the planar truth (in place) by the discrete recursion driven by the period
    means ``mean`` (n, 6); ``paper``: the accelerometer reads u' and v' = 0 (as printed),
    ``full``: the specific force with the transport terms."""
    n = mean.shape[0]
    a = mean[:, 0].copy()
    b = np.zeros(n) if mode == "paper" else mean[:, 1].copy()
    r = mean[:, 5].copy()
    u = np.zeros(n)
    v = np.zeros(n)
    psi = np.zeros(n)
    x = np.zeros(n)
    y = np.zeros(n)
    psi[0] = tru["yaw"][0]
    x[0], y[0] = tru["east"][0], tru["north"][0]
    for k in range(1, n):
        if mode == "paper":
            u[k] = u[k - 1] + a[k] * dt
            v[k] = v[k - 1] + b[k] * dt
        else:
            u[k] = u[k - 1] + (a[k] + r[k] * v[k - 1]) * dt
            v[k] = v[k - 1] + (b[k] - r[k] * u[k - 1]) * dt
        psi[k] = psi[k - 1] + r[k] * dt
        c, s = math.cos(psi[k]), math.sin(psi[k])
        x[k] = x[k - 1] + (u[k] * c - v[k] * s) * dt
        y[k] = y[k - 1] + (v[k] * c + u[k] * s) * dt
    tru.update(east=x, north=y, yaw=psi, speed=u, lateral=v)
    cs, sn = np.cos(psi), np.sin(psi)
    tru["vel_enu"] = np.column_stack([u * cs - v * sn, u * sn + v * cs, np.zeros(n)])
    mean[:, 0], mean[:, 1], mean[:, 5] = a, b, r


def model_error_bounds(truth: dict[str, Array], dt: float) -> dict[str, float]:
    """Bounds that make the per-step ``full``-mode discrete model hold for this truth at
    step ``dt``: ``nav_accel_bound`` A (m/s^2) and ``jerk_bound`` J (m/s^3) such that the
    per-step position residual is within A dt^2 / 2 and the velocity residual within
    J dt^2, measured on the truth with a 10 % margin.

    ``truth`` keys: east, north, u, v, psi (model heading) at the steps and accel_x,
    accel_y, r, the means over each step ending there.
    """
    x, y, u, v, psi = (truth[k] for k in ("east", "north", "u", "v", "psi"))
    a, b, r = truth["accel_x"], truth["accel_y"], truth["r"]
    c, s = np.cos(psi[1:]), np.sin(psi[1:])
    ex = np.diff(x) - (u[1:] * c - v[1:] * s) * dt
    ey = np.diff(y) - (v[1:] * c + u[1:] * s) * dt
    eu = np.diff(u) - (a[1:] + r[1:] * v[:-1]) * dt
    evv = np.diff(v) - (b[1:] - r[1:] * u[:-1]) * dt
    ep = float(max(np.max(np.abs(ex)), np.max(np.abs(ey))))
    ev = float(max(np.max(np.abs(eu)), np.max(np.abs(evv))))
    return {"nav_accel_bound": 1.1 * ep / (0.5 * dt * dt), "jerk_bound": 1.1 * ev / (dt * dt)}


def estimator_block(
    cfg: ScenarioConfig,
    tru: dict[str, Array],
    mean: Array,
    n_gnss: int,
    n_heading: int,
) -> dict[str, Any]:
    """``scenario.json: estimator``: the bounds the per-step estimator takes from a
    simulator directory (k at the whole-trip level of the record)."""
    from imubounds.dynamic.scenario.imu import k_level
    from imubounds.presets import get_preset

    step = 1.0  # the per-step estimator's default step
    per = max(1, int(round(step * cfg.rate_hz)))
    idx = np.arange(0, tru["t"].size, per)
    m = idx.size
    steps = {
        "east": tru["east"][idx],
        "north": tru["north"][idx],
        "u": tru["speed"][idx],
        "v": tru.get("lateral", np.zeros_like(tru["speed"]))[idx],
        "psi": tru["yaw"][idx],
    }
    for name, j in (("accel_x", 0), ("accel_y", 1), ("r", 5)):
        col = np.zeros(m)
        if per == 1:
            col[:] = mean[idx, j]
        else:
            blocks = mean[1 : 1 + (m - 1) * per, j].reshape(m - 1, per)
            col[1:] = blocks.mean(axis=1)
        steps[name] = col
    n = tru["t"].size
    noise_deg = cfg.compass_noise_deg
    return {
        "note": "for the per-step paper-mode estimator only; drive.yaml states the bounds",
        "imu_spec": {  # the datasheet figures, whether or not the bias was simulated
            kind: {
                "N": get_preset(cfg.imu_preset).kind(kind)["N"] * cfg.noise_scale,
                "B": get_preset(cfg.imu_preset).kind(kind)["B"] * cfg.noise_scale,
            }
            for kind in ("accel", "gyro")
        },
        "k_sigma": k_level(cfg.alpha, 6 * n),
        "t_avg_s": cfg.duration_s,
        "gps_cep_m": cfg.gps_cep_m,
        "gps_box": f"p={1.0 - cfg.alpha / max(n_gnss, 1)!r}",
        "compass_cal": "compass_cal.csv",
        "compass_mode": "corrected",
        "compass_floor_rad": k_level(cfg.alpha, max(n_heading, 1))
        * math.radians(noise_deg)
        * 1.001,
        "initial_speed_bound": 0.0,
        "mode": "full" if cfg.truth_model == "continuous" else cfg.truth_model,
        "model_error": model_error_bounds(steps, step),
    }
