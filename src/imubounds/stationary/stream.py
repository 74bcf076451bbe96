"""Out-of-core Allan variance: logs larger than memory (docs/static-method.md, section 1).

The in-memory path (:func:`imubounds.stationary.allan.allan`) holds the rate signal ``y``
and its phase ``x`` (compensated cumulative sum, length ``N + 1``) in RAM. Here
both stay on disk and only bounded blocks are in memory:

1. **read** - the log is read in blocks of rows (:mod:`imubounds.io.chunked`);
   per channel the mean (``math.fsum`` of block sums), the count and the
   finiteness are found. Text logs, which are slow to parse twice, are
   spilled to a temporary float64 file on the way.
2. **phase** - ``x[k] = t0 * sum_{i<k} (y[i] - mean)`` is computed block by
   block with the same compensated (TwoSum) recursion as
   :func:`imubounds.stationary._allan_kernels.phase_from_rate`, its state carried from
   one block to the next, and appended to a temporary file.
3. **sums** - for every cluster size ``m`` the sum of squared terms is taken
   over ranges of term indices ``[k0, k1)`` with the kernels of
   :mod:`imubounds.stationary._allan_kernels`. A range needs ``x`` at ``k + j*m``
   (``j = 0..d``): for ``d*m`` no larger than the block one contiguous window
   serves every small ``m`` at once; for larger ``m`` the ``d + 1`` segments
   are read and laid end to end, which turns them into the same kernel call
   with cluster size = segment length. Term chunks are aligned with those of
   the in-memory path, and partial sums are reduced with ``math.fsum``.
4. **noise id / EDF** - as in :mod:`imubounds.stationary.allan`, from at most 8192
   strided phase points per ``m`` read one by one.

The results agree with the in-memory path to about 1e-15 relative (the only
difference is the rounding of the mean, which the second differences cancel).

Memory: data buffers are bounded by ``memory_limit`` bytes (default 1 GiB):
blocks of ``B = memory_limit / 64`` values (rounded to the kernels' chunk
size), at most ``6 B`` values in memory at once. Interpreter, numpy, numba and
scipy add a fixed ~200-300 MB of RSS that does not grow with the log.

Temporary files live in ``tmpdir`` (default: the system temp directory; it
needs ``8 * (N + 1)`` bytes per channel, twice that for text logs) and are
removed on return, on error and on KeyboardInterrupt.

Progress is reported through ``progress(stage, done, total)`` (the library
never prints); :class:`EtaTracker` turns those calls into an estimate of the
time left.
"""

from __future__ import annotations

import io
import math
import shutil
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from imubounds.errors import AnalysisError, InputError, OptionError
from imubounds.io.chunked import ChunkedLog, open_chunked
from imubounds.stationary import _allan_kernels as _k
from imubounds.stationary.allan import (
    HADAMARD_ESTIMATORS,
    NOISE_ID_MAX_POINTS,
    AllanResult,
    _alpha_limits,
    _check_estimator,
    _check_rate,
    _parse_noise,
    noise_id_lag1,
    result_from_sums,
    tau_grid,
)
from imubounds.stationary.routing import DEFAULT_MEMORY as DEFAULT_MEMORY
from imubounds.stationary.routing import format_bytes as format_bytes
from imubounds.stationary.routing import parse_memory as parse_memory
from imubounds.stationary.routing import route_outofcore as route_outofcore

__all__ = [
    "DEFAULT_MEMORY",
    "EtaTracker",
    "PhaseFile",
    "allan_outofcore",
    "analyse_static_outofcore",
    "block_size",
    "format_bytes",
    "parse_memory",
    "phase_to_file",
]

Progress = Callable[[str, int, int], None]

_D = {
    "overlapping": 2,
    "hadamard": 3,
    "non-overlapping": 2,
    "non-overlapping-hadamard": 3,
    "total": 2,
    "modified": 3,
}


