"""gyro_z from the heading (docs/dynamic-method.md, section 3, **gyro_z**): the yaw rate's
kernel mean ``c0 (psi(b) - psi(a))/tau +- rate |c - c0| +- mean|q| tan(phi)``
(:func:`~imubounds.dynamic.estimator.aided.heading.r_from_psidot`), with the tilt
coupling's ``mean|q|`` from gyro_y's window means (:func:`~.form_tables.mean_abs_q`)."""

from __future__ import annotations

import numpy as np

from imubounds.dynamic.estimator.aided.common import WindowContext
from imubounds.dynamic.estimator.aided.form_tables import mean_abs_q
from imubounds.dynamic.estimator.aided.forms import share
from imubounds.dynamic.estimator.aided.heading import r_from_psidot
from imubounds.dynamic.estimator.window_plan import ChannelPlan, LevelPlan
from imubounds.interval import IntervalArray as IA


def gyro_z(w: WindowContext, plan: ChannelPlan, lp: LevelPlan, tau: np.ndarray) -> IA:
    """``[x_W]`` of gyro_z: the yaw rate from the heading at the window ends; the tilt
    coupling ``q tan(phi)`` with gyro_y's window mean of |q|
    (:func:`~.form_tables.mean_abs_q`) at its share of the window's probability (the
    band takes the rest, ``windows.MarginBuilder.evaluate``; :data:`~.forms.SHARES`
    ``["gyro_z.window"]``)."""
    ag = w.ag
    p1 = IA(ag.head_c[lp.i] - ag.head_h[lp.i], ag.head_c[lp.i] + ag.head_h[lp.i])
    p2 = IA(ag.head_c[lp.j] - ag.head_h[lp.j], ag.head_c[lp.j] + ag.head_h[lp.j])
    p_q = share("gyro_z.window", "mean_abs_q") * w.p_window
    q = mean_abs_q(w, lp, tau, p_q, term="gyro_z.mean_abs_q")
    return r_from_psidot(w, (p2 - p1) / IA(tau), lp, tau, own_q=True, q_mean=q)
