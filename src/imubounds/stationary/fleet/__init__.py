"""Fleet characterisation: the stationary pipeline over many logs on Dask (docs/fleet.md).

:func:`run_fleet` runs :func:`imubounds.stationary.pipeline.analyse_static` (the same
reading and settings as ``imubounds static``, out-of-core for large logs) on
every log of a fleet of units, on a ``dask.distributed`` cluster (a
``LocalCluster`` by default, or a running scheduler by address), and collects:

* ``DIR/fleet.parquet`` - one row per unit and channel: status, size, and the
  five IEEE 952 terms Q, N, B, K, R in SI from the fit and from the slope
  read-off, with their confidence intervals (columns ``N_fit``,
  ``N_fit_lo``, ``N_fit_hi``, ``N_slope``, ...; ``N``, ``N_lo``, ``N_hi`` are
  those of ``terms_from``). A unit that failed has one row with
  ``status="failed"`` and the error message.
* ``DIR/passfail.csv`` - with a datasheet spec (:func:`load_spec`), one row per
  unit, channel and term: value, limit, margin, pass.
* ``DIR/fleet.png`` / ``.svg`` - :func:`fleet_figure`.
* ``DIR/fleet.json`` - :meth:`FleetResult.summary` (for reports).

The package, one concern per module:

* :mod:`.settings` - :class:`FleetSettings`, how each unit is analysed;
* :mod:`.sources` - glob patterns and fsspec URLs to sources, unit names;
* :mod:`.cache` - content keys and the cache of finished units (``DIR/.cache``);
* :mod:`.plan` - units of work and tasks sized by input bytes;
* :mod:`.unit` - one unit (or a slice of its channels) through the static pipeline;
* :mod:`.execute` - the tasks run serially or on Dask, behind one interface;
* :mod:`.spec` - datasheet limits and the pass/fail table;
* :mod:`.result` - :class:`FleetResult` and ``fleet.json``;
* :mod:`.run` - :func:`run_fleet`, the driver.

The figures are drawn by :mod:`imubounds.report.fleet_plots`.
"""

from __future__ import annotations

from typing import Any

from imubounds.stationary.fleet.cache import (
    CACHE_ROWS,
    STRONG_VALIDATORS,
    content_key,
    remote_fingerprint,
)
from imubounds.stationary.fleet.execute import FLEET_WORKER_CONFIG, local_cluster
from imubounds.stationary.fleet.plan import plan_tasks, plan_work
from imubounds.stationary.fleet.result import FORMAT, FleetResult
from imubounds.stationary.fleet.run import run_fleet
from imubounds.stationary.fleet.settings import TERMS, FleetSettings, Progress
from imubounds.stationary.fleet.sources import (
    UNIT_SUFFIXES,
    expand_globs,
    is_url,
    source_size,
    unit_names,
)
from imubounds.stationary.fleet.spec import FleetSpec, check_spec, load_spec, parse_spec
from imubounds.stationary.fleet.unit import analyse_batch, analyse_unit, warm_up

__all__ = [
    "CACHE_ROWS",
    "FLEET_WORKER_CONFIG",
    "FORMAT",
    "STRONG_VALIDATORS",
    "TERMS",
    "UNIT_SUFFIXES",
    "FleetResult",
    "FleetSettings",
    "FleetSpec",
    "Progress",
    "analyse_batch",
    "analyse_unit",
    "check_spec",
    "content_key",
    "expand_globs",
    "fleet_figure",
    "fleet_stats_figure",
    "is_url",
    "load_spec",
    "local_cluster",
    "parse_spec",
    "plan_tasks",
    "plan_work",
    "remote_fingerprint",
    "run_fleet",
    "source_size",
    "unit_names",
    "warm_up",
]


def fleet_figure(result: FleetResult) -> Any:
    """:func:`imubounds.report.fleet_plots.fleet_figure` (the same as ``result.plot()``)."""
    from imubounds.report.fleet_plots import fleet_figure as figure

    return figure(result)


def fleet_stats_figure(result: FleetResult) -> Any:
    """:func:`imubounds.report.fleet_plots.fleet_stats_figure`."""
    from imubounds.report.fleet_plots import fleet_stats_figure as figure

    return figure(result)
