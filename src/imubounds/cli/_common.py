"""Options and helpers shared by several commands (reading logs, progress, output)."""

from __future__ import annotations

import argparse
import math
import sys
import threading
import time
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


def gap_factor(text: str) -> float:
    """A finite number > 1 (a multiple of the sample period)."""
    x = _number(text)
    if not x > 1:
        raise argparse.ArgumentTypeError(
            f"is a multiple of the sample period and must be > 1, got {text}"
        )
    return x


def declination(text: str) -> float:
    """A magnetic declination in degrees, east positive, within +-180 (drive.yaml's range)."""
    x = _number(text)
    if not -180.0 <= x <= 180.0:
        raise argparse.ArgumentTypeError(f"must be within -180..180 deg, got {text}")
    return x


def setting_value(key: str, unit: str) -> Callable[[str], float]:
    """An option that overrides the drive.yaml setting ``key``: a finite number in that
    setting's range (``--heading-deviation 1000`` is refused as ``heading.deviation_deg``
    would be)."""
    from imubounds.io.drive.settings import setting_range

    lo, inclusive, hi = setting_range(key)

    def parse(text: str) -> float:
        x = _number(text)
        if x < lo or (x == lo and not inclusive):
            rel = ">=" if inclusive else ">"
            raise argparse.ArgumentTypeError(f"must be {rel} {lo:g} {unit} ({key}), got {text}")
        if hi is not None and x > hi:
            raise argparse.ArgumentTypeError(
                f"must be at most {hi:g} {unit} ({key} in drive.yaml has the same range), "
                f"got {text}"
            )
        return x

    parse.__name__ = key.replace(".", "_")
    return parse


def imu_spec(text: str) -> str:
    """``--imu-spec``: a preset name or ``accel_nd=..,accel_bs=..,gyro_nd=..,gyro_bs=..``,
    checked when parsed (not empty; datasheet figures not all zero)."""
    t = text.strip()
    if not t:
        raise argparse.ArgumentTypeError("is empty; give a preset name (mtx, vn100) or figures")
    try:
        if "=" in t:
            from imubounds.dynamic.estimator.budget import parse_datasheet

            vals = parse_datasheet(t)
            if not any(vals.values()):
                raise argparse.ArgumentTypeError(
                    "every figure is 0: no IMU is noiseless; give the datasheet's figures"
                )
            zero = [k for k in ("accel_nd", "gyro_nd") if vals[k] == 0]
            if zero:
                raise argparse.ArgumentTypeError(
                    f"{', '.join(zero)} = 0: no IMU is noiseless; give the datasheet's noise "
                    "density"
                )
        else:
            from imubounds.presets import get_preset

            get_preset(t)
    except OptionError as err:
        raise argparse.ArgumentTypeError(str(err).replace("--imu-spec ", "")) from None
    return t


def noise_json(text: str) -> str:
    """``--static``: a noise.json of ``imubounds static`` (checked when parsed: text, JSON,
    figures for the accelerometers and the gyros; :func:`imubounds.io.drive.layout.
    check_noise_json`)."""
    from imubounds.errors import InputError
    from imubounds.io.drive.settings import check_noise_json

    try:
        check_noise_json(text)
    except InputError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    return text


def compass_calibration(text: str) -> str:
    """``--compass-cal``: a swing-calibration CSV whose pairs are all finite (checked when
    parsed; :func:`imubounds.io.drive.settings.check_calibration`)."""
    from imubounds.errors import InputError
    from imubounds.io.drive.settings import check_calibration

    try:
        check_calibration(text)
    except InputError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    return text


def _unit_type(kind: str, examples: str) -> Callable[[str], str]:
    def parse(text: str) -> str:
        from imubounds.io.columns import normalise_unit

        if normalise_unit(text, kind) is None:
            raise argparse.ArgumentTypeError(f"unknown {kind} unit {text!r}; use {examples}")
        return text

    parse.__name__ = f"{kind}_unit"
    return parse


