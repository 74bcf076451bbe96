"""The interval INS/GPS/compass estimator of dynamic error margins (METHOD.md 3)."""

from imubounds.dynamic.estimator.core import (
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
