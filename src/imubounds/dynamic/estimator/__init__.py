"""Dynamic error margins of an IMU from a drive (METHOD.md 3-4, docs/dynamic-method.md).

* :func:`dynamic_margins` -- the entry point (modes ``full`` and ``paper``), returning a
  :class:`DynamicResult`;
* :mod:`.budget` -- the error budget (noise terms, alpha plan, kernel variances);
* :mod:`.inputs` -- the IMU as integrable sample series, the aiding sensors as intervals;
* :mod:`.windows` -- window-mean margins per averaging time and the verdicts;
* :mod:`.smoother` -- the whole-trip interval smoother (numba) and its reference
  ``tests/smoother_reference.py``;
* :mod:`.full` -- mode ``full`` put together;
* :mod:`.paper`, :mod:`.paper_kernel` -- mode ``paper``, the
  paper's per-step estimator (not guaranteed).
"""

from imubounds.dynamic.estimator.api import MODES, dynamic_margins
from imubounds.dynamic.estimator.budget import CHANNELS, read_noise_json
from imubounds.dynamic.estimator.result import SCHEMA_VERSION, DynamicResult

__all__ = [
    "CHANNELS",
    "MODES",
    "SCHEMA_VERSION",
    "DynamicResult",
    "dynamic_margins",
    "read_noise_json",
]
