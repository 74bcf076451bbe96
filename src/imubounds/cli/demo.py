"""``imubounds demo``: the whole pipeline on the bundled real data."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from imubounds.cli._common import add_force_option


def register(sub: Any) -> None:
    p = sub.add_parser(
        "demo",
        help="run the whole pipeline on the bundled real data",
        description="Run the stationary analysis on the bundled ADIS16405 extract, the "
        "dynamic analysis on the paper's simulated trip and on the bundled VN-100 drive, "
        "and write one report: DIR/static, DIR/sim, DIR/dynamic, DIR/dynamic_vn100, "
        "DIR/report.html.",
    )
    p.add_argument("-o", "--out", default="out", metavar="DIR", help="output directory")
    add_force_option(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or messages")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from imubounds.io.outputs import OutputSet

    with OutputSet(args.out, force=args.force) as outset:
        outset.check(["report.html"])
        return _run(args, Path(args.out), outset)


def _run(args: argparse.Namespace, out: Path, outset: Any) -> int:
    from imubounds.cli import run_command
    from imubounds.io import bundled_static_log
    from imubounds.io.drive_readers import bundled_drive_log

    quiet = ["--quiet"] if args.quiet else []
    steps: list[tuple[str, list[str]]] = [
        (
            "stationary analysis of the bundled ADIS16405 static log",
            [
                "static",
                str(bundled_static_log()),
                "-o",
                str(out / "static"),
                "--tau",
                "points:40",
                "--no-report",
            ],
        ),
        (
            "simulating the paper's 9.4 km / 792 s trip (MTx-grade IMU, GPS, compass)",
            ["simulate", "--scenario", "paper", "--seed", "0", "-o", str(out / "sim")],
        ),
        (
            "dynamic error margins on the simulated trip",
            ["dynamic", str(out / "sim"), "-o", str(out / "dynamic"), "--no-report"],
        ),
        (
            "dynamic error margins on the bundled VN-100 + BU-353N drive",
            [
                "dynamic",
                str(bundled_drive_log()),
                "-o",
                str(out / "dynamic_vn100"),
                "--imu-spec",
                "vn100",
                "--no-report",
            ],
        ),
    ]
    for i, (what, argv) in enumerate(steps, 1):
        if not args.quiet:
            print(f"[{i}/{len(steps) + 1}] {what}")
        # errors and Ctrl-C propagate, so the message names what was written
        code = run_command([*argv, *quiet, *(["--force"] if args.force else [])])
        if code:
            return code
    from imubounds.report.html import write_report

    if not args.quiet:
        print(f"[{len(steps) + 1}/{len(steps) + 1}] writing the report")
    write_report(out, dest=outset.path("report.html"))
    outset.record(getattr(args, "argv", None), command_name="demo")
    if not args.quiet:
        print(f"demo finished; open {out / 'report.html'}")
    return 0
