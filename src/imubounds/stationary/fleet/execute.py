"""Running a fleet's tasks: in this process or on a ``dask.distributed`` cluster, behind
one interface (:class:`Executor`: ``run(tasks, collect)``).

:func:`open_executor` gives a :class:`SerialExecutor` (the units one after the other in
this process) or a :class:`DaskExecutor` on a client: the caller's, one of a running
scheduler by address, or of a new local cluster (:func:`local_cluster`, closed after).
Each Dask worker is warmed once (imports, numba kernels) by a worker plugin
(:mod:`imubounds.stationary.fleet._dask`); local clusters share the cores among the
workers' Allan kernels and start workers without Dask's ``MALLOC_TRIM_THRESHOLD_``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from typing import Any, Protocol

from imubounds.errors import OptionError
from imubounds.stationary.fleet.settings import FleetSettings
from imubounds.stationary.fleet.unit import analyse_batch, failed_result

__all__ = [
    "FLEET_WORKER_CONFIG",
    "DaskExecutor",
    "Executor",
    "SerialExecutor",
    "check_scheduler_address",
    "local_cluster",
    "open_client",
    "open_executor",
]

#: A work item: (unit index, part index); its arguments: (source, unit name, channel part).
Item = tuple[int, int]
ItemArgs = tuple[str, str, tuple[int, int] | None]
#: A task: its work items and their arguments (one :func:`analyse_batch` call).
Task = tuple[list[Item], list[ItemArgs]]
#: ``collect(items, results)``: called as each task's results arrive.
Collect = Callable[[list[Item], list[dict[str, Any]]], None]


class Executor(Protocol):
    """Runs a fleet's tasks and hands each task's unit results to ``collect``."""

    #: Where the tasks ran, as the result shows it (the scheduler's address, ...).
    name: str
    #: Worker threads the tasks are planned for.
    workers: int

    def run(self, tasks: Iterable[Task], collect: Collect) -> int:
        """Run every task (``tasks`` may be lazy: it is read as tasks are submitted);
        returns the number of tasks run."""
        ...


class SerialExecutor:
    """The tasks one after the other in this process, without Dask."""

    def __init__(self, settings: FleetSettings, numba_threads: int | None, name: str) -> None:
        self.settings = settings
        self.numba_threads = numba_threads
        self.name = name
        self.workers = 1

    def run(self, tasks: Iterable[Task], collect: Collect) -> int:
        n = 0
        for items, args in tasks:
            n += 1
            collect(items, analyse_batch(args, self.settings, self.numba_threads))
        return n


class DaskExecutor:
    """The tasks on the workers of a ``dask.distributed`` client, each worker warmed once;
    a task whose worker died gives failed units (the others go on)."""

    def __init__(
        self, client: Any, settings: FleetSettings, numba_threads: int | None, n_workers: int
    ) -> None:
        from imubounds.stationary.fleet._dask import ensure_warm

        ensure_warm(client, settings)
        self.client = client
        self.settings = settings
        self.name = str(client.scheduler.address)
        info = list(client.scheduler_info().get("workers", {}).values())
        self.workers = sum(int(w.get("nthreads", 1)) for w in info) or max(1, n_workers)
        self.numba_threads = kernel_threads(info) if numba_threads is None else numba_threads

    def run(self, tasks: Iterable[Task], collect: Collect) -> int:
        from dask.distributed import as_completed

        futures: dict[Any, Task] = {}
        running = as_completed()

        def finish(fut: Any) -> None:
            items, args = futures.pop(fut)
            try:
                batch = fut.result()
            except Exception as err:  # noqa: BLE001 - worker died; report, go on
                batch = [failed_result(src, unit, f"task failed: {err}")
                         for src, unit, _ in args]  # fmt: skip
            collect(items, batch)

        n = 0
        for items, args in tasks:
            fut = self.client.submit(analyse_batch, args, self.settings, self.numba_threads,
                                     pure=False)  # fmt: skip
            futures[fut] = (items, args)
            running.add(fut)
            n += 1
            while running.has_ready():
                finish(next(running))
        for fut in running:
            finish(fut)
        return n


@contextmanager
def open_executor(
    settings: FleetSettings,
    *,
    serial: bool,
    lone: bool = False,
    client: Any = None,
    scheduler: str | None = None,
    n_workers: int = 2,
    threads_per_worker: int = 1,
    numba_threads: int | None = None,
) -> Iterator[Executor]:
    """The executor of a run: serial in this process (``lone``: because only one unit is
    to be analysed), or Dask on ``client``, on the scheduler at ``scheduler`` or on a new
    local cluster of ``n_workers`` x ``threads_per_worker`` (closed on exit)."""
    if serial:
        name = "this process (one unit to analyse)" if lone else "serial (this process)"
        yield SerialExecutor(settings, numba_threads, name)
        return
    with ExitStack() as stack:
        client = client or stack.enter_context(
            open_client(scheduler, n_workers, threads_per_worker)
        )
        yield DaskExecutor(client, settings, numba_threads, n_workers)


#: Schemes of a Dask scheduler's address (``tcp://host:port`` is the usual one).
_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")


def check_scheduler_address(address: str) -> None:
    """Refuse an address no Dask scheduler has, before any work (Dask itself says only
    "missing port number"): ``[scheme://]host:port`` with a scheme of :data:`_SCHEMES`,
    or ``inproc://...``.

    Raises
    ------
    OptionError
        Naming the option and the expected form.
    """
    scheme, sep, loc = address.partition("://")
    if not sep:
        scheme, loc = "tcp", address
    if scheme == "inproc" and loc:
        return
    host, colon, port = loc.rpartition(":")
    if (scheme in _SCHEMES and colon and host.strip("[]") and "/" not in loc
            and port.isdigit() and 0 < int(port) < 65536):  # fmt: skip
        return
    raise OptionError(
        f"--scheduler {address!r} is not a Dask scheduler address; give it as "
        "tcp://host:port (as 'dask scheduler' prints it), or omit --scheduler for a local "
        "cluster"
    )


def kernel_threads(workers: Sequence[Mapping[str, Any]]) -> int:
    """Threads for the Allan kernels in each task: the cores of this machine shared among
    the worker threads when every worker runs here (a local cluster), else 1."""
    import os
    import socket

    hosts = {str(w.get("host", "")) for w in workers}
    local = {"127.0.0.1", "localhost", "::1", socket.gethostname()}
    if workers and hosts <= local:
        threads = sum(int(w.get("nthreads", 1)) for w in workers)
        return max(1, (os.cpu_count() or 1) // max(1, threads))
    return 1


@contextmanager
def open_client(scheduler: str | None, n_workers: int, threads_per_worker: int) -> Iterator[Any]:
    """A client of the scheduler at ``scheduler``, or of a new local cluster (closed after)."""
    from dask.distributed import Client

    if scheduler:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError, ValueError) as err:
            raise OptionError(
                f"cannot connect to the Dask scheduler at {scheduler!r} ({err}); "
                "check the address or omit --scheduler for a local cluster"
            ) from err
        with client:
            yield client
        return
    with local_cluster(n_workers, threads_per_worker) as cluster, Client(cluster) as client:
        yield client


#: Dask's nanny sets MALLOC_TRIM_THRESHOLD_=65536 in workers (to return memory to the
#: system early). Setting it makes glibc keep its mmap threshold at 128 KiB, so every
#: array of a unit is mapped and zero-filled afresh: measured 30x the page faults and
#: about 25 % more CPU per unit than the same analysis in a plain process. The
#: fleet's workers get :data:`imubounds.runtime.MALLOC_SETTINGS` instead.
_DASK_TRIM = ("MALLOC_TRIM_THRESHOLD_", "65536")

#: Worker settings of a fleet's local cluster: no statistical profiler (it samples
#: the task thread's stack every 10 ms under the GIL) and slower housekeeping ticks
#: (the event loop woke about 10 000 times a second, each time taking the GIL from
#: the analysis). A fleet task is seconds long; these only feed the dashboard.
FLEET_WORKER_CONFIG: dict[str, Any] = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "1s",
}


def local_cluster(
    n_workers: int = 2, threads_per_worker: int = 1, *, pin: bool = True, **kwargs: Any
) -> Any:
    """A ``dask.distributed.LocalCluster`` of worker processes set up for fleets.

    As ``LocalCluster(n_workers, threads_per_worker, processes=True)`` but with
    glibc malloc settings that keep freed memory for reuse
    (:data:`imubounds.runtime.MALLOC_SETTINGS`, instead of Dask's
    ``MALLOC_TRIM_THRESHOLD_=65536``, see :data:`_DASK_TRIM`; a value the user set
    in the environment is kept) and the quieter worker housekeeping of
    :data:`FLEET_WORKER_CONFIG`. With ``pin`` (default) and no more worker threads
    than cores, each worker is pinned to cores of its own (:func:`_pin_workers`).
    The caller closes it.
    """
    import os

    import dask
    from dask.distributed import LocalCluster

    from imubounds.runtime import malloc_environment

    name, dask_value = _DASK_TRIM
    inherited = os.environ.get(name)
    if inherited == dask_value:  # left by an earlier Dask nanny in this process
        del os.environ[name]
    environ = malloc_environment()
    try:
        with dask.config.set({
            **FLEET_WORKER_CONFIG,
            **{f"distributed.nanny.pre-spawn-environ.{k}": v for k, v in environ.items()},
        }):  # fmt: skip
            cluster = LocalCluster(
                n_workers=max(1, n_workers),
                threads_per_worker=max(1, threads_per_worker),
                processes=True,
                dashboard_address=kwargs.pop("dashboard_address", ":0"),
                **kwargs,
            )
    finally:
        if inherited is not None:
            os.environ[name] = inherited
    if pin:
        _pin_workers(cluster, max(1, threads_per_worker))
    return cluster


def _pin_workers(cluster: Any, threads_per_worker: int) -> list[set[int]]:
    """Pin worker ``i`` of a local cluster (every thread of its process) to cores
    ``i*t .. i*t+t-1`` of this process's allowed cores, when the workers' threads fit
    (Linux; else nothing). Returns the sets given.

    Measured on 2 cores, 16 units on 2 workers: 8 % less wall time (3.89 s against
    4.26 s, median of 9 runs): unpinned, the two workers and the client's scheduler
    thread migrate between the cores and the workers lose their caches. A restarted
    worker is not pinned again (it runs, unpinned).
    """
    import os

    if not hasattr(os, "sched_setaffinity"):
        return []
    cpus = sorted(os.sched_getaffinity(0))
    procs = [getattr(getattr(n, "process", None), "process", None)
             for n in getattr(cluster, "workers", {}).values()]  # fmt: skip
    pids = [int(p.pid) for p in procs if p is not None and p.pid]
    if len(pids) < 2 or len(pids) * threads_per_worker > len(cpus):
        return []
    given = []
    for i, pid in enumerate(pids):
        mine = set(cpus[i * threads_per_worker : (i + 1) * threads_per_worker])
        try:
            for tid in os.listdir(f"/proc/{pid}/task"):
                os.sched_setaffinity(int(tid), mine)
        except OSError:  # the worker went away, or no permission: leave it free
            continue
        given.append(mine)
    return given
