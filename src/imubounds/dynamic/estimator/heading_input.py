"""The heading stream of mode full, through the one compass function
(:func:`imubounds.dynamic.aiding.compass.compass_heading`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imubounds.errors import AnalysisError, InputError
from imubounds.units import DEG


@dataclass
class HeadingInput:
    """A heading stream ready for intervals: compass heading (rad, clockwise from north)
    after deviation correction, with its deviation bound and noise sigma."""

    t: np.ndarray
    heading_rad: np.ndarray
    deviation_bound_rad: float
    noise_sigma_rad: float
    source: str
    deviation_source: str = ""
    noise_source: str = ""
    noise_gain: float = 1.0
    independent_of_gnss: bool = True
    independent_of_imu: bool = True
    notes: list[str] = field(default_factory=list)
    #: the signed check against the GNSS course (course_check.check_against_course)
    course_check: dict[str, Any] | None = None
    #: the compass error model estimated against the GNSS course
    #: (course_check.estimate_heading_model; HeadingModel.to_dict), None when not estimated
    model: dict[str, Any] | None = None


def heading_input(drive: Any, opts: dict[str, Any]) -> HeadingInput | None:
    """The heading source of a drive, through the one compass function
    :func:`imubounds.dynamic.aiding.compass.compass_heading` (calibration, declination
    and deviation bound from ``drive.yaml: heading``; ``--declination``,
    ``--heading-deviation`` and ``--heading-noise`` override).

    A heading that cannot be calibrated with the default settings (a magnetometer whose
    drive turns too little for an ellipse fit, say) leaves the drive without a heading
    sensor, with a note saying why; asked for explicitly (``heading.fit`` or
    ``heading.use`` in ``drive.yaml``) the error is the user's to see.
    """
    from imubounds.dynamic.aiding import compass as C

    att = drive.attitude
    ahrs_yaw = att is not None and getattr(att, "yaw_rad", None) is not None
    if drive.heading is None and drive.mag is None and not ahrs_yaw:
        return None
    st = drive.settings.heading
    cal = opts.get("compass_cal")
    if cal is not None:
        from imubounds.io.validate import check_input_path

        cal = str(check_input_path(cal, what="compass calibration", option="--compass-cal"))
    try:
        ch = C.compass_heading(
            drive,
            fit=opts.get("compass_fit"),
            calibration=cal,
            declination_deg=opts.get("declination_deg"),
            deviation_deg=opts.get("heading_deviation_deg"),
            alpha=float(opts.get("alpha") or 0.01),
        )
    except (InputError, AnalysisError) as exc:
        explicit = (
            cal is not None
            or opts.get("compass_fit") is not None
            or not {"heading.fit", "heading.use"} <= set(drive.settings.defaulted)
        )
        if explicit:
            raise
        return HeadingInput(
            t=np.zeros(0),
            heading_rad=np.zeros(0),
            deviation_bound_rad=0.0,
            noise_sigma_rad=0.0,
            source="none",
            notes=[f"heading sensor not used: {exc}"],
        )
    noise = opts.get("heading_noise_deg")
    noise_rad = float(noise) * DEG if noise is not None else float(ch.noise_sigma_rad)
    gain = 1.0
    for key in ("swing", "gnss_course"):
        cal = ch.detail.get(key)
        if isinstance(cal, dict) and "B_rad" in cal and "C_rad" in cal:
            # the correction is evaluated at the noisy reading
            gain = 1.0 + abs(float(cal["B_rad"])) + abs(float(cal["C_rad"]))
    model = ch.detail.get("heading_model")
    if isinstance(model, dict) and model.get("applied"):
        # the estimated correction is evaluated at the noisy reading too
        gain *= float(model["noise_gain"])
    dev_src = f"compass_heading() ({ch.calibration})"
    if opts.get("heading_deviation_deg") is not None:
        dev_src = "option"
    elif st.deviation_deg is not None:
        dev_src = "drive.yaml"
    return HeadingInput(
        t=np.asarray(ch.t, dtype=float),
        heading_rad=np.asarray(ch.heading_rad, dtype=float),
        deviation_bound_rad=float(ch.deviation_bound_rad),
        noise_sigma_rad=noise_rad,
        source=str(ch.source),
        deviation_source=dev_src,
        noise_source="option" if noise is not None else "compass_heading()",
        noise_gain=gain,
        independent_of_gnss=bool(ch.independent_of_gnss),
        independent_of_imu=bool(ch.independent_of_imu),
        notes=list(ch.notes) + list(ch.assumed),
        course_check=ch.detail.get("gnss_course_check"),
        model=model if isinstance(model, dict) else None,
    )
