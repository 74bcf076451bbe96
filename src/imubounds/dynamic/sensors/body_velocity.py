"""A body-velocity sensor (DVL, wheel/CAN speed, odometry) as intervals in the body frame
(docs/dynamic-method.md, section 3): its bound plus a scale-factor fraction of the speed.
Its clock offset against the IMU is :func:`imubounds.dynamic.sensors.clocks.estimate_velocity`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from imubounds.constants import ROUND_REL
from imubounds.dynamic.estimator.budget import Term, setting_source
from imubounds.interval.rounding import up as _up

if TYPE_CHECKING:
    from imubounds.dynamic.estimator.inputs import Aiding
    from imubounds.dynamic.estimator.options import FullOptions

#: body-velocity kinds measured at the wheels, and the scale-factor bound they get when
#: ``velocity.scale`` is not stated: the rolling radius of a road tyre varies by 1-3 %
#: with pressure, wear and load.
WHEEL_KINDS = ("wheel", "can", "odometry")
WHEEL_SCALE_DEFAULT = 0.03


def body_velocity_boxes(
    ag: Aiding, drive: Any, st: Any, opts: FullOptions, t0: float
) -> None:
    """Body-velocity intervals (DVL, wheel/CAN speed): bound + scale x speed."""
    vel_s = drive.velocity
    if vel_s is not None and opts.use_velocity:
        bound = float(opts.velocity_bound or st.velocity.bound_mps)
        scale = float(st.velocity.scale)
        scale_src = setting_source(st, "velocity.scale")
        if "velocity.scale" in drive.settings.defaulted and vel_s.kind in WHEEL_KINDS:
            # a wheel speed scales with the tyre's rolling radius (pressure, wear, load)
            scale = WHEEL_SCALE_DEFAULT
            scale_src = "default for a wheel speed"
            ag.notes.append(
                f"{vel_s.kind} speed: scale-factor error assumed within "
                f"{100 * WHEEL_SCALE_DEFAULT:g} % (tyre rolling radius; set velocity.scale)"
            )
        ag.bvel_t = np.asarray(vel_s.t, dtype=float) - t0
        ag.bvel_u = np.asarray(vel_s.u_mps, dtype=float)
        ag.bvel_v = None if vel_s.v_mps is None else np.asarray(vel_s.v_mps, dtype=float)
        ag.bvel_w = None if vel_s.w_mps is None else np.asarray(vel_s.w_mps, dtype=float)
        spd = np.abs(ag.bvel_u)
        if ag.bvel_v is not None:
            spd = np.hypot(spd, np.nan_to_num(ag.bvel_v))
        ag.bvel_h = _up((bound + scale * spd) * (1 + ROUND_REL))
        ag.bvel_kind = vel_s.kind
        ag.budget["velocity"] = [
            Term(
                "bound",
                bound,
                "m/s",
                setting_source(st, "velocity.bound_mps", bool(opts.velocity_bound)),
                f"{vel_s.kind} body-velocity error per component",
            ),
            Term("scale", scale, "fraction", scale_src, "plus this fraction of the speed"),
        ]
