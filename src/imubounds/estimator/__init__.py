"""The interval INS/GPS/compass estimator of dynamic error margins (METHOD.md 3)."""

from pathlib import Path

from imubounds import _numba_cache

# The compiled loop inlines the imubounds.interval rules: an edit there must
# invalidate this package's numba cache too.
_HERE = Path(__file__).resolve().parent
_numba_cache.refresh(_HERE, [_HERE.parent / "interval"])

from imubounds.estimator.core import (  # noqa: E402
    CHANNELS,
    EstimatorConfig,
    EstimatorResult,
    ImuSpec,
    StepData,
    config_dict,
    config_for_log,
    prepare_steps,
    run,
    scenario_model_error,
    summarize,
)

__all__ = [
    "CHANNELS",
    "EstimatorConfig",
    "EstimatorResult",
    "ImuSpec",
    "StepData",
    "config_dict",
    "config_for_log",
    "scenario_model_error",
    "prepare_steps",
    "run",
    "summarize",
]
