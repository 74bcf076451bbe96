"""``imubounds report DIR``: one self-contained HTML page of a run directory."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from imubounds.cli._common import add_force_option


def register(sub: Any) -> None:
    p = sub.add_parser(
        "report",
        help="write DIR/report.html from the results in DIR",
        description="Collect noise.json, dynamic.json, figures and run records found in DIR "
        "(or its static/ and dynamic/ sub-directories) into one self-contained DIR/report.html. "
        "A report.html that imubounds did not write is not overwritten without --overwrite.",
    )
    p.add_argument("dir", help="output directory of a previous run")
    add_force_option(p)
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from imubounds.errors import InputError
    from imubounds.io.outputs import check_output_file, output_file
    from imubounds.report.html import build_report

    root = Path(args.dir)
    if not root.is_dir():
        what = "does not exist" if not root.exists() else "is not a directory"
        raise InputError(f"{root} {what}; give the -o directory of a previous run")
    dest = root / "report.html"
    advice = "move it away"
    check_output_file(dest, force=args.force, option=None, advice=advice)
    text = build_report(root)  # every result file is read before anything is written
    with output_file(dest, force=args.force, option=None, advice=advice) as tmp:
        tmp.write_text(text, encoding="utf-8")
    if not args.quiet:
        print(f"wrote {dest}")
    return 0
