"""NMEA 0183 captures via ``pynmea2``: GPS fixes, course and heading, plus VectorNav IMU.

A capture is a text file of sentences, one a line. A line may start with a
receive time stamp in seconds (``1763590170.28,$GPGGA,...`` or
``1763590170.28 $GPGGA,...``); such host stamps are used as the time of the
sentence (the same clock as an IMU log recorded on that host). Without them
the time is the UTC time of day in GGA/RMC, on the date of the RMC sentences
(or ``date``), as Unix seconds; HDT/HDG carry no time and take the time of
the last timed sentence before them.

Sentences used:

``GGA``
    latitude, longitude (deg), altitude (m), fix quality (0 = no fix), HDOP.
``RMC``
    course over ground (deg clockwise from true north), speed (knots), status, date.
``VTG``
    course over ground (true) and speed (km/h, else knots); no time of its own.
``HDT``
    true heading (deg clockwise from north).
``HDG``
    magnetic heading, with magnetic variation (E positive) applied when
    given, so the result is a true heading.
``VNYMR``
    VectorNav yaw/pitch/roll, magnetometer, accelerometer (m/s^2) and gyro
    (rad/s) in the sensor's **FRD** axes; read as an IMU log by
    :func:`read_nmea_imu` (converted to FLU).

Checksums: a sentence with a ``*hh`` checksum that does not match is an
error (one line naming the file line), unless ``on_bad_checksum="skip"``;
sentences without a checksum are accepted (it is optional in NMEA 0183).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import UTC, date, datetime, time
from pathlib import Path
from typing import Any

import numpy as np

from imubounds.errors import InputError, OptionError
from imubounds.frames import FRD_TO_FLU
from imubounds.io.drive import (
    AttitudeStream,
    Drive,
    DriveSettings,
    GnssStream,
    HeadingStream,
    ImuStream,
    MagStream,
)
from imubounds.io.log import ImuLog

from .assemble import RawChannel, RawTime, ReadOptions, assemble_logs
from .validate import check_input_path

KNOT = 1852.0 / 3600.0  #: one knot in m/s
_PREFIX = re.compile(r"^\s*([+-]?\d+(?:\.\d*)?)[,;\s]+(?=[$!])")


def sniff_nmea(head: bytes) -> bool:
    """True when the first bytes look like an NMEA capture (a line starting with ``$``)."""
    try:
        text = head.decode("ascii", errors="strict")
    except UnicodeDecodeError:
        return False
    first = text.lstrip().split("\n", 1)[0]
    return first.startswith("$") or bool(_PREFIX.match(first))


def nmea_checksum(body: str) -> int:
    """XOR of the characters between ``$`` and ``*``."""
    c = 0
    for ch in body:
        c ^= ord(ch)
    return c


@dataclass
class Sentence:
    """One sentence of a capture: file line, host stamp (s) or None, talker+type, text."""

    line: int
    host_t: float | None
    kind: str
    text: str


@dataclass
class NmeaCapture:
    """The sentences of a capture file, checked, with notes for the user."""

    path: Path
    sentences: list[Sentence]
    notes: list[str] = field(default_factory=list)


def scan_nmea(path: str | Path, *, on_bad_checksum: str = "error") -> NmeaCapture:
    """Read and checksum-check every sentence of a capture (streaming, line by line).

    Parameters
    ----------
    path:
        Text file of NMEA sentences (optionally with host time stamps).
    on_bad_checksum:
        ``"error"`` (raise :class:`InputError` at the first bad sentence) or
        ``"skip"`` (drop bad sentences, with a warning giving the count).
    """
    p = Path(path)
    if on_bad_checksum not in ("error", "skip"):
        raise OptionError(f"on_bad_checksum must be error or skip, got {on_bad_checksum!r}")
    check_input_path(p, what="NMEA capture")
    out: list[Sentence] = []
    bad: list[int] = []
    garbage = no_sum = 0
    try:
        with open(p, encoding="ascii", errors="replace", newline="") as f:
            for lineno, raw in enumerate(f, start=1):
                line = raw.strip().strip('"')
                if not line or line.startswith("#"):
                    continue
                host_t = None
                m = _PREFIX.match(line)
                if m:
                    host_t = float(m.group(1))
                    line = line[m.end():]
                if not line.startswith(("$", "!")):
                    garbage += 1
                    continue
                body, star, given = line[1:].partition("*")
                if star:
                    try:
                        ok = int(given[:2], 16) == nmea_checksum(body)
                    except ValueError:
                        ok = False
                    if not ok:
                        if on_bad_checksum == "error":
                            raise InputError(
                                f"{p}, line {lineno}: NMEA checksum {given[:2]!r} does not "
                                f"match the sentence (computed {nmea_checksum(body):02X}); the "
                                "capture is corrupt: repair it or skip bad sentences "
                                "(on_bad_checksum='skip')"
                            )
                        bad.append(lineno)
                        continue
                else:
                    no_sum += 1
                kind = body.split(",", 1)[0]
                out.append(Sentence(lineno, host_t, kind, "$" + body))
    except OSError as err:
        raise InputError(f"{p}: cannot read ({err.strerror})") from err
    cap = NmeaCapture(p, out)
    if bad:
        cap.notes.append(
            f"{p}: {len(bad)} sentence(s) with a bad checksum skipped (first at line {bad[0]})"
        )
    if garbage:
        cap.notes.append(f"{p}: {garbage} line(s) that are not NMEA sentences ignored")
    if no_sum:
        cap.notes.append(f"{p}: {no_sum} sentence(s) without a checksum accepted unchecked")
    if not out:
        raise InputError(f"{p}: no NMEA sentence found (lines must start with $ or a time stamp)")
    return cap


def _f(text: str) -> float:
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def _utc_seconds(d: date, t: time) -> float:
    dt = datetime.combine(d, t.replace(tzinfo=None), tzinfo=UTC)
    return dt.timestamp()


def drive_from_files(
    files: Mapping[str, Any], settings: DriveSettings, options: Mapping[str, Any]
) -> Drive:
    """The drive reader registered for the ``nmea`` format (see
    :data:`imubounds.io.registry.DriveReaderFunc`): the capture, and the IMU log if any."""
    return read_drive_nmea(
        files["nmea"], files["imu"], settings=settings, imu_frame=options["imu_frame"],
        date_utc=options["date_utc"], time_offset_s=options["time_offset_s"],
        on_bad_checksum=options["on_bad_checksum"],
    )


def read_drive_nmea(
    nmea_path: str | Path,
    imu_path: str | Path | None = None,
    *,
    settings: DriveSettings | None = None,
    imu_frame: str = "FLU",
    date_utc: str | None = None,
    time_offset_s: float = 0.0,
    on_bad_checksum: str = "error",
    imu_options: ReadOptions | None = None,
) -> Drive:
    """A drive from an NMEA capture (GGA, RMC, VTG, HDT/HDG) and an IMU log, merged by time.

    Parameters
    ----------
    nmea_path:
        The NMEA capture.
    imu_path:
        Any IMU log :func:`imubounds.io.read_imu` reads (CSV, Parquet,
        bag, ULog, HDF5); its time must be on the same clock as the NMEA time
        (host stamps, or Unix UTC seconds) after adding ``time_offset_s``.
        ``None``: the IMU comes from the capture's own ``$VNYMR`` sentences
        (with their yaw/pitch/roll as attitude and their magnetometer).
    settings:
        The drive's settings (mount, bounds); defaults if None.
    imu_frame:
        Body frame of the IMU file when the format does not say: ``"FLU"``
        (kept) or ``"FRD"`` (y and z negated).
    date_utc:
        ``YYYY-MM-DD`` for captures without host stamps and without RMC.
    time_offset_s:
        Added to the NMEA times (s) to put them on the IMU clock.
    on_bad_checksum:
        ``"error"`` or ``"skip"`` (see :func:`scan_nmea`).

    Returns
    -------
    Drive
        GNSS fixes from GGA (RMC positions when there is no GGA) with speed and
        course over ground from RMC or VTG of the same epoch, heading in rad
        clockwise from north from HDT (true) else HDG (magnetic; true when every
        HDG carries the variation), IMU in FLU.
    """
    from imubounds.io.drive.mount import apply_mount

    if imu_frame not in ("FLU", "FRD"):
        raise OptionError(f"imu_frame must be FLU or FRD, got {imu_frame!r}")
    if not math.isfinite(time_offset_s):
        raise OptionError(f"time offset must be a finite number of seconds, got {time_offset_s}")
    cap = scan_nmea(nmea_path, on_bad_checksum=on_bad_checksum)
    p = cap.path
    the_date: date | None = None
    if date_utc is not None:
        try:
            the_date = date.fromisoformat(date_utc)
        except ValueError as err:
            raise OptionError(f"date {date_utc!r} is not YYYY-MM-DD") from err
    parsed, the_date = _parse_sentences(cap, the_date)
    use_host = all(s.host_t is not None for s, _ in parsed)
    if not use_host and the_date is None:
        raise InputError(
            f"{p}: sentences have no host time stamps and no RMC date; give the date (date_utc)"
        )
    rows = _collect_rows(p, parsed, use_host, the_date)
    s_ = settings if settings is not None else DriveSettings()
    drive = Drive(settings=s_, source=f"{p}" + (f" + {imu_path}" if imu_path else ""),
                  layout="nmea")
    drive.warnings.extend(cap.notes)
    files: dict[str, str] = {"gnss": str(p)}
    off = time_offset_s
    _gnss_from_rows(p, rows, off, drive)
    _heading_from_rows(p, rows, off, drive)
    if drive.heading is not None:
        files["heading"] = str(p)
    if imu_path is None:
        _imu_from_vnymr(cap, drive, files, off)
    else:
        _imu_from_file(imu_path, imu_options, imu_frame, drive, files)
    drive.meta["files"] = files
    drive.meta["nmea_time"] = "host stamps" if use_host else "UTC"
    apply_mount(drive, attitude_of_sensor=True)
    return drive


def _parse_sentences(
    cap: NmeaCapture, the_date: date | None
) -> tuple[list[tuple[Sentence, object]], date | None]:
    """The sentences pynmea2 can parse (others are not used here), and the date: the
    given one, else that of the first RMC carrying one."""
    import pynmea2

    parsed: list[tuple[Sentence, object]] = []
    for s in cap.sentences:
        try:
            msg = pynmea2.parse(s.text, check=False)
        except pynmea2.ParseError:
            continue  # unknown or proprietary sentence types are not used here
        parsed.append((s, msg))
        if the_date is None and s.kind.endswith("RMC") and getattr(msg, "datestamp", None):
            the_date = msg.datestamp
    return parsed, the_date


def _collect_rows(
    p: Path, parsed: list[tuple[Sentence, object]], use_host: bool, the_date: date | None
) -> dict[str, list[tuple[float, ...]]]:
    """The rows of each used sentence type (GGA, RMC, VTG, HDT, HDG), each led by its
    time in s (host stamp, else UTC of the date; a sentence without time takes the last)."""
    rows: dict[str, list[tuple[float, ...]]] = {k: [] for k in ("GGA", "RMC", "VTG", "HDT",
                                                                 "HDG")}  # fmt: skip
    last_t = math.nan
    for s, msg in parsed:
        stamp = getattr(msg, "timestamp", None)
        if use_host:
            t = float(s.host_t)  # type: ignore[arg-type]
        elif isinstance(stamp, time) and the_date is not None:
            t = _utc_seconds(the_date, stamp)
            if t < last_t - 43200:  # passed midnight UTC
                t += 86400.0
        else:
            t = last_t
        if not math.isfinite(t):
            continue
        last_t = t
        typ = s.kind[-3:]
        try:
            row = _sentence_row(typ, msg, t)
        except (ValueError, TypeError, AttributeError) as err:
            raise InputError(f"{p}, line {s.line}: malformed {typ} sentence ({err})") from err
        if row is not None:
            rows[typ].append(row)
    return rows


def _sentence_row(typ: str, msg: object, t: float) -> tuple[float, ...] | None:
    """One row of a GGA (t, lat, lon, alt, hdop, quality), RMC (t, lat, lon, course deg,
    valid, speed m/s), VTG (t, course deg, speed m/s), HDT (t, heading deg) or HDG (t,
    magnetic heading deg, variation deg east) sentence; None for another type."""
    m: Any = msg
    if typ == "GGA":
        lat = m.latitude if m.lat else math.nan
        lon = m.longitude if m.lon else math.nan
        return (t, lat, lon, _f(m.altitude), _f(m.horizontal_dil), _f(m.gps_qual))
    if typ == "RMC":
        lat = m.latitude if m.lat else math.nan
        lon = m.longitude if m.lon else math.nan
        return (t, lat, lon, _f(m.true_course), 1.0 if m.status == "A" else 0.0,
                _f(m.spd_over_grnd) * KNOT)  # fmt: skip
    if typ == "VTG":
        kmh = _f(m.spd_over_grnd_kmph)
        spd = kmh / 3.6 if math.isfinite(kmh) else _f(m.spd_over_grnd_kts) * KNOT
        return (t, _f(m.true_track), spd)
    if typ == "HDT":
        return (t, _f(m.heading))
    if typ == "HDG":
        h = _f(m.heading)
        dev = _f(m.deviation)
        if math.isfinite(dev):
            h += dev if m.dev_dir == "E" else -dev
        var = _f(m.variation)
        var = (var if m.var_dir == "E" else -var) if math.isfinite(var) else math.nan
        return (t, h, var)
    return None


def _gnss_from_rows(
    p: Path, rows: dict[str, list[tuple[float, ...]]], off: float, drive: Drive
) -> None:
    """The GNSS stream: GGA fixes (RMC positions without GGA), with the speed and course
    of the RMC (else VTG) nearest in time."""
    from imubounds.io.drive.mount import match_times

    gga, rmc, vtg = rows["GGA"], rows["RMC"], rows["VTG"]
    if gga:
        g = _dedupe(np.asarray(gga, dtype=float))
        gs = GnssStream(
            t=g[:, 0] + off, lat_deg=g[:, 1], lon_deg=g[:, 2], alt_m=g[:, 3], hdop=g[:, 4],
            fix=np.isfinite(g[:, 5]) & (g[:, 5] > 0),
        )
    elif rmc:
        r = _dedupe(np.asarray(rmc, dtype=float))
        gs = GnssStream(t=r[:, 0] + off, lat_deg=r[:, 1], lon_deg=r[:, 2], fix=r[:, 4] > 0)
        drive.warnings.append(f"{p}: no GGA sentences: positions from RMC, default HDOP")
    else:
        return
    vel = rmc or vtg
    if vel:
        v = _dedupe(np.asarray([(r[0], r[3], r[5]) for r in rmc] if rmc else vtg, float))
        k, near = match_times(v[:, 0] + off, gs.t)
        gs.speed_mps = np.where(near, v[k, 2], np.nan)
        gs.course_rad = np.where(near, np.mod(np.radians(v[k, 1]), 2 * math.pi), np.nan)
    drive.gnss = gs


def _heading_from_rows(
    p: Path, rows: dict[str, list[tuple[float, ...]]], off: float, drive: Drive
) -> None:
    """The heading stream: HDT (true) else HDG (magnetic; true when every HDG carries
    the variation)."""
    hdt, hdg = rows["HDT"], rows["HDG"]
    if hdt:
        hh = _dedupe(np.asarray(hdt, dtype=float))
        hh = hh[np.isfinite(hh[:, 1])]
        drive.heading = HeadingStream(t=hh[:, 0] + off, heading_rad=np.mod(np.radians(hh[:, 1]),
                                      2 * math.pi), source="compass", true_north=True)
    elif hdg:
        hh = _dedupe(np.asarray(hdg, dtype=float))
        hh = hh[np.isfinite(hh[:, 1])]
        true = bool(np.all(np.isfinite(hh[:, 2])))
        deg = hh[:, 1] + (hh[:, 2] if true else 0.0)
        drive.heading = HeadingStream(t=hh[:, 0] + off, heading_rad=np.mod(np.radians(deg),
                                      2 * math.pi), source="compass", true_north=true)
        drive.notes.append(
            f"{p}: heading from HDG (magnetic" + (", variation applied: true north)" if true else
                                                  "; the drive's declination applies)")
        )


def _imu_from_file(
    imu_path: str | Path,
    imu_options: ReadOptions | None,
    imu_frame: str,
    drive: Drive,
    files: dict[str, str],
) -> None:
    """The IMU stream from a separate IMU log (read by the reader registry)."""
    from imubounds.io.registry import read_imu

    imu = read_imu(imu_path, on_gap="ignore") if imu_options is None else _read(
        imu_path, imu_options)
    drive.warnings.extend(imu.warnings)
    nan = np.full(imu.t.size, np.nan)
    acc = np.column_stack([imu.channels.get(f"accel_{a}", nan) for a in "xyz"])
    gyr = np.column_stack([imu.channels.get(f"gyro_{a}", nan) for a in "xyz"])
    frame_in = imu.frame if imu.frame in ("FLU", "FRD") else imu_frame
    if frame_in == "FRD":
        acc, gyr = acc * FRD_TO_FLU, gyr * FRD_TO_FLU
        drive.notes.append(f"{imu_path}: FRD body axes converted to FLU (y and z negated)")
    drive.imu = ImuStream(t=imu.t, accel=acc, gyro=gyr,
                          input_units={"gyro": "rad/s", "accel": "m/s^2"})
    files["imu"] = str(imu_path)


def _imu_from_vnymr(cap: NmeaCapture, drive: Drive, files: dict[str, str], off: float) -> None:
    rows: list[tuple[float, ...]] = []
    for s in cap.sentences:
        if s.kind != "VNYMR" or s.host_t is None:
            continue
        parts = s.text.split("*")[0].split(",")
        if len(parts) < 13:
            raise InputError(f"{cap.path}, line {s.line}: VNYMR sentence has {len(parts) - 1} "
                             "fields, expected 12")
        rows.append((s.host_t, *(_f(x) for x in parts[1:13])))
    if not rows:
        kinds = sorted({s.kind for s in cap.sentences})
        raise InputError(
            f"{cap.path}: no IMU: the capture holds {', '.join(kinds)} but no host-stamped "
            "$VNYMR IMU sentences; give an IMU log with it (time_s, gyro_{x,y,z}_<unit>, "
            "accel_{x,y,z}_<unit>)"
        )
    a = _dedupe(np.asarray(rows, dtype=float))
    t = a[:, 0] + off
    # yaw, pitch, roll (deg); mag (gauss); accel (m/s^2); gyro (rad/s); FRD axes
    drive.imu = ImuStream(t=t, accel=a[:, 7:10] * FRD_TO_FLU, gyro=a[:, 10:13] * FRD_TO_FLU,
                          input_units={"gyro": "rad/s", "accel": "m/s^2"})
    drive.mag = MagStream(t=t, mag=a[:, 4:7] * FRD_TO_FLU * 1e-4, unit="T")
    ok = np.isfinite(a[:, 1:4]).all(axis=1)
    drive.attitude = AttitudeStream(
        t=t[ok], roll_rad=np.radians(a[ok, 3]), pitch_rad=np.radians(a[ok, 2]),
        yaw_rad=np.mod(np.radians(a[ok, 1]), 2 * math.pi), source="ahrs",
    )
    files["imu"] = files["attitude"] = str(cap.path)
    files.setdefault("heading", str(cap.path))
    drive.notes.append(f"{cap.path}: IMU, magnetometer and attitude from the $VNYMR sentences "
                       "(VectorNav FRD axes converted to FLU)")


def _read(path: str | Path, opts: ReadOptions) -> ImuLog:
    from imubounds.io.registry import find_reader

    return find_reader(path).load()(Path(path), opts.validated())[0]


def _dedupe(a: np.ndarray) -> np.ndarray:
    """Sort by time and keep the first row of each time stamp."""
    a = a[np.argsort(a[:, 0], kind="stable")]
    keep = np.concatenate(([True], np.diff(a[:, 0]) > 0))
    return a[keep]


def read_nmea_imu(path: Path, opts: ReadOptions) -> list[ImuLog]:
    """Read the IMU of ``$VNYMR`` sentences (VectorNav) into SI :class:`ImuLog` segment(s).

    The sentence fields are yaw, pitch, roll (deg), magnetometer (gauss),
    accelerometer (m/s^2) and gyro (rad/s) in the sensor's FRD axes; they are
    converted to FLU. Time: the host stamps of the lines, else ``--rate``.
    A capture without VNYMR sentences (only GPS/heading) is refused with a
    pointer to ``imubounds dynamic``.
    """
    cap = scan_nmea(path, on_bad_checksum=str(opts.extra.get("on_bad_checksum", "error")))
    rows: list[tuple[float, ...]] = []
    lines: list[int] = []
    for s in cap.sentences:
        if s.kind != "VNYMR":
            continue
        parts = s.text.split(",")
        if len(parts) < 13:
            raise InputError(f"{path}, line {s.line}: VNYMR sentence has {len(parts) - 1} fields,"
                             " expected 12")
        vals = [_f(x) for x in parts[7:13]]
        rows.append((math.nan if s.host_t is None else s.host_t, *vals))
        lines.append(s.line)
    if not rows:
        kinds = sorted({s.kind for s in cap.sentences})
        raise InputError(
            f"{path}: no IMU sentences ($VNYMR) in this NMEA capture (it holds "
            f"{', '.join(kinds)}); NMEA GPS/heading go with an IMU log to 'imubounds dynamic'"
        )
    a = np.asarray(rows, dtype=float)
    acc = a[:, 1:4] * FRD_TO_FLU
    gyr = a[:, 4:7] * FRD_TO_FLU
    channels: dict[str, RawChannel] = {}
    for k, ax in enumerate("xyz"):
        channels[f"gyro_{ax}"] = RawChannel(gyr[:, k], "rad/s", f"VNYMR gyro {ax}")
        channels[f"accel_{ax}"] = RawChannel(acc[:, k], "m/s^2", f"VNYMR accel {ax}")
    if opts.channels is not None:
        channels = {c: v for c, v in channels.items() if c in opts.channels}
    has_t = bool(np.all(np.isfinite(a[:, 0])))
    return assemble_logs(
        str(path),
        RawTime(a[:, 0], "s", "host time stamp") if has_t else None,
        channels,
        opts,
        row_label=lambda i: f"line {lines[i]}",
        notes=[*cap.notes, f"{path}: VectorNav FRD axes converted to FLU (y and z negated)"],
        frame="FLU",
    )
