"""Command-line interface: ``imubounds <command> ...``.

Each command lives in its own module with a ``register(subparsers)`` function
that adds its parser and sets ``func``. Errors the user can fix
(:class:`imubounds.errors.ImuboundsError`) are printed as one line on stderr
with exit code 2, never as a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from imubounds import __version__
from imubounds.errors import ImuboundsError

# Command modules, in the order they appear in ``--help``.
COMMAND_MODULES: tuple[str, ...] = (
    "static",
    "simulate_noise",
    "simulate",
    "convert",
    "dynamic",
    "fleet",
    "report",
    "demo",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="imubounds",
        description="How much to trust a MEMS IMU: stationary noise (Allan variance, "
        "noise terms, stochastic models) and guaranteed dynamic error margins.",
    )
    parser.add_argument("--version", action="version", version=f"imubounds {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMAND_MODULES:
        module = importlib.import_module(f"imubounds.cli.{name}")
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    args.argv = argv
    # The command line alone chooses the figure backend and touches numba caches;
    # importing the library does neither.
    os.environ.setdefault("MPLBACKEND", "Agg")
    from imubounds import _numba_cache

    _numba_cache.refresh_all()
    try:
        code = args.func(args)
    except ImuboundsError as err:
        print(f"imubounds: error: {err}", file=sys.stderr)
        return err.exit_code
    except KeyboardInterrupt:
        print("imubounds: interrupted; no partial output was written", file=sys.stderr)
        return 130
    return int(code or 0)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
