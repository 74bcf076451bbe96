"""An attitude stream (AHRS, INS) as a sensor (docs/dynamic-method.md, section 3): its
roll/pitch samples with the stated error bound, or the vehicle's max tilt without one;
between samples the estimator widens them by the angular-rate bound
(:meth:`imubounds.dynamic.estimator.inputs.Aiding.tilt_range`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from imubounds.dynamic.estimator.budget import Term
from imubounds.units import DEG

if TYPE_CHECKING:
    from imubounds.dynamic.estimator.inputs import Aiding, Vehicle
    from imubounds.dynamic.estimator.options import FullOptions


def attitude_bounds(
    ag: Aiding, drive: Any, st: Any, vehicle: Vehicle, opts: FullOptions, t0: float
) -> None:
    """Roll/pitch intervals of an attitude stream, or the vehicle's max tilt."""
    att = drive.attitude
    if att is not None and opts.use_attitude:
        bd = opts.attitude_bound_deg
        ag.att_bound = float(bd if bd is not None else st.attitude.bound_deg) * DEG
        ag.att_t = np.asarray(att.t, dtype=float) - t0
        ag.att_roll = np.asarray(att.roll_rad, dtype=float)
        ag.att_pitch = np.asarray(att.pitch_rad, dtype=float)
        ag.att_source = att.source
        ok = np.isfinite(ag.att_roll) & np.isfinite(ag.att_pitch)
        ag.att_t, ag.att_roll, ag.att_pitch = ag.att_t[ok], ag.att_roll[ok], ag.att_pitch[ok]
        defaulted = bd is None and "attitude.bound_deg" in getattr(drive.settings, "defaulted", [])
        if defaulted:
            ag.notes.append(
                f"attitude stream ({att.source}): its roll/pitch error bound "
                f"{ag.att_bound / DEG:g} deg is the default (no figure given; state "
                "attitude.bound_deg in drive.yaml or --attitude-bound)"
            )
        ag.budget["attitude"] = [
            Term(
                "roll/pitch bound",
                ag.att_bound / DEG,
                "deg",
                "option" if bd is not None else "default" if defaulted else "drive.yaml",
                f"attitude stream ({att.source}) error; between samples widened by the "
                "angular-rate bound",
            )
        ]
        if att.source == "ahrs":
            ag.notes.append(
                "the attitude stream is an AHRS output computed from this IMU: the gravity "
                "terms of the accelerometer channels are then not independent of them"
            )
    else:
        ag.budget["attitude"] = [
            Term(
                "max tilt",
                vehicle.max_tilt / DEG,
                "deg",
                vehicle.sources.get("max_tilt", "default"),
                "no attitude stream: roll and pitch only bounded by the vehicle's max tilt",
            )
        ]
