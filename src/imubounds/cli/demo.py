"""``imubounds demo``: the whole pipeline on the bundled real data."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path
from typing import Any

from imubounds.cli._common import add_force_option


def register(sub: Any) -> None:
    p = sub.add_parser(
        "demo",
        help="run the whole pipeline on the bundled real data",
        description="One story about one IMU: characterise the bundled ADIS16405 static "
        "log (DIR/static), simulate the paper's 9.4 km trip with that IMU's measured "
        "noise (DIR/sim, from DIR/static/noise.json), bound its error in motion against "
        "the characterised noise (DIR/dynamic, with the in-motion figures in motion.json), "
        "export the filter parameters in every format, stationary and in motion "
        "(DIR/filter), and write one report (DIR/report.html).",
    )
    p.add_argument("-o", "--out", default="out", metavar="DIR", help="output directory")
    add_force_option(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or messages")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from imubounds.io.outputs import OutputSet

    with OutputSet(args.out, force=args.force, command="demo",
                   subsets=("static", "sim", "dynamic", "filter")) as outset:
        outset.check(["report.html"])
        return _run(args, Path(args.out), outset)


def _run(args: argparse.Namespace, out: Path, outset: Any) -> int:
    from imubounds.cli import run_command
    from imubounds.io import bundled_static_log

    quiet = ["--quiet"] if args.quiet else []
    static, sim, dyn, filt = (str(out / x) for x in ("static", "sim", "dynamic", "filter"))
    steps: list[tuple[str, list[str]]] = [
        (
            "characterising the bundled ADIS16405 static log (45 min at 100 Hz)",
            ["static", str(bundled_static_log()), "-o", static, "--no-report"],
        ),
        (
            "simulating the paper's 9.4 km / 792 s trip with that IMU's measured noise "
            "(static/noise.json), GNSS and compass",
            ["simulate", "--scenario", "paper", "--imu-noise", str(Path(static) / "noise.json"),
             "--seed", "0", "-o", sim],
        ),
        (
            "bounding the IMU's error in motion against the characterised noise",
            ["dynamic", sim, "--static", str(Path(static) / "noise.json"), "-o", dyn,
             "--no-report"],
        ),
    ]
    from imubounds.export import FORMATS

    for fmt in FORMATS:
        steps.append((
            f"exporting the {fmt} filter parameters (stationary and in motion)",
            ["export", static, "--format", fmt, "-o", str(Path(filt) / f"{fmt}.yaml")],
        ))
        steps.append((
            "",
            ["export", static, "--format", fmt, "--motion", dyn, "-o",
             str(Path(filt) / f"{fmt}_motion.yaml")],
        ))
    from imubounds.io.outputs import ensure_dir

    ensure_dir(filt)
    shown = [w for w, _ in steps if w] + ["writing the report"]
    ran: list[str] = []  # every command, as run (the report's "How to reproduce")
    for what, argv in steps:
        if what and not args.quiet:
            print(f"[{shown.index(what) + 1}/{len(shown)}] {what}")
        # errors and Ctrl-C propagate, so the message names what was written
        quiet_step = quiet if argv[0] != "export" else ["--quiet"]
        full = [*argv, *quiet_step, *(["--overwrite"] if args.force else [])]
        ran.append("imubounds " + shlex.join(full))
        code = run_command(full)
        if code:
            return code
    from imubounds.report.html import write_report

    if not args.quiet:
        print(f"[{len(shown)}/{len(shown)}] writing the report")
    run_argv = getattr(args, "argv", None)
    outset.record(run_argv, command_name="demo", commands=ran)
    demo = "imubounds " + shlex.join(run_argv if run_argv is not None else ["demo", "-o", str(out)])
    write_report(out, dest=outset.path("report.html"), commands=[demo, *ran])
    if not args.quiet:
        print(f"demo finished; open {out / 'report.html'}")
    return 0