def block_size(memory_limit: int) -> int:
    """Number of phase values per block for a memory setting (bytes).

    ``memory_limit / 64`` (at most 6 blocks of float64 are alive at once),
    rounded down to a multiple of the kernels' chunk (65536) when larger.
    """
    b = max(1024, int(memory_limit) // 64)
    if b >= _k.CHUNK:
        b -= b % _k.CHUNK
    return b


@dataclass
class EtaTracker:
    """Estimate of the time left from ``(done, total)`` progress calls.

    ``update(done, total)`` returns the seconds left (``None`` until some work
    was done), by the mean rate since the first call.
    """

    clock: Callable[[], float] = time.monotonic
    _t0: float | None = field(default=None, init=False)
    _d0: int = field(default=0, init=False)

    def update(self, done: int, total: int) -> float | None:
        now = self.clock()
        if self._t0 is None:
            self._t0, self._d0 = now, done
            return None
        if done <= self._d0 or now <= self._t0:
            return None
        rate = (done - self._d0) / (now - self._t0)
        return max(0.0, (total - done) / rate)

# --------------------------------------------------------------------------
# small helpers
# --------------------------------------------------------------------------


# --------------------------------------------------------------------------
# phase on disk
# --------------------------------------------------------------------------
@njit(cache=True, fastmath=False)
def _phase_block(
    y: np.ndarray, mean: float, t0: float, s: float, c: float, out: np.ndarray
) -> tuple[float, float]:
    # the recursion of _allan_kernels._phase_kernel with its state passed in and out
    for i in range(y.shape[0]):
        v = y[i] - mean
        t = s + v
        bp = t - s
        c += (s - (t - bp)) + (v - bp)
        s = t
        out[i] = (s + c) * t0
    return s, c


def _phase_block_ref(
    y: np.ndarray, mean: float, t0: float, s: float, c: float, out: np.ndarray
) -> tuple[float, float]:
    """Pure-Python reference of :func:`_phase_block` (tests only; slow)."""
    for i in range(y.shape[0]):
        v = float(y[i]) - mean
        t = s + v
        bp = t - s
        c += (s - (t - bp)) + (v - bp)
        s = t
        out[i] = (s + c) * t0
    return s, c


class PhaseFile:
    """Read access to a phase array (float64, ``N + 1`` values) stored on disk."""

    def __init__(self, path: str | Path, n_samples: int) -> None:
        self.path = Path(path)
        self.n = int(n_samples)
        self._f: io.BufferedReader = open(self.path, "rb")  # noqa: SIM115
        self.bytes_read = 0

    def read(self, a: int, b: int) -> np.ndarray:
        """``x[a:b]`` as a new float64 array."""
        a = max(0, int(a))
        b = min(self.n + 1, int(b))
        if b <= a:
            return np.empty(0, dtype=np.float64)
        self._f.seek(8 * a)
        out = np.fromfile(self._f, dtype=np.float64, count=b - a)
        if out.shape[0] != b - a:
            raise InputError(f"{self.path}: phase file is truncated")
        self.bytes_read += 8 * (b - a)
        return out

    def read_into(self, out: np.ndarray, a: int) -> None:
        """Fill the contiguous float64 array ``out`` with ``x[a : a + len(out)]``."""
        k = out.shape[0]
        if a < 0 or a + k > self.n + 1:
            raise ValueError(f"phase range [{a}, {a + k}) outside [0, {self.n + 1})")
        self._f.seek(8 * a)
        got = self._f.readinto(out.data.cast("B"))
        if got != 8 * k:
            raise InputError(f"{self.path}: phase file is truncated")
        self.bytes_read += 8 * k

    def read_strided(self, start: int, step: int, count: int, block: int) -> np.ndarray:
        """``x[start : start + step*count : step]`` with at most ``block`` values in memory."""
        out = np.empty(count, dtype=np.float64)
        if step <= block:
            per = max(1, block // step)
            for q in range(0, count, per):
                r = min(count, q + per)
                w = self.read(start + q * step, start + (r - 1) * step + 1)
                out[q:r] = w[::step]
        else:
            for q in range(count):
                out[q] = self.read(start + q * step, start + q * step + 1)[0]
        return out

    def close(self) -> None:
        self._f.close()

    def __enter__(self) -> PhaseFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def phase_to_file(
    blocks: Sequence[np.ndarray] | Any, mean: float, t0: float, dest: str | Path
) -> int:
    """Write the phase of a rate signal given as an iterable of blocks.

    Parameters
    ----------
    blocks : iterable of 1-D float64 arrays
        Consecutive blocks of the rate signal (unit U).
    mean : float
        Mean of the whole signal (U).
    t0 : float
        Sample period, s.
    dest : path
        File to write: ``N + 1`` little-endian float64 values (U*s).

    Returns
    -------
    int
        Number of samples N.
    """
    s = 0.0
    c = 0.0
    n = 0
    with open(dest, "wb") as f:
        np.zeros(1, dtype=np.float64).tofile(f)
        for y in blocks:
            y = np.ascontiguousarray(y, dtype=np.float64)
            out = np.empty_like(y)
            s, c = _phase_block(y, float(mean), float(t0), s, c, out)
            out.tofile(f)
            n += y.shape[0]
    return n


# --------------------------------------------------------------------------
# modified Allan: streaming pieces for large m
# --------------------------------------------------------------------------
@njit(cache=True, fastmath=False)
def _twosum_d2(
    a: np.ndarray, b: np.ndarray, c2: np.ndarray, s: float, c: float
) -> tuple[float, float]:
    for i in range(a.shape[0]):
        v = c2[i] - 2.0 * b[i] + a[i]
        t = s + v
        bp = t - s
        c += (s - (t - bp)) + (v - bp)
        s = t
    return s, c


@njit(cache=True, fastmath=False)
def _mdev_slide(
    p0: np.ndarray, p1: np.ndarray, p2: np.ndarray, p3: np.ndarray, s: float, c: float
) -> tuple[float, float, float]:
    total = 0.0
    for q in range(p0.shape[0]):
        v = p3[q] - 3.0 * p2[q] + 3.0 * p1[q] - p0[q]
        t = s + v
        bp = t - s
        c += (s - (t - bp)) + (v - bp)
        s = t
        w = s + c
        total += w * w
    return total, s, c


# --------------------------------------------------------------------------
# sums of squares over a phase file
# --------------------------------------------------------------------------
def _chunks(a: int, b: int, size: int, origin: int) -> list[tuple[int, int]]:
    """``[a, b)`` cut at multiples of ``size`` counted from ``origin``."""
    out = []
    k = a
    while k < b:
        nxt = origin + ((k - origin) // size + 1) * size
        out.append((k, min(b, nxt)))
        k = min(b, nxt)
    return out


def _run(
    x: np.ndarray,
    code: int,
    tasks: list[tuple[int, int, int, int]],
    idx: list[int],
    part: list[float],
) -> None:
    if not tasks:
        return
    arr = np.asarray(tasks, dtype=np.int64)
    res = _k._run_tasks(x, code, arr[:, 1].copy(), arr[:, 2].copy(), arr[:, 3].copy())
    idx.extend(int(i) for i in arr[:, 0])
    part.extend(float(v) for v in res)


def sumsq_file(
    ph: PhaseFile,
    estimator: str,
    ms: np.ndarray,
    block: int,
    tick: Callable[[int], None] | None = None,
) -> np.ndarray:
    """Sums of squared terms for every ``m``, reading ``ph`` in bounded blocks.

    Same result as :func:`imubounds.stationary._allan_kernels.sumsq_tasks` on the whole
    phase array, in (U*s)^2. ``tick(n)`` is called with the number of terms
    just done.
    """
    n = ph.n
    ms = np.asarray(ms, dtype=np.int64)
    chunk = min(_k.CHUNK, block)
    idx: list[int] = []
    part: list[float] = []
    done = tick or (lambda _n: None)
    ranges = [_k.term_range(estimator, n, int(m)) for m in ms]

    if estimator in ("overlapping", "hadamard", "total"):
        d = 3 if estimator == "hadamard" else 2
        code = 2 if estimator == "hadamard" else 0
        # overlapping-type terms; for total the interior k in [m, n-m] is term k-m
        lens = [
            (n - 2 * int(m) + 1) if estimator == "total" else max(0, b - a)
            for m, (a, b) in zip(ms, ranges, strict=True)
        ]
        small = [i for i, m in enumerate(ms) if d * int(m) <= block and lens[i] > 0]
        large = [i for i, m in enumerate(ms) if d * int(m) > block and lens[i] > 0]
        lmax = max((lens[i] for i in small), default=0)
        for k0 in range(0, lmax, block):
            live = [i for i in small if lens[i] > k0]
            mm = max(int(ms[i]) for i in live)
            w = ph.read(k0, min(k0 + block, lmax) + d * mm)
            tasks = []
            for i in live:
                k1 = min(k0 + block, lens[i])
                for a, b in _chunks(k0, k1, chunk, 0):
                    tasks.append((i, int(ms[i]), a - k0, b - k0))
            _run(w, code, tasks, idx, part)
            done(sum(min(k0 + block, lens[i]) - k0 for i in live))
        for i in large:
            m = int(ms[i])
            for k0 in range(0, lens[i], block):
                k1 = min(k0 + block, lens[i])
                seg = k1 - k0
                z = np.empty((d + 1) * seg, dtype=np.float64)
                for j in range(d + 1):
                    ph.read_into(z[j * seg : (j + 1) * seg], k0 + j * m)
                tasks = [(i, seg, a - k0, b - k0) for a, b in _chunks(k0, k1, chunk, 0)]
                _run(z, code, tasks, idx, part)
                done(seg)
        if estimator == "total":
            x0 = float(ph.read(0, 1)[0])
            xn = float(ph.read(n, n + 1)[0])
            eb = max(1, block // 2)  # three reads and two temporaries per edge block
            for i, m in enumerate(ms):
                m = int(m)
                # left edge k in [1, m): (2x0 - x[m-k]) - 2x[k] + x[k+m]
                for lo in range(1, min(m, n), eb):
                    hi = min(m, n, lo + eb)
                    xr = ph.read(m - hi + 1, m - lo + 1)[::-1]
                    dd = (2.0 * x0 - xr) - 2.0 * ph.read(lo, hi) + ph.read(lo + m, hi + m)
                    idx.append(i)
                    part.append(float(np.dot(dd, dd)))
                    done(hi - lo)
                # right edge k in [max(m, n-m+1), n): x[k-m] - 2x[k] + (2xn - x[2n-k-m])
                for lo in range(max(m, n - m + 1), n, eb):
                    hi = min(n, lo + eb)
                    xr = ph.read(2 * n - m - hi + 1, 2 * n - m - lo + 1)[::-1]
                    dd = ph.read(lo - m, hi - m) - 2.0 * ph.read(lo, hi) + (2.0 * xn - xr)
                    idx.append(i)
                    part.append(float(np.dot(dd, dd)))
                    done(hi - lo)

    elif estimator in ("non-overlapping", "non-overlapping-hadamard"):
        d = 3 if estimator == "non-overlapping-hadamard" else 2
        code = 2 if estimator == "non-overlapping-hadamard" else 0
        for i, m in enumerate(ms):
            m = int(m)
            a, b = ranges[i]
            for j0 in range(a, b, block):
                j1 = min(b, j0 + block)
                xs = ph.read_strided(j0 * m, m, j1 - j0 + d, block)
                tasks = [(i, 1, p - j0, q - j0) for p, q in _chunks(j0, j1, chunk, 0)]
                _run(xs, code, tasks, idx, part)
                done(j1 - j0)

    elif estimator == "modified":
        for i, m in enumerate(ms):
            m = int(m)
            a, b = ranges[i]
            if b <= a:
                continue
            csize = max(_k.CHUNK, 16 * m)
            if 3 * m <= block:
                # windowed: whole in-memory chunks per block, same chunk boundaries
                per = max(csize, (block // csize) * csize)
                for j0 in range(a, b, per):
                    j1 = min(b, j0 + per)
                    w = ph.read(j0, j1 - 1 + 3 * m)
                    tasks = [(i, m, p - j0, q - j0) for p, q in _chunks(j0, j1, csize, a)]
                    _run(w, 3, tasks, idx, part)
                    done(j1 - j0)
            else:
                part.append(_mdev_streaming(ph, m, a, b, block, done))
                idx.append(i)
    else:  # pragma: no cover - checked by the caller
        raise OptionError(f"unknown estimator {estimator!r}")

    if not idx:
        return np.zeros(ms.shape[0])
    return _k.reduce_partials(np.asarray(idx), np.asarray(part), ms.shape[0])


def _mdev_streaming(
    ph: PhaseFile, m: int, a: int, b: int, block: int, done: Callable[[int], None]
) -> float:
    """Modified-Allan numerator for one large ``m``, same recursion as ``mdev_sumsq``."""
    resync = max(16 * m, 4096)
    csize = max(_k.CHUNK, 16 * m)
    total = 0.0
    j = a
    while j < b:
        jstart = j
        chunk_end = min(b, a + ((j - a) // csize + 1) * csize)
        s, c = 0.0, 0.0
        for i0 in range(j, j + m, block):
            i1 = min(j + m, i0 + block)
            s, c = _twosum_d2(
                ph.read(i0, i1), ph.read(i0 + m, i1 + m), ph.read(i0 + 2 * m, i1 + 2 * m), s, c
            )
        w = s + c
        total += w * w
        jstop = min(chunk_end, j + resync)
        j += 1
        while j < jstop:
            nb = min(block, jstop - j)
            p = [ph.read(j - 1 + t * m, j - 1 + t * m + nb) for t in range(4)]
            tot, s, c = _mdev_slide(p[0], p[1], p[2], p[3], s, c)
            total += tot
            j += nb
        done(j - jstart)
    return total


def _alphas_file(
    ph: PhaseFile, ms: np.ndarray, t0: float, estimator: str, block: int
) -> np.ndarray:
    lo, hi = _alpha_limits(estimator)
    dmax = 3 if estimator in HADAMARD_ESTIMATORS else 2
    out = np.zeros(ms.size, dtype=np.int64)
    prev = 0
    n = ph.n
    for i, m in enumerate(ms):
        m = int(m)
        k = min(n // m, NOISE_ID_MAX_POINTS)
        a = None
        if k >= 30:
            xs = ph.read_strided(0, m, k + 1, block)
            a = noise_id_lag1(np.diff(xs) / (m * t0), dmax=dmax)
        if a is None:
            a = prev
        a = min(max(a, lo), hi)
        out[i] = a
        prev = a
    return out


def allan_from_phase_file(
    ph: PhaseFile,
    rate_hz: float,
    taus: str | int | Sequence[float] | np.ndarray = "octave",
    estimator: str = "overlapping",
    confidence: float = 0.683,
    noise: str | int = "auto",
    *,
    block: int = block_size(DEFAULT_MEMORY),
    tick: Callable[[int], None] | None = None,
) -> AllanResult:
    """:func:`imubounds.stationary.allan.allan` on a phase array stored on disk."""
    _check_estimator(estimator)
    rate = _check_rate(rate_hz)
    conf = float(confidence)
    if not 0.0 < conf < 1.0:
        raise OptionError(f"confidence must be in (0, 1), got {confidence!r}")
    fixed_alpha = _parse_noise(noise, estimator)
    n = ph.n
    ms, tau = tau_grid(n, rate, taus, estimator)
    t0 = 1.0 / rate
    sums = sumsq_file(ph, estimator, ms, block, tick)
    if fixed_alpha is None:
        alphas = _alphas_file(ph, ms, t0, estimator, block)
    else:
        alphas = np.full(ms.size, fixed_alpha, dtype=np.int64)
    return result_from_sums(sums, ms, tau, alphas, estimator, n, rate, conf)


def _work_terms(estimator: str, n: int, ms: np.ndarray) -> int:
    if estimator == "total":
        return int(sum(n - 1 for _ in ms))
    return int(sum(max(0, _k.n_terms(estimator, n, int(m))) for m in ms))


# --------------------------------------------------------------------------
# the driver
# --------------------------------------------------------------------------
@dataclass
class OutOfCoreStats:
    """What an out-of-core run did (for reports and benchmarks)."""

    n_samples: int = 0
    channels: int = 0
    block_values: int = 0
    temp_bytes: int = 0
    bytes_read: int = 0
    seconds: float = 0.0


def _work_dir(tmpdir: str | Path | None) -> str:
    """A fresh temporary directory in ``tmpdir`` (one-line errors if it cannot be made)."""
    from imubounds.errors import OutputError

    if tmpdir is not None and not Path(tmpdir).is_dir():
        what = "is not a directory" if Path(tmpdir).exists() else "does not exist"
        raise OptionError(f"--tmpdir {tmpdir} {what}; create it or choose another directory")
    try:
        return tempfile.mkdtemp(
            prefix="imubounds-ooc-", dir=None if tmpdir is None else str(tmpdir)
        )
    except OSError as err:
        where = tmpdir if tmpdir is not None else tempfile.gettempdir()
        raise OutputError(
            f"cannot create temporary files in {where} ({err.strerror or err}); "
            "choose a writable directory with --tmpdir"
        ) from err


def allan_outofcore(
    log: ChunkedLog | str | Path,
    taus: str | int | Sequence[float] | np.ndarray = "octave",
    estimator: str = "overlapping",
    confidence: float = 0.683,
    noise: str | int = "auto",
    *,
    channels: Sequence[str] | None = None,
    memory_limit: int | str = DEFAULT_MEMORY,
    tmpdir: str | Path | None = None,
    progress: Progress | None = None,
    stats: OutOfCoreStats | None = None,
    **open_kwargs: Any,
) -> dict[str, AllanResult]:
    """Allan curves of every channel of a log that need not fit in memory.

    Parameters
    ----------
    log : ChunkedLog or path
        An opened log, or a path opened with :func:`open_chunked` (``open_kwargs``
        such as ``rate_hz=``, ``channels=`` pass through).
    taus, estimator, confidence, noise
        As for :func:`imubounds.stationary.allan.allan`.
    channels : sequence of str, optional
        Only these channels.
    memory_limit : int or str
        Bound on the data buffers, bytes or ``"1GiB"``; default 1 GiB.
    tmpdir : path, optional
        Where the temporary phase files go (default: system temp directory).
    progress : callable(stage, done, total), optional
        Stages ``"read"`` and ``"phase"`` (rows) then ``"allan"`` (terms).
    stats : OutOfCoreStats, optional
        Filled with sizes and timings.

    Returns
    -------
    dict of channel -> AllanResult (SI units), equal to the in-memory result.
    """
    t_start = time.perf_counter()
    _check_estimator(estimator)
    _parse_noise(noise, estimator)
    mem = parse_memory(memory_limit)
    block = block_size(mem)
    if not isinstance(log, ChunkedLog):
        log = open_chunked(
            log, channels=list(channels) if channels is not None else None, **open_kwargs
        )
    names = list(channels) if channels else list(log.channels)
    missing = [c for c in names if c not in log.channels]
    if missing:
        raise OptionError(
            f"channel(s) {', '.join(missing)} not in {log.source}; available: "
            f"{', '.join(log.channels)}"
        )
    rows = max(1024, mem // (8 * 8 * max(1, len(log.channels))))
    t0 = 1.0 / log.rate_hz
    report = progress or (lambda _s, _d, _t: None)
    work = _work_dir(tmpdir)
    phases: dict[str, PhaseFile] = {}
    try:
        # ---- pass 1: count, mean, finiteness (and spill of text logs)
        sums: dict[str, list[float]] = {c: [] for c in names}
        spill = {c: Path(work) / f"y_{c}.f64" for c in names} if not log.rereadable else {}
        files = {c: open(p, "wb") for c, p in spill.items()}  # noqa: SIM115
        n = 0
        total_rows = log.n_samples or 0
        try:
            for blk in log.iter_chunks(rows):
                # finiteness, time order and gaps are checked by iter_chunks
                for c in names:
                    v = blk[c]
                    sums[c].append(float(np.sum(v)))
                    if c in files:
                        np.ascontiguousarray(v, dtype=np.float64).tofile(files[c])
                n += next(iter(blk.values())).shape[0] if blk else 0
                report("read", n, max(n, total_rows))
        finally:
            for f in files.values():
                f.close()
        if n == 0:
            raise InputError(f"{log.source}: no data rows")
        means = {c: math.fsum(sums[c]) / n for c in names}

        # ---- pass 2: phase files
        def blocks_of(c: str) -> Any:
            if spill:
                with open(spill[c], "rb") as f:
                    while True:
                        y = np.fromfile(f, dtype=np.float64, count=rows)
                        if y.size == 0:
                            return
                        yield y
            else:
                for blk in log.iter_chunks(rows):
                    yield blk[c]

        state = {c: (0.0, 0.0) for c in names}
        out_files = {c: open(Path(work) / f"x_{c}.f64", "wb") for c in names}  # noqa: SIM115
        try:
            for f in out_files.values():
                np.zeros(1, dtype=np.float64).tofile(f)
            if spill:
                done_rows = 0
                for c in names:
                    for y in blocks_of(c):
                        x = np.empty_like(y)
                        state[c] = _phase_block(y, means[c], t0, *state[c], x)
                        x.tofile(out_files[c])
                        done_rows += y.shape[0]
                        report("phase", done_rows // len(names), n)
                    spill[c].unlink()
            else:
                done_rows = 0
                for blk in log.iter_chunks(rows):
                    for c in names:
                        y = np.ascontiguousarray(blk[c], dtype=np.float64)
                        x = np.empty_like(y)
                        state[c] = _phase_block(y, means[c], t0, *state[c], x)
                        x.tofile(out_files[c])
                    done_rows += next(iter(blk.values())).shape[0]
                    report("phase", done_rows, n)
        finally:
            for f in out_files.values():
                f.close()
        for c in names:
            phases[c] = PhaseFile(Path(work) / f"x_{c}.f64", n)

        # ---- pass 3: Allan sums per channel
        ms, _ = tau_grid(n, log.rate_hz, taus, estimator)
        per = _work_terms(estimator, n, ms)
        total = per * len(names)
        progress_done = [0]

        def tick(k: int) -> None:
            progress_done[0] += k
            report("allan", min(progress_done[0], total), total)

        out: dict[str, AllanResult] = {}
        for c in names:
            out[c] = allan_from_phase_file(
                phases[c],
                log.rate_hz,
                taus,
                estimator,
                confidence,
                noise,
                block=block,
                tick=tick,
            )
            progress_done[0] = per * (len(out))
            report("allan", progress_done[0], total)
        if stats is not None:
            stats.n_samples = n
            stats.channels = len(names)
            stats.block_values = block
            stats.temp_bytes = 8 * (n + 1) * len(names)
            stats.bytes_read = sum(p.bytes_read for p in phases.values())
            stats.seconds = time.perf_counter() - t_start
        return out
    finally:
        for p in phases.values():
            p.close()
        shutil.rmtree(work, ignore_errors=True)


# --------------------------------------------------------------------------
# the static pipeline on a huge log
# --------------------------------------------------------------------------
def analyse_static_outofcore(
    path: str | Path | ChunkedLog,
    settings: Any = None,
    *,
    channels: Sequence[str] | None = None,
    memory_limit: int | str = DEFAULT_MEMORY,
    tmpdir: str | Path | None = None,
    progress: Progress | None = None,
    **open_kwargs: Any,
) -> Any:
    """:func:`imubounds.stationary.pipeline.analyse_static` through the out-of-core Allan path.

    Returns a :class:`~imubounds.stationary.pipeline.StaticResult` whose ``noise.json`` has
    the same curves and noise terms as the in-memory path. Stochastic models
    (GM/AR, which need the whole signal) are not fitted: a note says so.
    The ``log`` of the result holds no samples (zero-size stand-ins).
    """
    from imubounds.io.log import ImuLog
    from imubounds.stationary.pipeline import StaticSettings, analyse_static

    settings = settings or StaticSettings()
    log = (
        path
        if isinstance(path, ChunkedLog)
        else open_chunked(
            path, channels=list(channels) if channels is not None else None, **open_kwargs
        )
    )
    names = [c for c in (channels or log.channels) if c.startswith(("gyro", "accel"))]
    if not names:
        raise AnalysisError(f"{log.source} has no gyro or accelerometer channel to analyse")
    curves = allan_outofcore(
        log,
        settings.taus,
        settings.estimator,
        settings.confidence,
        channels=names,
        memory_limit=memory_limit,
        tmpdir=tmpdir,
        progress=progress,
    )
    n = next(iter(curves.values())).n_samples
    stub = ImuLog(
        channels={c: np.broadcast_to(np.float64(np.nan), (n,)) for c in names},
        rate_hz=log.rate_hz,
        t=np.broadcast_to(np.float64(0.0), (n,)),
        source=log.source,
        input_units={c: log.input_units[c] for c in names},
        warnings=list(log.warnings),
    )
    notes = []
    if settings.models:
        from dataclasses import replace

        settings = replace(settings, models=())
        notes.append("stochastic models (gm, ar) are not fitted on the out-of-core path")
    result = analyse_static(stub, settings, channels=names, progress=progress, curves=curves)
    result.notes.extend(notes)
    mem = format_bytes(parse_memory(memory_limit))
    result.notes.append(f"out-of-core Allan path: {n} samples, memory setting {mem}")
    return result
