"""``imubounds demo``: the whole pipeline on the bundled real data."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any


def register(sub: Any) -> None:
    p = sub.add_parser(
        "demo",
        help="run the whole pipeline on the bundled real data",
        description="Run the stationary analysis on the bundled ADIS16405 extract "
        "(and the dynamic analysis where available), writing everything under DIR.",
    )
    p.add_argument("-o", "--out", default="out", metavar="DIR", help="output directory")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or messages")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from imubounds.cli import main as cli_main
    from imubounds.outputs import ensure_dir
    from imubounds.readers import bundled_static_log

    out = ensure_dir(args.out)
    quiet = ["--quiet"] if args.quiet else []
    static_dir = Path(out) / "static"
    code = cli_main(
        [
            "static",
            str(bundled_static_log()),
            "-o",
            str(static_dir),
            "--tau",
            "40",
            "--no-report",
            *quiet,
        ]
    )
    if code:
        return code
    from imubounds.report import write_report

    path = write_report(out)
    if not args.quiet:
        print(f"demo finished; open {path}")
    return 0