#: Unit options, checked at parse time (the value is passed on as written).
gyro_unit = _unit_type("gyro", "rad/s, deg/s, deg/h or mrad/s")
accel_unit = _unit_type("accel", "m/s^2, g, mg or ug")
time_unit = _unit_type("time", "s, ms, us or ns")


def memory_size(text: str) -> int:
    """A memory setting (``1GiB``, ``512MB``, ``2e9``) in bytes, at least 64 KiB."""
    from imubounds.stationary.routing import parse_memory

    try:
        return parse_memory(text)
    except OptionError as err:
        raise argparse.ArgumentTypeError(str(err).replace("memory setting ", "")) from None


def existing_dir(text: str) -> str:
    """An existing, writable directory (checked when the option is parsed)."""
    import os

    if not text:
        raise argparse.ArgumentTypeError("is empty; give a directory")
    if not os.path.isdir(text):
        what = "is not a directory" if os.path.exists(text) else "does not exist"
        raise argparse.ArgumentTypeError(f"{text} {what}; create it or choose another")
    if not os.access(text, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"{text} is not writable; choose another directory")
    return text


def add_force_option(p: argparse.ArgumentParser) -> None:
    """``--overwrite`` (``--force``, the same option): write into an output folder that
    holds other files, and replace files there that imubounds did not write (never an
    input of the run); ``args.force``."""
    p.add_argument(
        "--overwrite",
        "--force",
        dest="force",
        action="store_true",
        help="write into an output folder that holds other files (they are kept) and "
        "replace files of the same names that imubounds did not write (never an input); "
        "--force is the same option",
    )


def add_log_options(p: argparse.ArgumentParser) -> None:
    """Options that say how to read an IMU log (shared by static, fleet, ...)."""
    g = p.add_argument_group("reading the log")
    g.add_argument(
        "--rate",
        type=positive_float,
        metavar="HZ",
        help="sample rate when the log has no time column",
    )
    g.add_argument(
        "--columns",
        metavar="MAP",
        help="map columns to channels, e.g. 'time=stamp,gyro_x=wx,accel_x=ax'",
    )
    g.add_argument(
        "--gyro-unit",
        type=gyro_unit,
        metavar="UNIT",
        help="gyro unit if not in the column name: rad/s, deg/s, deg/h",
    )
    g.add_argument(
        "--accel-unit", type=accel_unit, metavar="UNIT", help="accelerometer unit: m/s^2, g, mg"
    )
    g.add_argument(
        "--time-unit", type=time_unit, metavar="UNIT", help="time column unit: s, ms, us, ns"
    )
    g.add_argument(
        "--on-gap",
        choices=("refuse", "split", "ignore"),
        default="refuse",
        help="what to do with gaps in the time stamps (default: refuse and report them)",
    )
    g.add_argument(
        "--gap-tolerance",
        type=gap_factor,
        metavar="FACTOR",
        help="a gap is a time step longer than FACTOR x the nominal period",
    )
    g.add_argument(
        "--topic",
        metavar="NAME",
        help="ROS bag topic (sensor_msgs/Imu) or ULog topic (sensor_combined, vehicle_imu)",
    )
    g.add_argument("--dataset", metavar="PATH", help="HDF5 path of the IMU table, e.g. /imu")


TOPIC_ROLES = ("imu", "gnss", "mag", "heading", "velocity", "gnss_velocity", "attitude")


