"""The generic drive-log layout: a directory of CSV, CSV.gz or Parquet tables on one clock.

Every drive reader converts to this layout (``imubounds convert``) and
``imubounds dynamic DIR`` reads it directly. Files that are absent are simply
not used; all times are ``time_s`` in seconds on one clock. Each table may be
``NAME.csv``, ``NAME.csv.gz`` or ``NAME.parquet``. The layout is documented
with a complete example in ``docs/drive-layout.md``.

``imu.csv``
    ``time_s`` and any of ``gyro_{x,y,z}_<unit>`` (``rads``, ``dps``, ...) and
    ``accel_{x,y,z}_<unit>`` (``mps2``, ``g``, ``mg``), in the IMU's own axes;
    ``drive.yaml: imu_axes`` maps them to the vehicle body (x forward, y left,
    z up).
``gnss.csv``
    ``time_s, lat_deg, lon_deg``; optional ``alt_m, hdop, h_acc_m`` (1-sigma
    per horizontal axis, m), ``v_acc_m`` (1-sigma of the altitude, m), ``fix``
    (0 = no fix), ``speed_mps, course_deg`` (clockwise from true north),
    ``vel_n_mps, vel_e_mps, vel_acc_mps``.
``velocity.csv``
    body-frame velocity of a DVL or wheel/CAN speed: ``time_s, u_mps``,
    optional ``v_mps, w_mps`` and a text column ``kind`` (dvl, wheel, can,
    odometry).
``heading.csv``
    ``time_s, heading_deg`` (clockwise from north; ``drive.yaml heading:
    reference`` says magnetic or true, ``sensor`` compass, gnss or ahrs)
    and/or raw ``mag_{x,y,z}_<unit>`` (``T``, ``uT``, ``nT``, ``gauss``,
    ``raw``) in the IMU's axes (rotated by ``imu_axes``, or ``mag_axes``).
``attitude.csv``
    ``time_s, roll_deg, pitch_deg`` (optional ``yaw_deg``), roll positive right
    side down, pitch positive nose up, yaw clockwise from north; or a
    quaternion ``qw, qx, qy, qz`` body (FLU) -> ENU. The attitude of the
    vehicle body (not of a rotated sensor).
``truth.csv`` (optional)
    ``time_s`` with ``lat_deg, lon_deg`` or ``east_m, north_m`` (with
    ``origin_lat_deg, origin_lon_deg``, optional ``origin_alt_m``), optional
    ``heading_deg, u_mps, v_mps``; any further column is kept by name.
``drive.yaml``
    settings: ``imu_axes``, ``mag_axes``, ``imu``, ``gnss``, ``velocity``,
    ``heading``, ``attitude``, ``vehicle``, ``lever_arm_m`` (see
    :class:`~imubounds.io.drive.DriveSettings`), and two informational keys,
    ``converted_from`` and ``notes``. Unknown keys are an error naming the key;
    values are range-checked; a key left out takes its documented default and
    is listed as assumed.
"""

from __future__ import annotations

import dataclasses
import math
import shutil
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from imubounds.errors import InputError, OptionError
from imubounds.frames import axes_matrix, is_identity_axes, quaternion_to_rpy, rotate_axes
from imubounds.io.drive import (
    AttitudeStream,
    Drive,
    DriveSettings,
    GnssStream,
    HeadingStream,
    ImuStream,
    MagStream,
    Truth,
    VelocityStream,
)
from imubounds.io.drive.settings import (
    SETTINGS_FILE,
    parse_settings,
    read_settings,
    read_settings_with_info,
    settings_to_dict,
)
from imubounds.io.drive.validate import existing_file
from imubounds.io.validate import check_input_path
from imubounds.units import unit_factors

__all__ = [
    "FILES",
    "SETTINGS_FILE",
    "SUFFIXES",
    "TABLE_COLUMNS",
    "axes_matrix",
    "drive_from_tables",
    "release_freed_memory",
    "is_layout",
    "parse_settings",
    "quaternion_to_rpy_compass",
    "read_layout",
    "read_settings",
    "settings_to_dict",
    "write_layout",
]

FILES = ("imu", "gnss", "velocity", "heading", "attitude", "truth")
#: where :func:`write_layout` writes a swing calibration held in memory
CALIBRATION_FILE = "compass_cal.csv"
#: where :func:`write_layout` copies the static noise.json that ``imu.noise_json`` names
NOISE_FILE = "imu_noise.json"
#: every file :func:`write_layout` may write besides the tables
EXTRA_FILES = (CALIBRATION_FILE, NOISE_FILE)
SUFFIXES = (".csv", ".csv.gz", ".parquet")
FORMATS = {"csv": ".csv", "csv.gz": ".csv.gz", "parquet": ".parquet"}

