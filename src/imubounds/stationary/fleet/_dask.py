"""Dask side of :mod:`imubounds.stationary.fleet.execute`: a worker plugin that warms each worker.

Imported only when a fleet runs on Dask (``dask.distributed`` is the optional
``fleet`` extra). Every worker, including one that joins later (an adaptive
dask-jobqueue cluster), runs :func:`imubounds.stationary.fleet.unit.warm_up` once when
the plugin is registered or when it starts: imports, numba kernels loaded from
the on-disk cache (or compiled), the reader path exercised on a small log.
"""

from __future__ import annotations

from typing import Any

from distributed.diagnostics.plugin import WorkerPlugin

PLUGIN_NAME = "imubounds-fleet-warmup"


class FleetWarmup(WorkerPlugin):
    """Run :func:`~imubounds.stationary.fleet.unit.warm_up` on each worker at set-up."""

    name = PLUGIN_NAME

    def __init__(self, settings: Any = None) -> None:
        self.settings = settings
        self.seconds = 0.0

    def setup(self, worker: Any) -> None:
        from imubounds.stationary.fleet.unit import warm_up

        self.seconds = warm_up(self.settings)


def _has_plugin(dask_worker: Any) -> bool:
    return PLUGIN_NAME in getattr(dask_worker, "plugins", {})


def ensure_warm(client: Any, settings: Any = None) -> bool:
    """Register the warm-up plugin unless every worker has it; True if it was registered
    (the call returns when every current worker has run it)."""
    try:
        have = client.run(_has_plugin)
    except Exception:  # noqa: BLE001 - an old or restricted scheduler: just register
        have = {}
    if have and all(have.values()):
        return False
    client.register_plugin(FleetWarmup(settings), name=PLUGIN_NAME)
    return True
