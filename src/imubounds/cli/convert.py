"""``imubounds convert INPUT... -o DIR``: any supported drive log -> the documented layout."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from imubounds.cli._common import add_force_option, finite_float, positive_float
from imubounds.errors import OptionError

TOPIC_ROLES = ("imu", "gnss", "mag", "heading", "velocity", "gnss_velocity", "attitude")


def register(sub: Any) -> None:
    p = sub.add_parser(
        "convert",
        help="convert a drive log (VN-100, comma2k19, ROS bag, ULog, NMEA, CSV) to the drive "
        "layout",
        description="Read a drive log from any supported input and write it as the documented "
        "drive layout (imu.csv, gnss.csv, velocity.csv, heading.csv, attitude.csv, truth.csv, "
        "drive.yaml; docs/drive-layout.md), which 'imubounds dynamic DIR' reads directly. The "
        "IMU is written in the vehicle body frame (x forward, y left, z up) after the mount "
        "rotation; every input check of the readers applies (errors exit 2, problems that can "
        "be skipped are counted).",
    )
    p.add_argument(
        "input",
        nargs="+",
        help="a drive-layout, VN-100, comma2k19 or ROS 2 bag directory; a ROS 1 bag, MCAP, "
        "ULog; the two VN-100 CSVs; an NMEA capture (with an IMU log unless it holds $VNYMR); "
        "CSV logs (with --columns)",
    )
    p.add_argument("-o", "--out", required=True, metavar="DIR", help="output directory")
    add_force_option(p)
    p.add_argument(
        "--format",
        choices=("csv", "csv.gz", "parquet"),
        default="csv",
        help="table format of the output (csv)",
    )
    p.add_argument(
        "--settings",
        metavar="YAML",
        help="drive.yaml with the bounds and mount of this drive (replaces the input's own)",
    )
    p.add_argument(
        "--imu-axes",
        metavar="AXES",
        help="mount: body axes x,y,z (forward, left, up) as signed IMU axes, e.g. 'x,-z,y'",
    )
    p.add_argument(
        "--mount",
        choices=("auto", "forward", "backward"),
        default="auto",
        help="VN-100: detect a backwards unit from its yaw and the GPS course (auto)",
    )
    p.add_argument(
        "--topic",
        action="append",
        metavar="[ROLE=]TOPIC",
        help="ROS bag topic of a role (imu, gnss, mag, heading, velocity, gnss_velocity, "
        "attitude); a bare name is the IMU topic; repeatable",
    )
    p.add_argument(
        "--columns",
        metavar="MAP",
        help="CSV logs: layout column = source column, e.g. "
        "'time_s=stamp,gyro_z_dps=yaw_rate,accel_x_g=ax,lat_deg=Lat,lon_deg=Lon'",
    )
    n = p.add_argument_group("NMEA captures")
    n.add_argument(
        "--imu-frame",
        choices=("FLU", "FRD"),
        default="FLU",
        help="axes of the IMU log beside an NMEA capture when its format does not say (FLU)",
    )
    n.add_argument("--date", metavar="YYYY-MM-DD", help="UTC date of a capture without RMC")
    n.add_argument(
        "--time-offset",
        type=finite_float,
        default=0.0,
        metavar="S",
        help="seconds added to the NMEA times to put them on the IMU clock (0)",
    )
    n.add_argument(
        "--on-bad-checksum",
        choices=("error", "skip"),
        default="error",
        help="a sentence with a wrong checksum: stop (error) or skip and count it",
    )
    p.add_argument(
        "--max-speed",
        type=positive_float,
        metavar="M/S",
        help="speeds beyond this are dropped and counted (drive.yaml vehicle.max_speed_mps, "
        "70 m/s)",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="no messages on stderr")
    p.set_defaults(func=run)


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


def run(args: argparse.Namespace) -> int:
    from imubounds.io.drive_layout import FILES, FORMATS, SETTINGS_FILE, write_layout
    from imubounds.io.drive_readers import parse_drive_columns, read_drive
    from imubounds.io.outputs import OutputSet

    axes = None
    if args.imu_axes is not None:
        axes = [a for a in args.imu_axes.replace(" ", ",").split(",") if a]
    columns = parse_drive_columns(args.columns) if args.columns is not None else None
    topics = parse_topics(args.topic)
    drive = read_drive(
        list(args.input),
        settings=args.settings,
        imu_axes=axes,
        mount=args.mount,
        topics=topics or None,
        columns=columns,
        imu_frame=args.imu_frame,
        date_utc=args.date,
        time_offset_s=args.time_offset,
        on_bad_checksum=args.on_bad_checksum,
        max_speed_mps=args.max_speed,
    )
    if topics and drive.layout != "rosbag":
        raise OptionError("--topic applies to ROS bags only")
    inputs = [*args.input, *([args.settings] if args.settings else [])]
    suffix = FORMATS[args.format]
    with OutputSet(args.out, force=args.force, inputs=inputs) as out:
        out.check([f"{name}{suffix}" for name in FILES] + [SETTINGS_FILE])
        write_layout(drive, out.staging, fmt=args.format)
        out.record(getattr(args, "argv", None), command_name="convert")
    if not args.quiet:
        for line in summary(drive, args.out):
            print(line, file=sys.stderr)
    return 0


def summary(drive: Any, out: str) -> list[str]:
    """Lines saying what was converted: streams, time ranges, counted warnings, notes."""
    lines = [f"converted {drive.source} ({drive.layout}) -> {out}"]
    for name in drive.streams():
        s = getattr(drive, name)
        lo, hi = float(s.t[0]), float(s.t[-1])
        lines.append(f"  {name:9s} {s.t.size:8d} samples, {lo:.3f} .. {hi:.3f} s")
    for w in drive.warnings:
        lines.append(f"imubounds: warning: {w}")
    for n in drive.notes:
        lines.append(f"imubounds: note: {n}")
    return lines