#: The columns of each table (``<unit>`` columns by prefix); used for column maps.
TABLE_COLUMNS: dict[str, tuple[str, ...]] = {
    "imu": ("gyro_x_*", "gyro_y_*", "gyro_z_*", "accel_x_*", "accel_y_*", "accel_z_*"),
    "gnss": (
        "lat_deg",
        "lon_deg",
        "alt_m",
        "hdop",
        "h_acc_m",
        "fix",
        "speed_mps",
        "course_deg",
        "vel_n_mps",
        "vel_e_mps",
        "vel_acc_mps",
        "v_acc_m",
    ),
    "velocity": ("u_mps", "v_mps", "w_mps", "kind"),
    "heading": ("heading_deg", "mag_x_*", "mag_y_*", "mag_z_*"),
    "attitude": ("roll_deg", "pitch_deg", "yaw_deg", "qw", "qx", "qy", "qz"),
    "truth": (
        "lat_deg",
        "lon_deg",
        "east_m",
        "north_m",
        "origin_lat_deg",
        "origin_lon_deg",
        "origin_alt_m",
        "heading_deg",
        "u_mps",
        "v_mps",
    ),
}

_AXES = {"x": 0, "y": 1, "z": 2}
#: ``<unit>`` suffixes of the IMU columns -> factor to SI (the spellings of imubounds.units)
_GYRO_UNITS = unit_factors("gyro")
_ACCEL_UNITS = unit_factors("accel")
#: Magnetometer units -> tesla ("raw": counts of unknown scale, kept as they are).
MAG_UNITS = {
    "t": 1.0,
    "ut": 1e-6,
    "nt": 1e-9,
    "gauss": 1e-4,
    "g": 1e-4,
    "mgauss": 1e-7,
    "raw": 1.0,
}


