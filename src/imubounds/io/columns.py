"""Recognise IMU columns by name, parse unit suffixes and ``--columns`` maps.

Recognised channel names (case-insensitive; ``.``, ``/``, ``-`` and spaces
count as ``_``; an optional leading ``field_``/``imu_``/``msg_`` prefix is
dropped, so ROS ``rostopic echo -p`` exports work):

=========  ==================================================================
gyro       ``gyro``, ``gyr``, ``gyros``, ``gyroscope``, ``omega`` (Kalibr),
           ``w_rs_s`` (EuRoC / TUM-VI), ``angular_velocity``, ``ang_vel``,
           ``angvel``, ``angular_rate``
accel      ``accel``, ``acc``, ``accl``, ``accelerometer``, ``acceleration``,
           ``alpha`` (Kalibr's bagcreater CSV uses alpha for acceleration),
           ``a_rs_s`` (EuRoC / TUM-VI), ``linear_acceleration``, ``lin_acc``
=========  ==================================================================

followed by an axis ``x``/``y``/``z`` (with or without ``_``), then optionally
a unit, either as a suffix (``gyro_x_dps``, ``accel_z_g``, ``gyro_x_rad_s``,
``accel_x_mps2``) or in brackets (``w_RS_S_x [rad s^-1]``, ``acc_x (m/s^2)``).
Kalibr's ``omega_*``/``alpha_*`` without a unit are rad/s and m/s^2 by that
format's convention (and its ``timestamp`` is in ns).
A suffix that is not a known unit (``gyro_x_bias``, ``gyro_x_raw``) means the
column is *not* recognised: it is probably not the calibrated rate.

Deliberately not recognised: one-letter names such as ``gx``/``ax``/``wx``
(``ax`` is as often an axis or a plot handle as an acceleration). Map such
columns explicitly with ``columns={"gyro_x": "gx", ...}`` (CLI ``--columns``).

Time columns: ``time``, ``t``, ``timestamp``, ``time_stamp``, ``stamp``,
``ts``, ``sec``/``secs``/``seconds``, ``%time`` and ``field.header.stamp``
(ROS, in ns), each with an optional unit suffix or bracket (``time_ns``,
``timestamp_us``, ``t_ms``, ``#timestamp [ns]``).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from imubounds.errors import OptionError
from imubounds.io.log import IMU_CHANNELS
from imubounds.units import (
    ACCEL_UNIT_SYNONYMS,
    ACCEL_UNITS,
    GYRO_UNIT_SYNONYMS,
    GYRO_UNITS,
    TIME_UNIT_SYNONYMS,
    TIME_UNITS,
)

TIME_KEY = "time"
#: Keys accepted on the left of a ``--columns`` map.
MAP_KEYS: tuple[str, ...] = (*IMU_CHANNELS, TIME_KEY)

GYRO_BASES: tuple[str, ...] = (
    "gyroscope",
    "gyros",
    "gyro",
    "gyr",
    "omega",
    "w_rs_s",
    "angular_velocity",
    "angular_rate",
    "ang_vel",
    "angvel",
)
ACCEL_BASES: tuple[str, ...] = (
    "accelerometer",
    "acceleration",
    "accel",
    "accl",
    "acc",
    "alpha",
    "a_rs_s",
    "linear_acceleration",
    "lin_acc",
)
TIME_BASES: tuple[str, ...] = ("timestamp", "time_stamp", "time", "stamp", "ts", "t", "seconds",
                               "secs", "sec")
_PREFIXES = ("field_", "imu_", "msg_", "data_")



@dataclass(frozen=True)
class Recognised:
    """What a column name says about itself.

    Attributes
    ----------
    canonical:
        ``gyro_x`` ... ``accel_z`` or ``"time"``.
    unit:
        Canonical unit key (of ``units.GYRO_UNITS``, ``ACCEL_UNITS`` or
        ``TIME_UNITS``) if the name states one, else ``None``.
    layout:
        ``"kalibr"`` for ``omega_*``/``alpha_*``, ``"euroc"`` for ``w_RS_S_*``/
        ``a_RS_S_*``, ``"ros"`` for ROS stamp columns, ``"generic"`` otherwise.
    """

    canonical: str
    unit: str | None
    layout: str


def _compact_unit(text: str) -> str:
    s = text.strip().lower()
    s = s.replace("°", "deg").replace("µ", "u").replace("μ", "u").replace("²", "^2")
    s = re.sub(r"\s*\*\s*|\s*·\s*", " ", s)
    # "rad s^-1" -> "rad/s", "m s^-2" -> "m/s^2"
    s = re.sub(r"\s*\bs\^?-1\b", "/s", s)
    s = re.sub(r"\s*\bs\^?-2\b", "/s^2", s)
    s = re.sub(r"\s*\bh\^?-1\b", "/h", s)
    s = s.replace("/s/s", "/s^2")
    s = re.sub(r"\s+", "", s)
    s = s.replace("degree", "deg").replace("degs/", "deg/")
    return s


def normalise_unit(text: str, kind: str) -> str | None:
    """Canonical unit key for a unit spelling, or ``None`` if unknown.

    Parameters
    ----------
    text:
        A unit as written: ``"rad s^-1"``, ``"dps"``, ``"m/s²"``, ``"g"``, ``"ns"``...
    kind:
        ``"gyro"``, ``"accel"`` or ``"time"``.
    """
    s = _compact_unit(text)
    table = {"gyro": GYRO_UNIT_SYNONYMS, "accel": ACCEL_UNIT_SYNONYMS,
             "time": TIME_UNIT_SYNONYMS}[kind]
    if s in table:
        return table[s]
    plain = {"gyro": GYRO_UNITS, "accel": ACCEL_UNITS, "time": TIME_UNITS}[kind]
    return s if s in plain else None


def _alt(words: tuple[str, ...]) -> str:
    return "|".join(re.escape(w) for w in sorted(words, key=len, reverse=True))


_SENSOR_RE = re.compile(
    rf"^(?P<base>{_alt(GYRO_BASES)}|{_alt(ACCEL_BASES)})_?(?P<axis>[xyz])(?:_(?P<unit>.+))?$"
)
_TIME_RE = re.compile(rf"^(?P<base>{_alt(TIME_BASES)})(?:_(?P<unit>[a-z]+))?$")
_BRACKET_RE = re.compile(r"^(?P<name>.*?)\s*[\[(](?P<unit>[^\])]*)[\])]\s*$")


def split_bracket_unit(name: str) -> tuple[str, str | None]:
    """Split ``"w_RS_S_x [rad s^-1]"`` into ``("w_RS_S_x", "rad s^-1")``."""
    m = _BRACKET_RE.match(name.strip())
    if m and m.group("name"):
        return m.group("name"), m.group("unit")
    return name.strip(), None


def _normalise_name(name: str) -> str:
    s = name.strip().lower().lstrip("#%").strip()
    s = re.sub(r"[\s./\-]+", "_", s)
    s = re.sub(r"_+", "_", s).strip("_")
    changed = True
    while changed:
        changed = False
        for p in _PREFIXES:
            if s.startswith(p) and len(s) > len(p):
                s = s[len(p):]
                changed = True
    return s


def recognise(name: str) -> Recognised | None:
    """Recognise a column name as an IMU channel or a time column.

    Returns ``None`` when the name is not recognised (including names with an
    unknown unit suffix such as ``gyro_x_bias``).
    """
    raw = name.strip()
    ros_time = raw.lower() in ("%time", "field.header.stamp", "header.stamp")
    base_name, bracket = split_bracket_unit(raw)
    s = _normalise_name(base_name)
    if ros_time or s in ("header_stamp",):
        return Recognised(TIME_KEY, "ns", "ros")
    m = _SENSOR_RE.match(s)
    if m:
        base = m.group("base")
        kind = "gyro" if base in GYRO_BASES else "accel"
        unit_text = m.group("unit")
        if unit_text is not None and bracket is not None:
            return None
        unit_text = unit_text if unit_text is not None else bracket
        unit = None
        if unit_text is not None:
            unit = normalise_unit(unit_text, kind)
            if unit is None:
                return None
        if base in ("omega", "alpha"):
            layout = "kalibr"
            if unit is None:  # Kalibr's CSV convention: rad/s and m/s^2
                unit = "rad/s" if kind == "gyro" else "m/s^2"
        elif base in ("w_rs_s", "a_rs_s"):
            layout = "euroc"
        else:
            layout = "generic"
        return Recognised(f"{kind}_{m.group('axis')}", unit, layout)
    m = _TIME_RE.match(s)
    if m:
        unit_text = m.group("unit")
        if unit_text is not None and bracket is not None:
            return None
        unit_text = unit_text if unit_text is not None else bracket
        unit = None
        if unit_text is not None:
            unit = normalise_unit(unit_text, "time")
            if unit is None:
                return None
        return Recognised(TIME_KEY, unit, "generic")
    return None


def parse_column_map(text: str) -> dict[str, str]:
    """Parse a CLI column map ``"gyro_x=wx,gyro_y=wy,time=stamp"``.

    Keys are ``gyro_x`` ... ``accel_z`` or ``time`` (``t`` is accepted for
    ``time``); values are source column names as written in the file header
    (surrounding spaces are stripped).

    Raises
    ------
    OptionError
        On an empty map, an item without ``=``, an unknown or repeated key, an
        empty source name, or one source used for two keys.
    """
    if not text or not text.strip():
        raise OptionError("--columns is empty; give e.g. --columns gyro_x=wx,gyro_y=wy,time=stamp")
    out: dict[str, str] = {}
    for item in text.split(","):
        item = item.strip()
        if not item:
            raise OptionError(f"--columns {text!r} has an empty item; remove the extra comma")
        if "=" not in item:
            raise OptionError(
                f"--columns item {item!r} has no '='; write CANONICAL=SOURCE, e.g. gyro_x=wx"
            )
        key, _, src = item.partition("=")
        key = key.strip().lower()
        src = src.strip()
        if key == "t":
            key = TIME_KEY
        if key not in MAP_KEYS:
            raise OptionError(
                f"--columns key {key!r} is not known; use one of {', '.join(MAP_KEYS)}"
            )
        if not src:
            raise OptionError(f"--columns item {item!r} names no source column after '='")
        if key in out:
            raise OptionError(f"--columns gives {key} twice; give each key once")
        if src in out.values():
            other = next(k for k, v in out.items() if v == src)
            raise OptionError(
                f"--columns maps column {src!r} to both {other} and {key}; map it once"
            )
        out[key] = src
    return out


@dataclass(frozen=True)
class ColumnSpec:
    """One selected source column: its position, header text and stated unit."""

    index: int
    source: str
    unit: str | None
    layout: str


@dataclass(frozen=True)
class ColumnPlan:
    """Which source columns feed the time and each canonical channel."""

    time: ColumnSpec | None
    channels: dict[str, ColumnSpec]
    notes: tuple[str, ...] = ()

    def indices(self) -> list[int]:
        """Source column indices needed, time first."""
        idx = [] if self.time is None else [self.time.index]
        return idx + [c.index for c in self.channels.values()]


def _found(header: list[str], limit: int = 14) -> str:
    names = [repr(h) for h in header[:limit]]
    more = f" and {len(header) - limit} more" if len(header) > limit else ""
    return "[" + ", ".join(names) + "]" + more


def plan_columns(
    header: list[str],
    source: str,
    *,
    columns: Mapping[str, str] | None = None,
    channels: Sequence[str] | None = None,
) -> ColumnPlan:
    """Decide which header column feeds time and each canonical channel.

    Parameters
    ----------
    header:
        Column names as in the file.
    source:
        File name for messages.
    columns:
        Explicit map ``{canonical: source_column}`` that overrides recognition.
    channels:
        Restrict to these canonical channels (all present ones if ``None``).

    Raises
    ------
    OptionError
        A mapped source column is not in the header.
    InputError
        No IMU channel, an ambiguous channel, or a requested channel missing.
    """
    from imubounds.errors import InputError

    stripped = [h.strip() for h in header]
    columns = dict(columns or {})
    used: dict[int, str] = {}
    chosen: dict[str, ColumnSpec] = {}
    for key, src in columns.items():
        if key not in MAP_KEYS:
            raise OptionError(f"columns key {key!r} is not known; use one of {', '.join(MAP_KEYS)}")
        matches = [i for i, h in enumerate(stripped) if h == src.strip()]
        if not matches:
            matches = [i for i, h in enumerate(stripped) if h.lower() == src.strip().lower()]
        if not matches:
            raise OptionError(
                f"column {src!r} given for {key} in --columns is not in {source}; "
                f"found columns {_found(stripped)}"
            )
        if len(matches) > 1:
            raise OptionError(
                f"column {src!r} given for {key} in --columns appears {len(matches)} times in "
                f"{source}; rename the duplicates"
            )
        i = matches[0]
        if i in used:
            raise OptionError(f"--columns maps column {src!r} to both {used[i]} and {key}")
        used[i] = key
        rec = recognise(stripped[i])
        unit = None
        if key == TIME_KEY:
            _, br = split_bracket_unit(stripped[i])
            unit = rec.unit if rec is not None and rec.canonical == TIME_KEY else None
            if unit is None and br is not None:
                unit = normalise_unit(br, "time")
        else:
            kind = key.split("_")[0]
            if rec is not None and rec.canonical.startswith(kind):
                unit = rec.unit
            else:
                _, br = split_bracket_unit(stripped[i])
                if br is not None:
                    unit = normalise_unit(br, kind)
        chosen[key] = ColumnSpec(i, stripped[i], unit, "mapped")

    candidates: dict[str, list[ColumnSpec]] = {}
    for i, h in enumerate(stripped):
        if i in used:
            continue
        rec = recognise(h)
        if rec is None:
            continue
        candidates.setdefault(rec.canonical, []).append(ColumnSpec(i, h, rec.unit, rec.layout))

    notes: list[str] = []
    for key in MAP_KEYS:
        if key in chosen or key not in candidates:
            continue
        cands = candidates[key]
        if len(cands) > 1:
            if key == TIME_KEY:
                notes.append(
                    f"several time columns in {source} "
                    f"({', '.join(repr(c.source) for c in cands)}); used {cands[0].source!r}"
                )
            else:
                raise InputError(
                    f"columns {', '.join(repr(c.source) for c in cands)} of {source} all look "
                    f"like {key}; choose one with --columns {key}=NAME"
                )
        chosen[key] = cands[0]

    chan = {k: v for k, v in chosen.items() if k != TIME_KEY}
    if not chan:
        raise InputError(
            f"no IMU channel found in {source}: found columns {_found(stripped)}; name them "
            "gyro_x..gyro_z, accel_x..accel_z (optionally with a unit suffix such as _dps, _g) "
            "or map them with --columns gyro_x=NAME,..."
        )
    if channels is not None:
        missing = [c for c in channels if c not in chan]
        if missing:
            raise InputError(
                f"channel(s) {', '.join(missing)} not found in {source}: recognised "
                f"{', '.join(chan) or 'none'} among {_found(stripped)}; map them with --columns"
            )
        chan = {c: chan[c] for c in IMU_CHANNELS if c in channels}
    else:
        chan = {c: chan[c] for c in IMU_CHANNELS if c in chan}
    return ColumnPlan(chosen.get(TIME_KEY), chan, tuple(notes))
