"""``imubounds report DIR``: one self-contained HTML page of a run directory."""

from __future__ import annotations

import argparse
from typing import Any


def register(sub: Any) -> None:
    p = sub.add_parser(
        "report",
        help="write DIR/report.html from the results in DIR",
        description="Collect noise.json, dynamic.json, figures and run records found in DIR "
        "(or its static/ and dynamic/ sub-directories) into one self-contained DIR/report.html.",
    )
    p.add_argument("dir", help="output directory of a previous run")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from imubounds.report.html import write_report

    path = write_report(args.dir)
    if not args.quiet:
        print(f"wrote {path}")
    return 0