def quaternion_to_rpy_compass(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body (FLU) -> ENU quaternions (w, x, y, z) -> roll, pitch, compass yaw (rad)."""
    return quaternion_to_rpy(q)


# ----------------------------------------------------------------------------- settings

def _find(d: Path, stem: str) -> Path | None:
    """The table of stream ``stem`` in ``d``; two files for one stream are refused."""
    import os

    found = [f"{stem}{s}" for s in SUFFIXES if os.path.lexists(d / f"{stem}{s}")]
    if len(found) > 1:
        raise InputError(
            f"{d}: {' and '.join(found)} are two files for the {stem} stream; keep one "
            "(move or delete the other)"
        )
    return existing_file(d, stem, SUFFIXES)


#: Suffixes of files that look like data tables (a stray one is reported as ignored).
_TABLE_LIKE = (".csv", ".csv.gz", ".parquet", ".tsv", ".gz", ".npy")


def ignored_files(d: Path, settings: DriveSettings) -> list[str]:
    """Data files in the layout folder ``d`` that no stream reads (``gps.csv``): not a
    layout table, not named by ``drive.yaml`` and not an output an imubounds run
    recorded there (``run.json``)."""
    from imubounds.io.outputs import recorded_files

    used = {SETTINGS_FILE, "scenario.json", "run.json"}
    for name in FILES:
        used |= {f"{name}{s}" for s in SUFFIXES}
    for ref in (settings.imu.noise_json, settings.heading.calibration):
        if isinstance(ref, str):
            used.add(Path(ref).name)
    used |= recorded_files(d)
    out = []
    try:
        entries = sorted(p.name for p in d.iterdir() if p.is_file())
    except OSError:
        return []
    for name in entries:
        if name in used or name.startswith("."):
            continue
        if name.lower().endswith(_TABLE_LIKE):
            out.append(name)
    return out


def release_freed_memory() -> None:
    """Give the memory the reading freed back to the system (glibc's ``malloc_trim``;
    nothing elsewhere): the tables, their conversions and the checks leave freed heap
    that the process would otherwise keep (0.6 GB on a 24 h trip at 100 Hz under the
    command line's malloc settings, :func:`imubounds.runtime.tune_malloc`). Only freed
    memory is returned: no value changes."""
    import ctypes
    import ctypes.util

    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        trim = libc.malloc_trim
    except (OSError, AttributeError):  # musl or another libc
        return
    trim.argtypes = [ctypes.c_size_t]
    trim.restype = ctypes.c_int
    trim(0)


def _read_parquet(path: Path) -> pd.DataFrame:
    """``pd.read_parquet`` with one block per column, the Arrow buffers released while
    they are converted (pandas >= 3: ``to_pandas_kwargs``): a column taken from the frame
    keeps only itself alive, not the whole table (a 24 h IMU table is 0.5 GB)."""
    import inspect

    import pyarrow as pa

    kw: dict[str, Any] = {}
    if "to_pandas_kwargs" in inspect.signature(pd.read_parquet).parameters:
        kw["to_pandas_kwargs"] = {"split_blocks": True, "self_destruct": True}
    # the system allocator, trimmed after: Arrow's default pool (mimalloc) keeps most of
    # what the decoding freed (about the table's size again) long after the read
    pool = pa.system_memory_pool()
    before = pa.default_memory_pool()
    pa.set_memory_pool(pool)
    try:
        df = pd.read_parquet(path, **kw)
    finally:
        pa.set_memory_pool(before)
    release_freed_memory()
    return df


def read_table(path: Path) -> pd.DataFrame:
    """One layout table (CSV, CSV.gz or Parquet) with a ``time_s`` column and >= 1 row."""
    import zlib

    check_input_path(path, what="drive table")
    try:
        if path.name.endswith(".parquet"):
            df = _read_parquet(path)
        else:
            df = pd.read_csv(path, comment="#", skipinitialspace=True)
    except EOFError as err:
        raise InputError(
            f"{path}: the compressed file ends early (cut off while it was written or "
            "copied); copy it again or decompress what is left"
        ) from err
    except pd.errors.ParserError as err:
        first = (str(err).splitlines() or [type(err).__name__])[0]
        raise InputError(
            f"{path}: cannot read as a table ({first}): a row has more fields than the "
            "header; fix or remove that row"
        ) from err
    except (OSError, ValueError, ImportError, zlib.error) as err:
        first = (str(err).splitlines() or [type(err).__name__])[0]
        raise InputError(f"{path}: cannot read as a table ({first})") from err
    df.columns = [str(c).strip() for c in df.columns]
    dup = sorted({c for c in df.columns if list(df.columns).count(c) > 1})
    if dup:
        raise InputError(f"{path}: column {dup[0]} appears twice; keep one")
    if "time_s" not in df.columns:
        raise InputError(
            f"{path}: no time_s column (found: {', '.join(df.columns[:12]) or 'no columns'}); "
            "the first column must be time_s, the time in seconds"
        )
    if df.shape[0] == 0:
        raise InputError(f"{path}: no data rows (only a header)")
    return df


def _col(df: pd.DataFrame, name: str, where: str, required: bool = False) -> np.ndarray | None:
    if name not in df.columns:
        if required:
            raise InputError(
                f"{where}: missing column {name} (found: {', '.join(df.columns[:12])})"
            )
        return None
    raw = df[name]
    dtype = raw.dtype
    if pd.api.types.is_bool_dtype(dtype) and name != "fix":
        raise InputError(
            f"{where}: column {name} holds booleans (true/false), not numbers; write the "
            "values in the unit of the column name"
        )
    if pd.api.types.is_datetime64_any_dtype(dtype):
        raise InputError(
            f"{where}: column {name} holds dates and times ({dtype}), not seconds; write "
            "seconds on the drive's one clock (e.g. (t - t0) / 1 s, as in every table)"
        )
    if pd.api.types.is_timedelta64_dtype(dtype):
        return np.asarray(raw.dt.total_seconds().to_numpy(float))  # durations: in s
    if pd.api.types.is_complex_dtype(dtype):
        raise InputError(f"{where}: column {name} holds complex numbers; write real values")
    if pd.api.types.is_numeric_dtype(dtype):  # parsed as numbers already
        return raw.to_numpy(float)
    is_bool = raw.map(lambda x: isinstance(x, bool | np.bool_))
    if is_bool.any():
        i = int(np.flatnonzero(is_bool.to_numpy())[0])
        raise InputError(
            f"{where}: column {name}, data row {i + 1}: {raw.iloc[i]!r} is a boolean, not a "
            "number"
        )
    v = pd.to_numeric(raw, errors="coerce")
    bad = v.isna() & raw.notna() & (raw.astype(str).str.strip().str.lower() != "nan")
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise InputError(
            f"{where}: column {name}, data row {i + 1}: {raw.iloc[i]!r} is not a number"
        )
    return v.to_numpy(float)


def _req(df: pd.DataFrame, name: str, where: str) -> np.ndarray:
    a = _col(df, name, where, required=True)
    assert a is not None
    return a


def _time(df: pd.DataFrame, where: str) -> np.ndarray:
    t = _req(df, "time_s", where)
    if not np.all(np.isfinite(t)):
        i = int(np.flatnonzero(~np.isfinite(t))[0])
        raise InputError(f"{where}: time_s is empty, NaN or infinite at data row {i + 1}")
    return t


def _unit_columns(
    df: pd.DataFrame, prefix: str, units: Mapping[str, float], where: str
) -> tuple[np.ndarray | None, str | None]:
    """Columns ``<prefix>_{x,y,z}_<unit>`` -> (n, 3) SI array (NaN for absent axes) and unit."""
    found: dict[int, tuple[str, str]] = {}
    for c in df.columns:
        for ax, i in _AXES.items():
            head = f"{prefix}_{ax}_"
            if c.lower().startswith(head):
                if i in found:
                    raise InputError(
                        f"{where}: two columns for {prefix}_{ax} ({found[i][0]}, {c}); keep one"
                    )
                found[i] = (c, c[len(head) :])
    if not found:
        return None, None
    out = np.full((df.shape[0], 3), np.nan)
    units_seen = set()
    for i, (c, unit) in found.items():
        key = unit.lower()
        if key not in units:
            raise InputError(
                f"{where}: column {c}: unknown unit {unit!r}; use one of {', '.join(units)}"
            )
        np.multiply(_req(df, c, where), units[key], out=out[:, i])
        units_seen.add(key)
    if len(units_seen) > 1:
        raise InputError(
            f"{where}: the {prefix} columns mix units ({', '.join(sorted(units_seen))}); "
            "give every axis in one unit"
        )
    return out, units_seen.pop()


def _rows_with_data(df: pd.DataFrame, table: str) -> pd.DataFrame:
    """Rows of a wide table that carry at least one value of ``table``'s columns."""
    cols = [c for c in df.columns if _belongs(c, table)]
    if not cols:
        return df.iloc[0:0]
    keep = df[cols].notna().any(axis=1)
    return df.loc[keep].reset_index(drop=True)


def _belongs(col: str, table: str) -> bool:
    for pat in TABLE_COLUMNS[table]:
        if pat.endswith("*") and col.lower().startswith(pat[:-1]):
            return True
        if col == pat:
            return True
    return False


def imu_from_table(df: pd.DataFrame, where: str, rot: np.ndarray) -> ImuStream:
    """``imu`` table -> :class:`ImuStream` in the body frame (``rot``: sensor -> body)."""
    t = _time(df, where)
    gyro, gu = _unit_columns(df, "gyro", _GYRO_UNITS, where)
    acc, au = _unit_columns(df, "accel", _ACCEL_UNITS, where)
    if gyro is None and acc is None:
        raise InputError(
            f"{where}: no IMU columns; expected gyro_{{x,y,z}}_<unit> (rads, dps) and/or "
            "accel_{x,y,z}_<unit> (mps2, g)"
        )
    n = df.shape[0]
    gyro = np.full((n, 3), np.nan) if gyro is None else gyro
    acc = np.full((n, 3), np.nan) if acc is None else acc
    if not np.array_equal(rot, np.eye(3)):  # the identity: the values as they are
        acc, gyro = rotate_axes(acc, rot), rotate_axes(gyro, rot)
    return ImuStream(
        t=t,
        accel=acc,
        gyro=gyro,
        input_units={"gyro": gu or "", "accel": au or ""},
    )


def gnss_from_table(df: pd.DataFrame, where: str) -> GnssStream:
    """``gnss`` table -> :class:`GnssStream` (course in rad, ``fix`` as booleans)."""
    if "lat_deg" not in df.columns or "lon_deg" not in df.columns:
        raise InputError(
            f"{where}: GNSS needs columns time_s, lat_deg, lon_deg (found: "
            f"{', '.join(df.columns[:12])})"
        )
    course = _col(df, "course_deg", where)
    fix = _col(df, "fix", where)
    return GnssStream(
        t=_time(df, where),
        lat_deg=_req(df, "lat_deg", where),
        lon_deg=_req(df, "lon_deg", where),
        alt_m=_col(df, "alt_m", where),
        hdop=_col(df, "hdop", where),
        h_acc_m=_col(df, "h_acc_m", where),
        fix=None if fix is None else (np.nan_to_num(fix, nan=0.0) != 0),
        speed_mps=_col(df, "speed_mps", where),
        course_rad=None if course is None else np.mod(np.radians(course), 2 * math.pi),
        vel_n_mps=_col(df, "vel_n_mps", where),
        vel_e_mps=_col(df, "vel_e_mps", where),
        vel_acc_mps=_col(df, "vel_acc_mps", where),
        v_acc_m=_col(df, "v_acc_m", where),
    )


def velocity_from_table(df: pd.DataFrame, where: str) -> VelocityStream:
    """``velocity`` table -> :class:`VelocityStream` (``kind`` column, default dvl)."""
    kind = "dvl"
    if "kind" in df.columns:
        kinds = {str(k).strip().lower() for k in df["kind"].dropna()}
        if len(kinds) > 1:
            raise InputError(f"{where}: column kind holds several sensors ({', '.join(kinds)})")
        if kinds:
            kind = kinds.pop()
        if kind not in ("dvl", "wheel", "can", "odometry"):
            raise InputError(f"{where}: kind {kind!r}; use dvl, wheel, can or odometry")
    if "u_mps" not in df.columns:
        raise InputError(
            f"{where}: a velocity sensor needs columns time_s, u_mps (optional v_mps, w_mps)"
        )
    return VelocityStream(
        t=_time(df, where),
        u_mps=_req(df, "u_mps", where),
        v_mps=_col(df, "v_mps", where),
        w_mps=_col(df, "w_mps", where),
        kind=kind,
    )


def heading_from_table(
    df: pd.DataFrame, where: str, settings: DriveSettings, mag_rot: np.ndarray, drive: Drive
) -> tuple[HeadingStream | None, MagStream | None]:
    """``heading`` table -> (heading stream, magnetometer stream); NaN rows are dropped
    and counted in ``drive``."""
    t = _time(df, where)
    h = _col(df, "heading_deg", where)
    mag, mu = _unit_columns(df, "mag", MAG_UNITS, where)
    if h is None and mag is None:
        raise InputError(
            f"{where}: expected heading_deg and/or mag_{{x,y,z}}_<unit> columns (found: "
            f"{', '.join(df.columns[:12])})"
        )
    hs = ms = None
    if h is not None:
        ok = np.isfinite(h)
        nb = int((~ok).sum())
        if nb and mag is None:
            drive.warn("heading_nan", nb, f"{where}: {nb} row(s) with NaN heading_deg skipped")
        elif nb and mag is not None:
            # rows of the magnetometer only carry no heading; count the others
            lost = int((~ok & ~np.isfinite(mag).any(axis=1)).sum())
            drive.warn("heading_nan", lost, f"{where}: {lost} row(s) with neither heading_deg "
                       "nor a magnetometer value skipped")
        if ok.any():
            hs = HeadingStream(
                t=t[ok],
                heading_rad=np.mod(np.radians(h[ok]), 2 * math.pi),
                source=settings.heading.sensor,
                true_north=settings.heading.reference == "true",
            )
        elif mag is None:
            raise InputError(f"{where}: heading_deg has no finite value in {t.size} row(s)")
    if mag is not None:
        rows = np.ones(t.size, bool) if h is None else np.isfinite(mag).any(axis=1)
        if rows.any():
            ms = MagStream(
                t=t[rows], mag=rotate_axes(mag[rows], mag_rot), unit="raw" if mu == "raw" else "T"
            )
        elif hs is None:
            raise InputError(f"{where}: the magnetometer columns have no finite value")
    return hs, ms


def attitude_from_table(df: pd.DataFrame, where: str) -> AttitudeStream:
    """``attitude`` table (degrees or a body->ENU quaternion) -> :class:`AttitudeStream`."""
    t = _time(df, where)
    if "roll_deg" in df.columns or "pitch_deg" in df.columns:
        yaw = _col(df, "yaw_deg", where)
        return AttitudeStream(
            t=t,
            roll_rad=np.radians(_req(df, "roll_deg", where)),
            pitch_rad=np.radians(_req(df, "pitch_deg", where)),
            yaw_rad=None if yaw is None else np.mod(np.radians(yaw), 2 * math.pi),
        )
    if "qw" in df.columns:
        q = np.column_stack([_req(df, k, where) for k in ("qw", "qx", "qy", "qz")])
        norm = np.linalg.norm(q, axis=1)
        bad = ~(np.isfinite(norm) & (norm > 0.5) & (norm < 1.5))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise InputError(
                f"{where}: quaternion at data row {i + 1} has norm {norm[i]:g}; expected unit "
                "quaternions (qw, qx, qy, qz)"
            )
        roll, pitch, yaw = quaternion_to_rpy(q)
        return AttitudeStream(t=t, roll_rad=roll, pitch_rad=pitch, yaw_rad=yaw)
    raise InputError(f"{where}: expected roll_deg, pitch_deg (or qw, qx, qy, qz) columns")


def truth_from_table(df: pd.DataFrame, where: str) -> Truth:
    """``truth`` table -> :class:`Truth` (ENU of its origin; extra columns kept by name)."""
    from imubounds.geodesy import geodetic_to_enu

    t = _time(df, where)
    used = {"time_s"}
    if "east_m" in df.columns:
        e, n = _req(df, "east_m", where), _req(df, "north_m", where)
        if "origin_lat_deg" in df.columns:
            # origin_alt_m left out: NaN, not 0 (the truth check then takes the GNSS
            # origin's altitude rather than the ellipsoid's surface)
            origin = (
                float(_req(df, "origin_lat_deg", where)[0]),
                float(_req(df, "origin_lon_deg", where)[0]),
                float(_req(df, "origin_alt_m", where)[0]) if "origin_alt_m" in df.columns
                else math.nan,
            )
        else:
            origin = (math.nan, math.nan, math.nan)
        used |= {"east_m", "north_m", "origin_lat_deg", "origin_lon_deg", "origin_alt_m"}
    elif "lat_deg" in df.columns:
        lat, lon = _req(df, "lat_deg", where), _req(df, "lon_deg", where)
        alt = _col(df, "alt_m", where)
        first = int(np.argmax(np.isfinite(lat) & np.isfinite(lon)))
        org0 = None
        if alt is not None and np.isfinite(alt[first]):
            org0 = (float(lat[first]), float(lon[first]), float(alt[first]))
        e, n, org = geodetic_to_enu(lat, lon, alt if org0 is not None else None,
                                    origin=org0 or (float(lat[first]), float(lon[first]), 0.0))
        origin = (float(org[0]), float(org[1]), float(org[2]) if org0 else math.nan)
        used |= {"lat_deg", "lon_deg"}
        if org0 is not None and alt is not None:
            used.add("alt_m")
            up = alt - org0[2]  # the truth's height over its origin (the truth check uses it)
    else:
        raise InputError(f"{where}: truth needs lat_deg, lon_deg or east_m, north_m")
    hd = _col(df, "heading_deg", where)
    used |= {"heading_deg", "u_mps", "v_mps"}
    extra = {c: _col(df, c, where) for c in df.columns if c not in used}
    if "alt_m" in used and "up_m" not in extra:
        extra["up_m"] = up
    return Truth(
        t=t,
        east_m=e,
        north_m=n,
        origin=origin,
        heading_rad=None if hd is None else np.mod(np.radians(hd), 2 * math.pi),
        u_mps=_col(df, "u_mps", where),
        v_mps=_col(df, "v_mps", where),
        extra={k: v for k, v in extra.items() if v is not None},
    )


def _warn_empty_columns(drive: Drive, df: pd.DataFrame, where: str) -> None:
    """An IMU column that is there but holds no value (every row empty or NaN): the axis
    is absent (not analysed), which the file does not say: a counted warning naming it."""
    cols = [c for c in df.columns if c.lower().startswith(("gyro_", "accel_"))]
    for c in cols:
        v = pd.to_numeric(df[c], errors="coerce").to_numpy(float)
        if v.size and not np.isfinite(v).any():
            axis = "_".join(c.split("_")[:2])
            drive.warn(
                "imu_column_empty", 1,
                f"{where}: column {c} holds no value in any of its {v.size} rows (empty or "
                f"NaN): {axis} is treated as absent (not analysed: no samples); fill it or drop "
                "the column",
            )


def drive_from_tables(
    tables: Mapping[str, tuple[pd.DataFrame, str]],
    settings: DriveSettings,
    *,
    source: str,
    layout: str,
    wide: bool = False,
) -> Drive:
    """Build a :class:`Drive` from layout tables ``{name: (frame, where)}``.

    The IMU (and the magnetometer) are rotated into the body frame by
    ``settings.imu_axes`` (``mag_axes``) before anything else. ``wide``: the
    tables are one wide log, so each keeps only the rows that carry its columns.
    """
    drive = Drive(settings=settings, source=source, layout=layout)
    rot = axes_matrix(settings.imu_axes)
    mag_rot = axes_matrix(settings.mag_axes) if settings.mag_axes is not None else rot
    files: dict[str, str] = {}
    for name, (df, where) in tables.items():
        if name not in FILES:
            raise InputError(f"{where}: unknown drive table {name!r}; use {', '.join(FILES)}")
        if wide:
            df = _rows_with_data(df, name)
            if df.shape[0] == 0:
                continue
        files[name] = where
        if name == "imu":
            drive.imu = imu_from_table(df, where, rot)
            _warn_empty_columns(drive, df, where)
        elif name == "gnss":
            drive.gnss = gnss_from_table(df, where)
        elif name == "velocity":
            drive.velocity = velocity_from_table(df, where)
        elif name == "heading":
            drive.heading, drive.mag = heading_from_table(df, where, settings, mag_rot, drive)
        elif name == "attitude":
            drive.attitude = attitude_from_table(df, where)
        else:
            drive.truth = truth_from_table(df, where)
        del df  # not held while the next table is read
    drive.meta["files"] = files
    if not is_identity_axes(settings.imu_axes):
        drive.notes.append(
            f"IMU mount: imu_axes {list(settings.imu_axes)} applied (sensor axes rotated into "
            "the body frame x forward, y left, z up)"
        )
    return drive


# ----------------------------------------------------------------------------- reading


class _LazyTables(Mapping[str, tuple[pd.DataFrame, str]]):
    """``{name: (frame, path)}`` whose frames are read (:func:`read_table`) when asked
    for and not kept."""

    def __init__(self, paths: dict[str, str]) -> None:
        self._paths = paths

    def __getitem__(self, name: str) -> tuple[pd.DataFrame, str]:
        p = self._paths[name]
        return read_table(Path(p)), p

    def __iter__(self) -> Any:
        return iter(self._paths)

    def __len__(self) -> int:
        return len(self._paths)


def read_layout(directory: str | Path, settings: DriveSettings | None = None) -> Drive:
    """Read a drive-layout directory into a :class:`Drive` (SI, body frame FLU).

    ``settings`` replaces ``drive.yaml`` when given (command-line overrides are
    applied by the caller on the parsed settings). The drive is not validated
    here: :func:`imubounds.io.read_drive` validates it.
    """
    d = check_input_path(directory, what="drive-layout directory", need_dir=True)
    info: dict[str, Any] = {}
    if settings is None:
        settings, info = read_settings_with_info(d)
    found = {name: p for name in FILES if (p := _find(d, name)) is not None}
    if not found:
        raise InputError(
            f"{d}: no drive table; expected imu.csv (time_s, gyro_{{x,y,z}}_<unit>, "
            "accel_{x,y,z}_<unit>) and at least one of gnss.csv, velocity.csv, heading.csv"
        )
    # each table read when its stream is built and dropped after (one table in memory)
    tables = _LazyTables({name: str(p) for name, p in found.items()})
    drive = drive_from_tables(tables, settings, source=str(d), layout="generic")
    stray = ignored_files(d, settings)
    if stray:
        drive.warn(
            "layout_ignored_files",
            len(stray),
            f"{d}: {len(stray)} file(s) match no stream of the drive layout and are ignored: "
            f"{', '.join(stray[:5])}{' ...' if len(stray) > 5 else ''} (the tables are "
            f"{', '.join(FILES)}; rename a table to its stream's name)",
        )
    if info.get("notes"):
        drive.notes[:0] = [str(n) for n in info["notes"]]
    if info.get("converted_from"):
        drive.meta["converted_from"] = str(info["converted_from"])
    return drive


def is_layout(d: Path) -> bool:
    """True if ``d`` looks like a drive-layout directory (an ``imu`` table or ``drive.yaml``)."""
    if not d.is_dir() or (d / "scenario.json").is_file() and (d / "gps.csv").is_file():
        return False
    return any((d / f"imu{s}").exists() for s in SUFFIXES) or (d / SETTINGS_FILE).is_file()


# ----------------------------------------------------------------------------- writing


def write_layout(drive: Drive, directory: str | Path, fmt: str = "csv") -> Path:
    """Write ``drive`` as a drive-layout directory (``fmt``: csv, csv.gz or parquet).

    The IMU is written in body axes, so ``drive.yaml`` says ``imu_axes: [x, y,
    z]`` and the notes record the mount that was applied. Settings that took
    their default are left out of ``drive.yaml`` (they stay assumed). The
    caller handles atomic placement (see :mod:`imubounds.io.outputs`).
    """
    import yaml

    if fmt not in FORMATS:
        raise OptionError(f"format {fmt!r}: use one of {', '.join(FORMATS)}")
    suffix = FORMATS[fmt]
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)

    def put(name: str, cols: dict[str, Any]) -> None:
        df = pd.DataFrame({k: v for k, v in cols.items() if v is not None})
        path = d / f"{name}{suffix}"
        if fmt == "parquet":
            df.to_parquet(path, index=False)
        else:
            df.to_csv(path, index=False)  # shortest repr: reads back bit for bit

    if drive.imu is not None:
        cols: dict[str, Any] = {"time_s": drive.imu.t}
        for kind, arr, unit in (("gyro", drive.imu.gyro, "rads"), ("accel", drive.imu.accel,
                                                                     "mps2")):
            for i, ax in enumerate("xyz"):
                if np.any(np.isfinite(arr[:, i])):
                    cols[f"{kind}_{ax}_{unit}"] = arr[:, i]
        put("imu", cols)
    g = drive.gnss
    if g is not None:
        put(
            "gnss",
            {
                "time_s": g.t,
                "lat_deg": g.lat_deg,
                "lon_deg": g.lon_deg,
                "alt_m": g.alt_m,
                "hdop": g.hdop,
                "h_acc_m": g.h_acc_m,
                "fix": None if g.fix is None else g.fix.astype(int),
                "speed_mps": g.speed_mps,
                "course_deg": None if g.course_rad is None else np.degrees(g.course_rad),
                "vel_n_mps": g.vel_n_mps,
                "vel_e_mps": g.vel_e_mps,
                "vel_acc_mps": g.vel_acc_mps,
                "v_acc_m": g.v_acc_m,
            },
        )
    v = drive.velocity
    if v is not None:
        put(
            "velocity",
            {
                "time_s": v.t,
                "u_mps": v.u_mps,
                "v_mps": v.v_mps,
                "w_mps": v.w_mps,
                "kind": np.full(v.t.size, v.kind),
            },
        )
    settings = dataclasses.replace(
        drive.settings,
        imu_axes=("x", "y", "z"),
        mag_axes=None,
        heading=dataclasses.replace(drive.settings.heading),
        defaulted=list(drive.settings.defaulted),
    )
    if drive.heading is not None or drive.mag is not None:
        _put_heading(drive, put, settings)
    cal = settings.heading.calibration
    if isinstance(cal, np.ndarray):  # swing pairs held in memory: written beside
        pd.DataFrame({"measured_deg": cal[:, 0], "reference_deg": cal[:, 1]}).to_csv(
            d / CALIBRATION_FILE, index=False, float_format="%.17g"
        )
        settings.heading.calibration = CALIBRATION_FILE
    elif isinstance(cal, str):  # a file: copied beside, so that the layout is self-contained
        shutil.copyfile(cal, d / CALIBRATION_FILE)
        settings.heading.calibration = CALIBRATION_FILE
    noise = settings.imu.noise_json
    if noise is not None:
        settings.imu = dataclasses.replace(settings.imu)
        shutil.copyfile(noise, d / NOISE_FILE)
        settings.imu.noise_json = NOISE_FILE
    a = drive.attitude
    if a is not None:
        put(
            "attitude",
            {
                "time_s": a.t,
                "roll_deg": np.degrees(a.roll_rad),
                "pitch_deg": np.degrees(a.pitch_rad),
                "yaw_deg": None if a.yaw_rad is None else np.degrees(a.yaw_rad),
            },
        )
    tr = drive.truth
    if tr is not None:
        cols = {
            "time_s": tr.t,
            "east_m": tr.east_m,
            "north_m": tr.north_m,
            "origin_lat_deg": np.full(tr.t.size, tr.origin[0]),
            "origin_lon_deg": np.full(tr.t.size, tr.origin[1]),
            **({"origin_alt_m": np.full(tr.t.size, tr.origin[2])}
               if math.isfinite(tr.origin[2]) else {}),
            "heading_deg": None if tr.heading_rad is None else np.degrees(tr.heading_rad),
            "u_mps": tr.u_mps,
            "v_mps": tr.v_mps,
        }
        cols.update(tr.extra)
        put("truth", cols)
    doc = settings_to_dict(settings)
    doc["converted_from"] = drive.meta.get("converted_from", drive.source)
    notes = [*drive.notes, *(f"when converted: {w}" for w in drive.warnings
                             if f"when converted: {w}" not in drive.notes)]
    if notes:
        doc["notes"] = notes
    header = (
        "# drive settings (imubounds drive layout, docs/drive-layout.md); settings left out\n"
        "# take their documented default and are listed as assumed by every output\n"
    )
    (d / SETTINGS_FILE).write_text(
        header + yaml.safe_dump(doc, sort_keys=False, allow_unicode=True), encoding="utf-8"
    )
    return d


def _put_heading(drive: Drive, put: Any, settings: DriveSettings) -> None:
    h, m = drive.heading, drive.mag
    if h is not None:
        # say what the heading column is when it is not the default (a magnetic compass)
        sensor = h.source if h.source in ("compass", "gnss", "ahrs") else "compass"
        reference = "true" if h.true_north else "magnetic"
        for key, value, default in (("sensor", sensor, "compass"),
                                    ("reference", reference, "magnetic")):
            setattr(settings.heading, key, value)
            if value != default and f"heading.{key}" in settings.defaulted:
                settings.defaulted.remove(f"heading.{key}")
    if h is not None and m is not None and not np.array_equal(h.t, m.t):
        t = np.union1d(h.t, m.t)
        hh: np.ndarray | None = np.full(t.size, np.nan)
        hh[np.searchsorted(t, h.t)] = np.degrees(h.heading_rad)  # type: ignore[index]
        mm: np.ndarray | None = np.full((t.size, 3), np.nan)
        mm[np.searchsorted(t, m.t)] = m.mag  # type: ignore[index]
    else:
        t = h.t if h is not None else m.t  # type: ignore[union-attr]
        hh = None if h is None else np.degrees(h.heading_rad)
        mm = None if m is None else m.mag
    cols: dict[str, Any] = {"time_s": t, "heading_deg": hh}
    if mm is not None:
        unit = "raw" if m is not None and m.unit.lower() == "raw" else "T"
        for i, ax in enumerate("xyz"):
            cols[f"mag_{ax}_{unit}"] = mm[:, i]
    put("heading", cols)
