"""``imubounds convert INPUT... -o DIR``: any supported drive log -> the documented layout."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from imubounds.cli._common import add_drive_options, add_force_option, drive_read_options
from imubounds.errors import OptionError


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
    add_drive_options(p)
    p.add_argument("-q", "--quiet", action="store_true", help="print no summary")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from imubounds.cli._common import Reporter
    from imubounds.io.drive.layout import (
        CALIBRATION_FILE,
        FILES,
        FORMATS,
        NOISE_FILE,
        SETTINGS_FILE,
        write_layout,
    )
    from imubounds.io.drive.readers import read_drive
    from imubounds.io.outputs import OutputSet

    opts = drive_read_options(args)
    with Reporter(args.quiet).steps("imubounds convert", 1) as steps:
        steps.step("reading the drive")
        drive = read_drive(list(args.input), **opts)
    from imubounds.dynamic.imu_mount import mount_warning

    if (w := mount_warning(drive)) is not None:
        drive.warnings.append(w)
    if opts.get("topics") and drive.layout != "rosbag":
        raise OptionError("--topic applies to ROS bags only")
    inputs = [*args.input, *([args.settings] if args.settings else [])]
    suffix = FORMATS[args.format]
    with OutputSet(args.out, force=args.force, inputs=inputs, command="convert",
                   source=args.input) as out:
        extra = [CALIBRATION_FILE] if drive.settings.heading.calibration is not None else []
        extra += [NOISE_FILE] if drive.settings.imu.noise_json is not None else []
        out.check([f"{name}{suffix}" for name in FILES] + [SETTINGS_FILE, *extra])
        write_layout(drive, out.staging, fmt=args.format)
        out.record(getattr(args, "argv", None), command_name="convert")
    for line in summary(drive, args.out):  # the summary on stdout, warnings on stderr
        if args.quiet and not line.startswith("imubounds: warning:"):
            continue  # the warnings about the input even with --quiet
        print(line, file=sys.stderr if line.startswith("imubounds: ") else sys.stdout)
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
