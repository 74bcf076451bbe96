"""The generic drive-log layout: a directory of CSV (or Parquet) files on one clock.

Every drive reader converts to this layout (``imubounds convert``) and
``imubounds dynamic DIR`` reads it directly. Files that are absent are simply
not used; all times are ``time_s`` in seconds on one clock.

``imu.csv``
    ``time_s`` and any of ``gyro_{x,y,z}_<unit>`` (``rads``, ``dps``, ...) and
    ``accel_{x,y,z}_<unit>`` (``mps2``, ``g``, ``mg``), in the IMU's own axes;
    ``drive.yaml: imu_axes`` maps them to the vehicle body (x forward, y left,
    z up).
``gnss.csv``
    ``time_s, lat_deg, lon_deg``; optional ``alt_m, hdop, h_acc_m`` (1-sigma
    horizontal, m), ``fix`` (0 = no fix), ``speed_mps, course_deg`` (clockwise
    from north), ``vel_n_mps, vel_e_mps``.
``velocity.csv``
    body-frame velocity of a DVL or wheel/CAN speed: ``time_s, u_mps``,
    optional ``v_mps, w_mps``.
``heading.csv``
    ``time_s, heading_deg`` (clockwise from north) and/or raw
    ``mag_{x,y,z}_<unit>`` in the vehicle body axes.
``attitude.csv``
    ``time_s, roll_deg, pitch_deg`` (optional ``yaw_deg``), roll positive right
    side down, pitch positive nose up; or a quaternion ``qw, qx, qy, qz``
    body (FLU) -> ENU.
``truth.csv`` (optional)
    ``time_s`` with ``lat_deg, lon_deg`` or ``east_m, north_m``, optional
    ``heading_deg, u_mps, v_mps``; any further column is kept by name.
``drive.yaml``
    settings: ``imu_axes``, ``imu``, ``gnss``, ``velocity``, ``heading``,
    ``attitude``, ``vehicle``, ``lever_arm_m`` (see :class:`DriveSettings`).
    Unknown keys are an error naming the key.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from imubounds.errors import InputError
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
from imubounds.units import ACCEL_UNITS, GYRO_UNITS

FILES = ("imu", "gnss", "velocity", "heading", "attitude", "truth")
SETTINGS_FILE = "drive.yaml"
_AXES = {"x": 0, "y": 1, "z": 2}


# ----------------------------------------------------------------------------- mount


def axes_matrix(imu_axes: tuple[str, str, str] | list[str]) -> np.ndarray:
    """The 3x3 signed permutation taking IMU axes to body axes for an ``imu_axes`` mapping.

    ``imu_axes[i]`` names the signed IMU axis that points along body axis i
    (x forward, y left, z up): ``["x", "-z", "y"]`` means body x = IMU x,
    body y = -IMU z, body z = IMU y. The result must be a proper rotation.
    """
    if len(imu_axes) != 3:
        raise InputError(f"imu_axes must name 3 axes, e.g. [x, -z, y]; got {list(imu_axes)}")
    m = np.zeros((3, 3))
    for i, a in enumerate(imu_axes):
        text = str(a).strip().lower()
        sign = -1.0 if text.startswith("-") else 1.0
        name = text.lstrip("+-")
        if name not in _AXES:
            raise InputError(f"imu_axes entry {a!r}: use x, y, z with an optional sign")
        m[i, _AXES[name]] = sign
    if not np.allclose(m @ m.T, np.eye(3)) or not math.isclose(np.linalg.det(m), 1.0):
        raise InputError(
            f"imu_axes {list(imu_axes)} is not a rotation (each IMU axis once, right-handed)"
        )
    return m


# ----------------------------------------------------------------------------- settings


def _section(cls: type, data: Any, where: str, assumed: list[str]) -> Any:
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise InputError(f"{where}: must be a mapping of settings")
    names = {f.name for f in dataclasses.fields(cls)}
    for k in data:
        if k not in names:
            raise InputError(f"{where}: unknown key {k!r}; known: {', '.join(sorted(names))}")
    obj = cls(**data)
    for f in dataclasses.fields(cls):
        if f.name not in data:
            assumed.append(f"{where}.{f.name} = {getattr(obj, f.name)!r} (default)")
    return obj


def parse_settings(data: Any, where: str = SETTINGS_FILE) -> DriveSettings:
    """``drive.yaml`` contents -> :class:`DriveSettings`; unknown keys are an error."""
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise InputError(f"{where}: must be a mapping (key: value lines)")
    known = {f.name for f in dataclasses.fields(DriveSettings) if f.name != "assumed"}
    for k in data:
        if k not in known:
            raise InputError(f"{where}: unknown key {k!r}; known: {', '.join(sorted(known))}")
    assumed: list[str] = []
    kw: dict[str, Any] = {}
    for f in dataclasses.fields(DriveSettings):
        if f.name in ("assumed", "imu_axes", "lever_arm_m"):
            continue
        cls = type(getattr(DriveSettings(), f.name))
        kw[f.name] = _section(cls, data.get(f.name), f"{where}: {f.name}", assumed)
    axes = data.get("imu_axes", ["x", "y", "z"])
    axes_matrix(axes)
    kw["imu_axes"] = tuple(str(a) for a in axes)
    if "imu_axes" not in data:
        assumed.append(f"{where}: imu_axes = [x, y, z] (IMU axes are the body axes; default)")
    lever = data.get("lever_arm_m")
    if lever is not None:
        try:
            lv = tuple(float(x) for x in lever)
        except (TypeError, ValueError) as err:
            raise InputError(f"{where}: lever_arm_m must be [x, y, z] in m") from err
        if len(lv) != 3:
            raise InputError(f"{where}: lever_arm_m must be [x, y, z] in m")
        kw["lever_arm_m"] = lv
    return DriveSettings(**kw, assumed=assumed)


def settings_to_dict(s: DriveSettings) -> dict[str, Any]:
    """:class:`DriveSettings` -> a mapping ``drive.yaml`` can hold (no ``assumed``)."""
    d = dataclasses.asdict(s)
    d.pop("assumed", None)
    d["imu_axes"] = list(s.imu_axes)
    if s.lever_arm_m is None:
        d.pop("lever_arm_m")
    else:
        d["lever_arm_m"] = list(s.lever_arm_m)
    return d


# ----------------------------------------------------------------------------- reading


def _find(d: Path, stem: str) -> Path | None:
    for suffix in (".csv", ".csv.gz", ".parquet"):
        p = d / f"{stem}{suffix}"
        if p.is_file():
            return p
    return None


def _read_table(path: Path) -> pd.DataFrame:
    try:
        if path.suffix == ".parquet":
            df = pd.read_parquet(path)
        else:
            df = pd.read_csv(path, comment="#")
    except (OSError, ValueError, pd.errors.ParserError) as err:
        raise InputError(f"{path}: cannot read as a table ({str(err).splitlines()[0]})") from err
    df.columns = [str(c).strip() for c in df.columns]
    if "time_s" not in df.columns:
        raise InputError(f"{path}: no time_s column (found: {', '.join(df.columns[:12])})")
    if df.shape[0] == 0:
        raise InputError(f"{path}: no data rows")
    return df


def _col(df: pd.DataFrame, name: str, path: Path, required: bool = False) -> np.ndarray | None:
    if name not in df.columns:
        if required:
            raise InputError(f"{path}: missing column {name} (found: {', '.join(df.columns[:12])})")
        return None
    v = pd.to_numeric(df[name], errors="coerce")
    bad = v.isna() & df[name].notna()
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise InputError(f"{path}: column {name} row {i + 2}: {df[name].iloc[i]!r} is not a number")
    return v.to_numpy(float)


def _unit_columns(
    df: pd.DataFrame, prefix: str, units: dict[str, float], path: Path
) -> tuple[np.ndarray | None, str | None]:
    """Columns ``<prefix>_{x,y,z}_<unit>`` -> (n, 3) SI array (NaN for absent axes) and unit."""
    found: dict[int, tuple[str, str]] = {}
    for c in df.columns:
        for ax, i in _AXES.items():
            head = f"{prefix}_{ax}_"
            if c.lower().startswith(head):
                found[i] = (c, c[len(head) :])
    if not found:
        return None, None
    out = np.full((df.shape[0], 3), np.nan)
    unit_seen = None
    for i, (c, unit) in found.items():
        key = unit.lower()
        if key not in units:
            raise InputError(
                f"{path}: column {c}: unknown unit {unit!r}; use one of {', '.join(units)}"
            )
        out[:, i] = _col(df, c, path, required=True) * units[key]  # type: ignore[operator]
        unit_seen = key
    return out, unit_seen


_GYRO_UNITS = {**GYRO_UNITS, "rad_s": 1.0, "deg_s": math.pi / 180.0}
_ACCEL_UNITS = {**ACCEL_UNITS, "m_s2": 1.0}
_MAG_UNITS = {
    "t": 1.0,
    "ut": 1e-6,
    "nt": 1e-9,
    "gauss": 1e-4,
    "g": 1e-4,
    "mgauss": 1e-7,
    "raw": 1.0,
}


def read_layout(directory: str | Path, settings: DriveSettings | None = None) -> Drive:
    """Read a drive-layout directory into a :class:`Drive` (SI, body frame FLU).

    ``settings`` replaces ``drive.yaml`` when given (command-line overrides are
    applied by the caller on the parsed settings).
    """
    d = Path(directory)
    if not d.is_dir():
        raise InputError(f"{d}: not a directory")
    if settings is None:
        settings = read_settings(d)
    warnings: list[str] = []
    drive = Drive(settings=settings, source=str(d), layout="generic", warnings=warnings)
    rot = axes_matrix(settings.imu_axes)

    p = _find(d, "imu")
    if p is not None:
        df = _read_table(p)
        t = _col(df, "time_s", p, True)
        gyro, gu = _unit_columns(df, "gyro", _GYRO_UNITS, p)
        acc, au = _unit_columns(df, "accel", _ACCEL_UNITS, p)
        if gyro is None and acc is None:
            raise InputError(
                f"{p}: no IMU columns; expected gyro_{{x,y,z}}_<unit> (rads, dps) and/or "
                "accel_{x,y,z}_<unit> (mps2, g)"
            )
        n = df.shape[0]
        gyro = np.full((n, 3), np.nan) if gyro is None else gyro
        acc = np.full((n, 3), np.nan) if acc is None else acc
        assert t is not None
        drive.imu = ImuStream(
            t=t,
            accel=acc @ rot.T,
            gyro=gyro @ rot.T,
            input_units={"gyro": gu or "", "accel": au or ""},
        )

    p = _find(d, "gnss")
    if p is not None:
        df = _read_table(p)
        course = _col(df, "course_deg", p)
        fix = _col(df, "fix", p)
        drive.gnss = GnssStream(
            t=_col(df, "time_s", p, True),  # type: ignore[arg-type]
            lat_deg=_col(df, "lat_deg", p, True),  # type: ignore[arg-type]
            lon_deg=_col(df, "lon_deg", p, True),  # type: ignore[arg-type]
            alt_m=_col(df, "alt_m", p),
            hdop=_col(df, "hdop", p),
            h_acc_m=_col(df, "h_acc_m", p),
            fix=None if fix is None else (np.nan_to_num(fix, nan=0.0) != 0),
            speed_mps=_col(df, "speed_mps", p),
            course_rad=None if course is None else np.radians(course),
            vel_n_mps=_col(df, "vel_n_mps", p),
            vel_e_mps=_col(df, "vel_e_mps", p),
        )

    p = _find(d, "velocity")
    if p is not None:
        df = _read_table(p)
        kind = str(df["kind"].iloc[0]) if "kind" in df.columns else "dvl"
        drive.velocity = VelocityStream(
            t=_col(df, "time_s", p, True),  # type: ignore[arg-type]
            u_mps=_col(df, "u_mps", p, True),  # type: ignore[arg-type]
            v_mps=_col(df, "v_mps", p),
            w_mps=_col(df, "w_mps", p),
            kind=kind,
        )

    p = _find(d, "heading")
    if p is not None:
        df = _read_table(p)
        t = _col(df, "time_s", p, True)
        assert t is not None
        h = _col(df, "heading_deg", p)
        mag, mu = _unit_columns(df, "mag", _MAG_UNITS, p)
        if h is None and mag is None:
            raise InputError(f"{p}: expected heading_deg and/or mag_{{x,y,z}}_<unit> columns")
        if h is not None:
            ok = np.isfinite(h)
            drive.heading = HeadingStream(t=t[ok], heading_rad=np.radians(h[ok]) % (2 * math.pi))
        if mag is not None:
            drive.mag = MagStream(t=t, mag=mag, unit=mu or "unknown")

    p = _find(d, "attitude")
    if p is not None:
        df = _read_table(p)
        t = _col(df, "time_s", p, True)
        assert t is not None
        if "roll_deg" in df.columns:
            yaw = _col(df, "yaw_deg", p)
            drive.attitude = AttitudeStream(
                t=t,
                roll_rad=np.radians(_col(df, "roll_deg", p, True)),  # type: ignore[arg-type]
                pitch_rad=np.radians(_col(df, "pitch_deg", p, True)),  # type: ignore[arg-type]
                yaw_rad=None if yaw is None else np.radians(yaw) % (2 * math.pi),
            )
        elif "qw" in df.columns:
            q = np.column_stack([_col(df, k, p, True) for k in ("qw", "qx", "qy", "qz")])
            roll, pitch, yaw = quaternion_to_rpy_compass(q)
            drive.attitude = AttitudeStream(t=t, roll_rad=roll, pitch_rad=pitch, yaw_rad=yaw)
        else:
            raise InputError(f"{p}: expected roll_deg, pitch_deg (or qw, qx, qy, qz) columns")

    p = _find(d, "truth")
    if p is not None:
        drive.truth = _read_truth(p)
    return drive


def quaternion_to_rpy_compass(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body (FLU) -> ENU quaternions (w, x, y, z) -> roll (right side down +), pitch (nose
    up +) and yaw (compass, clockwise from north), rad."""
    from scipy.spatial.transform import Rotation

    r = Rotation.from_quat(np.column_stack([q[:, 1], q[:, 2], q[:, 3], q[:, 0]]))
    m = r.as_matrix()  # columns: body axes (x fwd, y left, z up) in ENU
    # nose up: body x has a +Up component; right side down: body y (left) points up
    pitch = np.arcsin(np.clip(m[:, 2, 0], -1.0, 1.0))
    roll = np.arctan2(m[:, 2, 1], m[:, 2, 2])
    yaw_enu = np.arctan2(m[:, 1, 0], m[:, 0, 0])
    yaw = np.mod(0.5 * math.pi - yaw_enu, 2 * math.pi)
    return roll, pitch, yaw