def add_drive_options(p: argparse.ArgumentParser) -> None:
    """Options that say how to read a drive log (``imubounds.io.read_drive``): settings,
    mount, ROS topics, CSV column map, NMEA clock and IMU frame, maximum speed."""
    g = p.add_argument_group("reading the drive log")
    g.add_argument(
        "--settings",
        metavar="YAML",
        help="drive.yaml with the bounds and mount of this drive (replaces the input's own)",
    )
    g.add_argument(
        "--imu-axes",
        metavar="AXES",
        help="mount: body axes x,y,z (forward, left, up) as signed IMU axes, e.g. 'x,-z,y' "
        "(write --imu-axes=-x,-y,z when the first one has a sign)",
    )
    g.add_argument(
        "--mount",
        choices=("auto", "forward", "backward"),
        default="auto",
        help="VN-100: detect a backwards unit from its yaw and the GPS course (auto)",
    )
    g.add_argument(
        "--topic",
        action="append",
        metavar="[ROLE=]TOPIC",
        help="ROS bag topic of a role (imu, gnss, mag, heading, velocity, gnss_velocity, "
        "attitude); a bare name is the IMU topic; repeatable",
    )
    g.add_argument(
        "--columns",
        metavar="MAP",
        help="CSV logs: layout column = source column, e.g. "
        "'time_s=stamp,gyro_z_dps=yaw_rate,accel_x_g=ax,lat_deg=Lat,lon_deg=Lon'",
    )
    g.add_argument(
        "--imu-frame",
        choices=("FLU", "FRD"),
        default="FLU",
        help="axes of the IMU log beside an NMEA capture when its format does not say (FLU)",
    )
    g.add_argument("--date", metavar="YYYY-MM-DD", help="UTC date of an NMEA capture without RMC")
    g.add_argument(
        "--time-offset",
        type=finite_float,
        default=0.0,
        metavar="S",
        help="seconds added to the NMEA times to put them on the IMU clock (0)",
    )
    g.add_argument(
        "--on-bad-checksum",
        choices=("error", "skip"),
        default="error",
        help="an NMEA sentence with a wrong checksum: stop (error) or skip and count it",
    )
    g.add_argument(
        "--max-speed",
        type=positive_float,
        metavar="M/S",
        help="speeds beyond this are dropped and counted (drive.yaml vehicle.max_speed_mps, "
        "70 m/s)",
    )


def parse_topics(items: list[str] | None) -> dict[str, str]:
    """``["imu=/imu/data", "/gps/fix"]`` -> {role: topic} (a bare name is the IMU topic)."""
    out: dict[str, str] = {}
    for item in items or []:
        role, eq, topic = item.partition("=")
        if not eq:
            role, topic = "imu", item
        role, topic = role.strip().lower(), topic.strip()
        if role not in TOPIC_ROLES:
            raise OptionError(
                f"--topic {item!r}: unknown role {role!r}; use {', '.join(TOPIC_ROLES)}"
            )
        if not topic:
            raise OptionError(f"--topic {item!r} names no topic")
        if role in out:
            raise OptionError(f"--topic gives the {role} topic twice")
        out[role] = topic
    return out


def drive_read_options(args: argparse.Namespace) -> dict[str, Any]:
    """The keyword arguments of ``imubounds.io.read_drive`` from :func:`add_drive_options`."""
    from imubounds.io.drive.readers import parse_drive_columns

    axes = None
    if args.imu_axes is not None:
        axes = [a for a in args.imu_axes.replace(" ", ",").split(",") if a]
    return {
        "settings": args.settings,
        "imu_axes": axes,
        "mount": args.mount,
        "topics": parse_topics(args.topic) or None,
        "columns": parse_drive_columns(args.columns) if args.columns is not None else None,
        "imu_frame": args.imu_frame,
        "date_utc": args.date,
        "time_offset_s": args.time_offset,
        "on_bad_checksum": args.on_bad_checksum,
        "max_speed_mps": args.max_speed,
    }


