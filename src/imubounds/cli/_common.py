"""Options and helpers shared by several commands (reading logs, progress, output)."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from imubounds.errors import OptionError

# ----------------------------------------------------------------------------- option types
# Every numeric option is range-checked when it is parsed: argparse turns an
# ArgumentTypeError into "imubounds CMD: error: argument --x: ..." and exit 2.


def _number(text: str, kind: type = float) -> float:
    try:
        x = kind(text)
    except (TypeError, ValueError):
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(x):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return x


def finite_float(text: str) -> float:
    """Any finite number."""
    return _number(text)


def positive_float(text: str) -> float:
    """A finite number > 0."""
    x = _number(text)
    if not x > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return x


def nonneg_float(text: str) -> float:
    """A finite number >= 0."""
    x = _number(text)
    if not x >= 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text}")
    return x


def probability(text: str) -> float:
    """A number strictly between 0 and 1."""
    x = _number(text)
    if not 0 < x < 1:
        raise argparse.ArgumentTypeError(f"must be between 0 and 1 (exclusive), got {text}")
    return x


def positive_int(text: str) -> int:
    """A whole number >= 1."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {text}")
    return n


def nonneg_int(text: str) -> int:
    """A whole number >= 0."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text}")
    return n


def add_force_option(p: argparse.ArgumentParser) -> None:
    """``--force``: allow overwriting files in the output directory that imubounds did not write."""
    p.add_argument(
        "--force",
        action="store_true",
        help="overwrite files in the output directory that imubounds did not write",
    )


def add_log_options(p: argparse.ArgumentParser) -> None:
    """Options that say how to read an IMU log (shared by static, fleet, ...)."""
    g = p.add_argument_group("reading the log")
    g.add_argument(
        "--rate", type=float, metavar="HZ", help="sample rate when the log has no time column"
    )
    g.add_argument(
        "--columns",
        metavar="MAP",
        help="map columns to channels, e.g. 'time=stamp,gyro_x=wx,accel_x=ax'",
    )
    g.add_argument(
        "--gyro-unit",
        metavar="UNIT",
        help="gyro unit if not in the column name: rad/s, deg/s, deg/h",
    )
    g.add_argument("--accel-unit", metavar="UNIT", help="accelerometer unit: m/s^2, g, mg")
    g.add_argument("--time-unit", metavar="UNIT", help="time column unit: s, ms, us, ns")
    g.add_argument(
        "--on-gap",
        choices=("refuse", "split", "ignore"),
        default="refuse",
        help="what to do with gaps in the time stamps (default: refuse and report them)",
    )
    g.add_argument(
        "--gap-tolerance",
        type=float,
        metavar="FACTOR",
        help="a gap is a time step longer than FACTOR x the nominal period",
    )
    g.add_argument(
        "--topic",
        metavar="NAME",
        help="ROS bag topic (sensor_msgs/Imu) or ULog topic (sensor_combined, vehicle_imu)",
    )
    g.add_argument("--dataset", metavar="PATH", help="HDF5 path of the IMU table, e.g. /imu")


def read_log_from_args(path: str, args: argparse.Namespace) -> Any:
    from imubounds.io import parse_column_map, read_imu

    kwargs: dict[str, Any] = {
        "rate_hz": args.rate,
        "columns": parse_column_map(args.columns) if args.columns else None,
        "gyro_unit": args.gyro_unit,
        "accel_unit": args.accel_unit,
        "time_unit": args.time_unit,
        "on_gap": args.on_gap,
    }
    if args.gap_tolerance is not None:
        kwargs["gap_tolerance"] = args.gap_tolerance
    fmt = {k: getattr(args, k, None) for k in ("topic", "dataset")}
    kwargs["format_options"] = {k: v for k, v in fmt.items() if v is not None}
    return read_imu(path, **kwargs)


def parse_taus(text: str) -> str | int | list[float]:
    """``octave`` | ``decade`` | ``all`` | ``points:K`` | ``1,10,100s`` (seconds).

    The grammar lives in :func:`imubounds.stationary.allan.parse_tau_spec`; a bare
    number is refused as ambiguous.
    """
    from imubounds.stationary.allan import parse_tau_spec

    return parse_tau_spec(text)


def parse_list(text: str, allowed: tuple[str, ...], option: str) -> tuple[str, ...]:
    items = tuple(s.strip().lower() for s in text.split(",") if s.strip())
    bad = [s for s in items if s not in allowed]
    if bad:
        raise OptionError(f"{option}: unknown {', '.join(bad)}; choose from {', '.join(allowed)}")
    return items


class Reporter:
    """Progress bars and messages on stderr; silent with ``--quiet``."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self._bars: dict[str, Any] = {}

    def info(self, msg: str) -> None:
        if not self.quiet:
            print(msg, file=sys.stderr)

    def warn(self, msg: str) -> None:
        print(f"imubounds: warning: {msg}", file=sys.stderr)

    def progress(self, stage: str, done: int, total: int) -> None:
        if self.quiet:
            return
        from tqdm import tqdm

        bar = self._bars.get(stage)
        if bar is None:
            bar = tqdm(total=total, desc=stage, unit="step", file=sys.stderr, leave=False)
            self._bars[stage] = bar
        bar.n = done
        bar.refresh()
        if done >= total:
            bar.close()

    def close(self) -> None:
        for bar in self._bars.values():
            bar.close()
        self._bars.clear()

    @contextmanager
    def session(self) -> Iterator[Callable[[str, int, int], None]]:
        try:
            yield self.progress
        finally:
            self.close()
