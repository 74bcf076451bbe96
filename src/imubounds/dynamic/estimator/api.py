"""The Python API of the dynamic analysis: :func:`dynamic_margins`."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from imubounds.dynamic.estimator.result import DynamicResult
from imubounds.errors import InputError, OptionError

if TYPE_CHECKING:
    from imubounds.dynamic.estimator.options import FullOptions
    from imubounds.io.drive import Drive
    from imubounds.stationary.pipeline import StaticResult

MODES = ("full", "paper")


def dynamic_margins(
    drive: Drive,
    *,
    noise: str | Path | dict[str, Any] | StaticResult | None = None,
    mode: str = "full",
    options: FullOptions | None = None,
    progress: Callable[[str, int, int], None] | None = None,
    **kwargs: Any,
) -> DynamicResult:
    """Dynamic error margins of a drive's IMU.

    Parameters
    ----------
    drive:
        A :class:`imubounds.io.drive.Drive` (IMU plus any aiding sensors, SI units).
    noise:
        The IMU's noise: a ``noise.json`` of ``imubounds static`` (path or loaded
        dict) or the :class:`~imubounds.stationary.pipeline.StaticResult` of
        :func:`imubounds.characterize`; when None, ``drive.settings.imu`` (drive.yaml),
        the ``imu_spec`` option, or the MTx preset.
    mode:
        ``"full"`` (default): guaranteed window-mean margins per averaging time with
        verdicts, and the whole-trip interval smoother (docs/dynamic-method.md).
        ``"paper"``: the paper's per-step estimator (not guaranteed).
    options:
        The options of mode ``full`` as a
        :class:`~imubounds.dynamic.estimator.options.FullOptions` (the command line builds
        one); not with keyword options.
    **kwargs:
        Mode options as keywords (SI unless named otherwise): for ``full`` the fields of
        :class:`~imubounds.dynamic.estimator.options.FullOptions` (``alpha``,
        ``imu_spec``, ``max_tilt_deg``, ``lateral_speed_bound_mps``, ...), checked here
        (:func:`~imubounds.dynamic.estimator.options.check_options`); for ``paper`` see
        :class:`imubounds.dynamic.estimator.paper.PaperConfig`.
    progress:
        Called as ``progress(stage, done, total)`` while mode full advances (its windows
        channel by channel, then the smoother); the library never prints.

    Returns
    -------
    DynamicResult
        ``.to_dict()`` (the dynamic.json block of the mode), ``.to_frame()`` (margins
        table), ``.plot(ax=None)`` (margins vs tau).
    """
    from imubounds.interval.rounding import nearest
    from imubounds.io.drive import Drive as _Drive
    from imubounds.stationary.pipeline import StaticResult as _StaticResult

    if mode not in MODES:
        raise OptionError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
    if not isinstance(drive, _Drive):
        raise InputError(
            "dynamic_margins takes a Drive (from imubounds.read_drive or simulate_trip(...)"
            f".drive), got {type(drive).__name__}"
        )
    if isinstance(noise, _StaticResult):
        noise = noise.to_dict()
    if options is not None and (kwargs or mode != "full"):
        raise OptionError(
            "options= (a FullOptions) is for mode full, without keyword options; got "
            f"mode {mode!r} and {', '.join(sorted(kwargs)) or 'no keywords'}"
        )
    spec = options.imu_spec if options is not None else kwargs.get("imu_spec")
    if spec is not None and (not isinstance(spec, str) or not spec.strip()):
        raise OptionError(
            f"imu_spec must be a preset name or 'accel_nd=..,accel_bs=..,gyro_nd=..,"
            f"gyro_bs=..', got {spec!r}"
        )
    if noise is not None and not isinstance(noise, str | Path | dict):
        raise OptionError(
            "noise must be a noise.json path, its loaded dict or imubounds.characterize's "
            f"StaticResult, got {type(noise).__name__} {noise!r:.40}"
        )
    drive.check()
    with nearest():
        if mode == "full":
            from imubounds.dynamic.estimator.full import run_full
            from imubounds.dynamic.estimator.result import full_summary

            # the keywords are checked into a FullOptions by build_context (check_options)
            run = run_full(drive, noise, options if options is not None else kwargs,
                           progress=progress)
            return DynamicResult("full", full_summary(run, drive), full=run)
        from imubounds.dynamic.estimator.paper import run_paper

        paper: DynamicResult = run_paper(drive, noise, **kwargs)
        return paper
