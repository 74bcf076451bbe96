"""imubounds: how much to trust a MEMS IMU.

Stationary noise of a static log (Allan-variance family, IEEE 952 noise terms,
Gauss-Markov and AR models, stationary bounds) and guaranteed dynamic error
margins from a drive with aiding sensors (GNSS, compass, speed).

The curated API (everything in SI; every result has ``.to_dict()``,
``.to_frame()`` and, where there is something to draw, ``.plot(ax=None)``)::

    import imubounds as ib

    log = ib.read_log(ib.bundled_static_log())        # ImuLog
    curve = ib.allan(log.channels["gyro_z"], log.rate_hz, unit="rad/s")
    terms = ib.noise_terms(curve)                       # Selection (Q, N, B, K, R)
    static = ib.characterize(log)                       # StaticResult (= noise.json)

    drive = ib.read_drive(ib.bundled_drive_log())       # Drive
    dyn = ib.dynamic_margins(drive, imu_spec="vn100")   # DynamicResult (= dynamic.json)

Functions: :func:`read_log`, :func:`read_frame`, :func:`allan`,
:func:`noise_terms`, :func:`characterize`, :func:`read_drive`,
:func:`dynamic_margins`, :func:`simulate_trip`, :func:`export_noise`,
:func:`bundled_static_log`, :func:`bundled_drive_log`. Errors (all subclasses of
:class:`ValueError`):
:class:`ImuboundsError`, :class:`InputError`, :class:`UnitsError`,
:class:`OptionError`, :class:`AnalysisError`, :class:`OutputError`.

Importing the package is light and has no side effects: the names above are
imported on first use (PEP 562), no matplotlib backend is chosen, no file is
created or deleted and the umask is left alone. Only the command line
(``imubounds ...``) chooses a backend, refreshes numba caches and prints.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from imubounds.errors import (
    AnalysisError,
    ImuboundsError,
    InputError,
    OptionError,
    OutputError,
    UnitsError,
)
from imubounds.version import __version__ as __version__

#: Public name -> module that defines it (imported on first access).
_LAZY: dict[str, str] = {
    # functions
    "read_log": "imubounds.api",
    "read_frame": "imubounds.io.table",
    "allan": "imubounds.api",
    "noise_terms": "imubounds.api",
    "characterize": "imubounds.api",
    "export_noise": "imubounds.api",
    "simulate_trip": "imubounds.api",
    "read_drive": "imubounds.io.drive.readers",
    "bundled_drive_log": "imubounds.io.drive.readers",
    "bundled_static_log": "imubounds.io.registry",
    "dynamic_margins": "imubounds.dynamic.estimator.api",
    # result and data classes
    "ImuLog": "imubounds.io.log",
    "AllanResult": "imubounds.stationary.allan",
    "NoiseTerms": "imubounds.stationary.terms",
    "Selection": "imubounds.stationary.terms",
    "SelectedTerm": "imubounds.stationary.terms",
    "StaticResult": "imubounds.stationary.pipeline",
    "StaticSettings": "imubounds.stationary.pipeline",
    "ChannelResult": "imubounds.stationary.pipeline",
    "Drive": "imubounds.io.drive",
    "DriveSettings": "imubounds.io.drive",
    "DynamicResult": "imubounds.dynamic.estimator.result",
    "SimResult": "imubounds.dynamic.scenario",
}

__all__ = [
    "AllanResult",
    "AnalysisError",
    "ChannelResult",
    "Drive",
    "DriveSettings",
    "DynamicResult",
    "ImuLog",
    "ImuboundsError",
    "InputError",
    "NoiseTerms",
    "OptionError",
    "OutputError",
    "SelectedTerm",
    "Selection",
    "SimResult",
    "StaticResult",
    "StaticSettings",
    "UnitsError",
    "__version__",
    "allan",
    "bundled_drive_log",
    "bundled_static_log",
    "characterize",
    "dynamic_margins",
    "export_noise",
    "noise_terms",
    "read_drive",
    "read_frame",
    "read_log",
    "simulate_trip",
]

if TYPE_CHECKING:
    from imubounds.api import (
        allan,
        characterize,
        export_noise,
        noise_terms,
        read_log,
        simulate_trip,
    )
    from imubounds.dynamic.estimator.api import dynamic_margins
    from imubounds.dynamic.estimator.result import DynamicResult
    from imubounds.dynamic.scenario import SimResult
    from imubounds.io.drive import Drive, DriveSettings
    from imubounds.io.drive.readers import bundled_drive_log, read_drive
    from imubounds.io.log import ImuLog
    from imubounds.io.registry import bundled_static_log
    from imubounds.io.table import read_frame
    from imubounds.stationary.allan import AllanResult
    from imubounds.stationary.pipeline import ChannelResult, StaticResult, StaticSettings
    from imubounds.stationary.terms import NoiseTerms, SelectedTerm, Selection


def __getattr__(name: str) -> Any:
    """Import a public name on first use (PEP 562)."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'imubounds' has no attribute {name!r}")
    value = getattr(import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