def read_log_from_args(path: str, args: argparse.Namespace) -> Any:
    from imubounds.io import parse_column_map, read_imu

    kwargs: dict[str, Any] = {
        "rate_hz": args.rate,
        "columns": parse_column_map(args.columns) if args.columns else None,
        "gyro_unit": args.gyro_unit,
        "accel_unit": args.accel_unit,
        "time_unit": args.time_unit,
        "on_gap": args.on_gap,
        "unusual_rate": bool(getattr(args, "allow_unusual_rate", False)),
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
    from imubounds.stationary.allan_grammar import parse_tau_spec

    return parse_tau_spec(text)


def tau_grid(text: str) -> str:
    """``--tau``, checked when parsed (:func:`parse_taus`); the text is passed on."""
    try:
        parse_taus(text)
    except OptionError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    return text


def parse_list(text: str, allowed: tuple[str, ...], option: str) -> tuple[str, ...]:
    items = tuple(s.strip().lower() for s in text.split(",") if s.strip())
    bad = [s for s in items if s not in allowed]
    if bad:
        raise OptionError(f"{option}: unknown {', '.join(bad)}; choose from {', '.join(allowed)}")
    return items


class Steps:
    """The progress line of a command of several steps, on a terminal only (stderr, gone
    when the command ends): ``title: k/n step name (what the library reports) [elapsed]``.

    With ``tick`` a thread redraws it twice a second, so that a step of many seconds is
    seen moving (the elapsed time) even where the library reports nothing;
    :meth:`paused` stops that thread for a while (a ``fork`` wants a single thread).
    Without a terminal, or with ``--quiet``, every method does nothing.
    """

    def __init__(self, title: str, total: int, enabled: bool, tick: bool = True) -> None:
        self._bar: Any = None
        self._lock = threading.Lock()
        self._title, self._total, self._k = title, total, 0
        self._name = ""
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._tick = tick
        self.started = time.monotonic()
        if enabled:
            from tqdm import tqdm

            self._bar = tqdm(total=total, file=sys.stderr, leave=False,
                             bar_format="{desc} [{elapsed}]",
                             desc=f"{title}: 0/{total} starting")
            self._start_ticker()

    def _show(self, text: str) -> None:
        self._bar.set_description_str(f"{self._title}: {self._k}/{self._total} {text}")

    def _start_ticker(self) -> None:
        if self._bar is None or not self._tick or self._thread is not None:
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="imubounds-progress",
                                        daemon=True)
        self._thread.start()

    def _stop_ticker(self) -> None:
        if self._thread is not None:
            self._stop.set()
            self._thread.join()
            self._thread = None

    def _run(self) -> None:
        while not self._stop.wait(0.5):
            with self._lock:
                if self._bar is not None:
                    self._bar.refresh()

    def step(self, name: str) -> None:
        """Start the next step."""
        if self._bar is None:
            return
        with self._lock:
            self._k = min(self._k + 1, self._total)
            self._name = name
            self._show(name)

    def sub(self, stage: str, done: int, total: int) -> None:
        """A ``progress(stage, done, total)`` callback of the library, shown in the line."""
        if self._bar is None:
            return
        with self._lock:
            self._show(f"{self._name}: {stage} ({done}/{total})")

    @contextmanager
    def paused(self) -> Iterator[None]:
        self._stop_ticker()
        try:
            yield
        finally:
            self._start_ticker()

    def close(self) -> None:
        self._stop_ticker()
        if self._bar is not None:
            self._bar.close()
            self._bar = None


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
        if self.quiet or not sys.stderr.isatty():  # progress bars only on a terminal
            return
        from tqdm import tqdm

        bar = self._bars.get(stage)
        if bar is None:
            bar = tqdm(total=total, desc=stage, unit="step", file=sys.stderr, leave=False)
            self._bars[stage] = bar
        if bar.total != total:  # a total found as the work goes (fleet units not cached)
            bar.total = total
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

    @contextmanager
    def steps(self, title: str, total: int, tick: bool = True) -> Iterator[Steps]:
        """A :class:`Steps` line for the command, on a terminal and without ``--quiet``."""
        s = Steps(title, total, enabled=not self.quiet and sys.stderr.isatty(), tick=tick)
        try:
            yield s
        finally:
            s.close()