def _read_truth(p: Path) -> Truth:
    from imubounds.dynamic.aiding.geodesy import geodetic_to_enu

    df = _read_table(p)
    t = _col(df, "time_s", p, True)
    assert t is not None
    used = {"time_s"}
    if "east_m" in df.columns:
        e, n = _col(df, "east_m", p, True), _col(df, "north_m", p, True)
        olat = df.attrs.get("origin")  # parquet metadata, rarely present
        origin = (
            (float(df["origin_lat_deg"].iloc[0]), float(df["origin_lon_deg"].iloc[0]), 0.0)
            if "origin_lat_deg" in df.columns
            else (olat if isinstance(olat, tuple) else (math.nan, math.nan, 0.0))
        )
        used |= {"east_m", "north_m", "origin_lat_deg", "origin_lon_deg"}
    elif "lat_deg" in df.columns:
        lat, lon = _col(df, "lat_deg", p, True), _col(df, "lon_deg", p, True)
        e, n, origin = geodetic_to_enu(lat, lon, None)
        used |= {"lat_deg", "lon_deg"}
    else:
        raise InputError(f"{p}: truth needs lat_deg, lon_deg or east_m, north_m")
    hd = _col(df, "heading_deg", p)
    used |= {"heading_deg", "u_mps", "v_mps"}
    extra = {c: _col(df, c, p) for c in df.columns if c not in used}
    return Truth(
        t=t,
        east_m=e,  # type: ignore[arg-type]
        north_m=n,  # type: ignore[arg-type]
        origin=tuple(origin),  # type: ignore[arg-type]
        heading_rad=None if hd is None else np.radians(hd),
        u_mps=_col(df, "u_mps", p),
        v_mps=_col(df, "v_mps", p),
        extra={k: v for k, v in extra.items() if v is not None},
    )


