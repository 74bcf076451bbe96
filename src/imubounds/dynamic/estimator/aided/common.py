"""The IMU-side magnitude bounds shared by the true-signal constraints."""

from __future__ import annotations

from typing import Any

import numpy as np

from imubounds.dynamic.estimator.aided.base import up
from imubounds.dynamic.estimator.aided.forms import FormRecord
from imubounds.dynamic.estimator.aided.tilt import TiltSignals
from imubounds.dynamic.estimator.window_plan import LevelPlan
from imubounds.interval import IntervalArray as IA


class WindowContext:
    """What every true-signal constraint reads: the run's context (IMU, vehicle, aiding,
    tilt, noise budget), the per-window probability of the level being evaluated, whether
    the gyro_z's window-centred bound may be used (``fine_r``), and the caches of the
    quantities computed once per run (``cache``)."""

    def __init__(self, ctx: Any) -> None:
        self.ctx = ctx
        self.imu = ctx.imu
        self.veh = ctx.vehicle
        self.ag = ctx.aiding
        self.tilt: TiltSignals = ctx.tilt
        self.cache: dict[str, Any] = {}
        self.fine_r = True  # False once the gyro_z verdict is 'exceeds'
        self.p_window = 1e-6  # per-window probability of the current level
        #: roll/pitch at the ends of gyro_x's, gyro_y's, accel_z's windows (attitude
        #: states, ``attitude.consumers.ends_provider``); None: the attitude stream's
        self.ends: Any = None
        #: accel_x's and accel_y's kinematic parts per (channel, id(level)) from the
        #: attitude pass (``attitude.gravity``); the margins add the gravity term
        self.kin_cache: dict[tuple[str, int], IA] = {}
        self.forms = FormRecord()  # which forms gave each window's bound, per term

    def mag_mean(self, ch: str, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Upper bound of the mean of |true signal| of channel ``ch`` over ``[a, b]``
        (magnitude of the measured samples plus the per-sample error bound)."""
        if not self.imu.available[ch]:
            return np.full(np.shape(a), self.imu.sig[ch].xmax)
        ln = np.maximum(np.asarray(b) - np.asarray(a), 1e-300)
        cn = self.ctx.noise[ch]
        m = (self.imu.sig[ch].abs_integral(a, b) / ln + self.ctx.E0[ch]) / (1.0 - cn.scale)
        return np.minimum(up(m), self.imu.sig[ch].xmax)

    def kernel_mag(self, ch: str, lp: LevelPlan, tau: np.ndarray) -> np.ndarray:
        """Upper bound of the kernel mean of |true signal| (kernel <= 1/tau on its support)."""
        supp = lp.b2 - lp.a1
        return up(self.mag_mean(ch, lp.a1, lp.b2) * supp / tau)

    def imu_mean(self, ch: str, lp: LevelPlan, tau: np.ndarray) -> IA:
        """The IMU side ``[y_W]``: the kernel mean of the recorded samples."""
        return self.imu.sig[ch].kernel_mean(lp.a1, lp.b1, lp.a2, lp.b2, tau)

    def gyro_abs_mean(self, ch: str, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """:meth:`mag_mean` of a gyro capped by the vehicle's angular-rate bound."""
        return np.minimum(self.mag_mean(ch, a, b), self.veh.max_rate)