def read_settings(d: Path) -> DriveSettings:
    """``d/drive.yaml`` -> :class:`DriveSettings` (defaults, listed as assumed, if absent)."""
    p = d / SETTINGS_FILE
    if not p.is_file():
        s = parse_settings({}, str(p))
        s.assumed.insert(0, f"{p} is absent: every setting is its documented default")
        return s
    import yaml

    try:
        data = yaml.safe_load(p.read_text())
    except (OSError, yaml.YAMLError) as err:
        raise InputError(f"{p}: cannot read ({str(err).splitlines()[0]})") from err
    return parse_settings(data, str(p))


def is_layout(d: Path) -> bool:
    """True if ``d`` looks like a drive-layout directory (``imu.csv`` or ``drive.yaml``)."""
    return d.is_dir() and (_find(d, "imu") is not None or (d / SETTINGS_FILE).is_file())


# ----------------------------------------------------------------------------- writing


def write_layout(drive: Drive, directory: str | Path, fmt: str = "csv") -> Path:
    """Write ``drive`` as a drive-layout directory (IMU in body axes: ``imu_axes`` = x, y, z).

    The directory must not exist or be empty; the caller handles atomic
    replacement (see :mod:`imubounds.io.outputs`).
    """
    import yaml

    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)

    def put(name: str, cols: dict[str, Any]) -> None:
        df = pd.DataFrame({k: v for k, v in cols.items() if v is not None})
        if fmt == "parquet":
            df.to_parquet(d / f"{name}.parquet", index=False)
        else:
            df.to_csv(d / f"{name}.csv", index=False, float_format="%.12g")

    if drive.imu is not None:
        cols: dict[str, Any] = {"time_s": drive.imu.t}
        for i, ax in enumerate("xyz"):
            if np.any(np.isfinite(drive.imu.gyro[:, i])):
                cols[f"gyro_{ax}_rads"] = drive.imu.gyro[:, i]
        for i, ax in enumerate("xyz"):
            if np.any(np.isfinite(drive.imu.accel[:, i])):
                cols[f"accel_{ax}_mps2"] = drive.imu.accel[:, i]
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
            },
        )
    v = drive.velocity
    if v is not None:
        put("velocity", {"time_s": v.t, "u_mps": v.u_mps, "v_mps": v.v_mps, "w_mps": v.w_mps})
    if drive.heading is not None or drive.mag is not None:
        h, m = drive.heading, drive.mag
        if h is not None and m is not None and not np.array_equal(h.t, m.t):
            t = np.union1d(h.t, m.t)
            hh = np.full(t.size, np.nan)
            hh[np.searchsorted(t, h.t)] = np.degrees(h.heading_rad)
            mm = np.full((t.size, 3), np.nan)
            mm[np.searchsorted(t, m.t)] = m.mag
        else:
            t = h.t if h is not None else m.t  # type: ignore[union-attr]
            hh = None if h is None else np.degrees(h.heading_rad)
            mm = None if m is None else m.mag
        cols = {"time_s": t, "heading_deg": hh}
        if mm is not None:
            unit = {"t": "T", "ut": "uT", "nt": "nT", "gauss": "gauss"}.get(
                (m.unit if m else "").lower(), "raw"
            )
            factor = _MAG_UNITS.get(unit.lower(), 1.0)
            for i, ax in enumerate("xyz"):
                cols[f"mag_{ax}_{unit}"] = mm[:, i] / factor
        put("heading", cols)
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
            "heading_deg": None if tr.heading_rad is None else np.degrees(tr.heading_rad),
            "u_mps": tr.u_mps,
            "v_mps": tr.v_mps,
        }
        cols.update(tr.extra)
        put("truth", cols)
    s = dataclasses.replace(drive.settings, imu_axes=("x", "y", "z"))
    (d / SETTINGS_FILE).write_text(yaml.safe_dump(settings_to_dict(s), sort_keys=False))
    return d
