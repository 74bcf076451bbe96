"""Command-line interface: ``imubounds <command> ...``.

Each command lives in its own module with a ``register(subparsers)`` function
that adds its parser and sets ``func``. What a user sees when something goes
wrong is one line on stderr, never a traceback:

* an invalid option: ``imubounds CMD: error: argument --x: ...`` (exit 2);
* :class:`imubounds.errors.ImuboundsError` (bad input, options, analysis,
  output): ``imubounds: error: ...`` (exit 2);
* an operating-system error (a missing or read-only folder, a full disk, an
  over-long path) and ``MemoryError``: the same one line, naming the file and
  what to do (exit 2);
* Ctrl-C (SIGINT) or SIGTERM: ``imubounds: interrupted ...`` saying truthfully
  which results, if any, were completely written before (exit 130 or 143);
  results are written through :mod:`imubounds.io.outputs`, so nothing is ever
  left half-written;
* anything else is a bug: ``imubounds: internal error ...`` (exit 70).

``imubounds --debug CMD ...`` (or ``CMD ... --debug``, or ``IMUBOUNDS_DEBUG=1``)
shows the traceback as well, and Python warnings in full.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import os
import signal
import sys
import threading
import traceback
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any, NoReturn

from imubounds.errors import ImuboundsError
from imubounds.version import __version__

# Command modules, in the order they appear in ``--help``.
COMMAND_MODULES: tuple[str, ...] = (
    "static",
    "simulate_noise",
    "simulate",
    "convert",
    "dynamic",
    "fleet",
    "report",
    "export",
    "demo",
)

#: Exit codes besides 0 and ImuboundsError.exit_code (2).
EXIT_INTERRUPTED = 130
EXIT_TERMINATED = 143
EXIT_BROKEN_PIPE = 141
EXIT_INTERNAL = 70


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (no usage block); ``--help`` shows the usage."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The parser of ``imubounds``; given the command line ``argv``, only its command's.

    Registering a command imports what its options need (the scenario tables of
    ``simulate``, the estimators of ``static``...), about half a second for all of
    them; a command line that names its command (``imubounds static ...``, after
    ``--debug`` only) gets a parser with that command alone, which parses it the same
    (its ``--help`` included). Without ``argv``, or when ``argv`` names no command
    (``--help``, ``--version``, a misspelt command), every command is registered.
    """
    only = _named_command(argv)
    if only is not None:
        parser = _parser_with((only,))
        if argv is not None and _command_token(argv) in _subparsers(parser).choices:
            return parser
    return _parser_with(COMMAND_MODULES)


def _command_token(argv: Sequence[str]) -> str | None:
    """The first argument that is not ``--debug`` (the command, if one is named)."""
    return next((a for a in argv if a != "--debug"), None)


def _named_command(argv: Sequence[str] | None) -> str | None:
    """The command module ``argv`` names (``simulate-noise`` -> ``simulate_noise``)."""
    token = None if argv is None else _command_token(argv)
    if token is None:
        return None
    module = token.replace("-", "_")
    return module if module in COMMAND_MODULES else None


def _subparsers(parser: argparse.ArgumentParser) -> Any:
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))


def _parser_with(modules: Sequence[str]) -> argparse.ArgumentParser:
    parser = _Parser(
        prog="imubounds",
        description="How much to trust a MEMS IMU: stationary noise (Allan variance, "
        "noise terms, stochastic models) and guaranteed dynamic error margins.",
    )
    parser.add_argument("--version", action="version", version=f"imubounds {__version__}")
    parser.add_argument(
        "--debug", action="store_true", help="show Python tracebacks of errors (for bug reports)"
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in modules:
        module = importlib.import_module(f"imubounds.cli.{name}")
        module.register(sub)
    for p in sub.choices.values():  # accepted after the command too
        p.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                       help=argparse.SUPPRESS)
    return parser


def run_command(argv: Sequence[str]) -> int:
    """Parse and run one command; its errors propagate (``demo`` runs its steps so)."""
    args = build_parser(list(argv)).parse_args(list(argv))
    args.argv = list(argv)
    return int(args.func(args) or 0)


def _one_line_warning(message: Any, category: type[Warning], *_: Any, **__: Any) -> None:
    text = " ".join(str(message).split())
    print(f"imubounds: warning: {category.__name__}: {text}", file=sys.stderr)


def _os_error_message(err: OSError) -> str:
    """One line for an operating-system error: what, which file, what to do."""
    what = err.strerror or str(err) or type(err).__name__
    names = [n for n in (err.filename, getattr(err, "filename2", None)) if n]
    where = f": {' -> '.join(str(n) for n in names)}" if names else ""
    advice = {
        errno.EACCES: "check the permissions, or choose another location",
        errno.EPERM: "check the permissions, or choose another location",
        errno.EROFS: "the file system is read-only; choose another location",
        errno.ENOSPC: "the disk is full; free space or choose another location (--tmpdir, -o)",
        errno.EDQUOT: "the disk quota is exhausted; free space or choose another location",
        errno.ENOENT: "check the path",
        errno.ENOTDIR: "a folder in the path is a file; check the path",
        errno.EISDIR: "give a file, not a directory",
        errno.ENAMETOOLONG: "the path or a name in it is too long; use a shorter one",
        errno.EMFILE: "too many open files; raise the limit (ulimit -n)",
        errno.EIO: "the device reported an input/output error",
    }.get(err.errno or -1, "check the file and try again")
    return f"{what}{where}; {advice}"


def _interrupted(signame: str) -> str:
    outputs = sys.modules.get("imubounds.io.outputs")  # not imported yet: nothing written
    done = outputs.committed_outputs() if outputs is not None else []
    if done:
        return (
            f"imubounds: interrupted ({signame}); complete results had been written to "
            f"{', '.join(done)}; nothing else was written"
        )
    return f"imubounds: interrupted ({signame}); nothing was written (outputs are as they were)"


class _Terminated(KeyboardInterrupt):
    """SIGTERM, handled like Ctrl-C (results are cleaned up the same way)."""


@contextmanager
def _terminate_as_interrupt() -> Iterator[None]:
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        raise _Terminated

    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``imubounds ARGV``; return the exit code (see the module docstring)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    state = {"debug": "--debug" in argv or bool(os.environ.get("IMUBOUNDS_DEBUG"))}
    with warnings.catch_warnings(), _terminate_as_interrupt():
        try:
            return _main(argv, state)
        except _Terminated:
            _trace(state["debug"])
            print(_interrupted("SIGTERM"), file=sys.stderr)
            return EXIT_TERMINATED
        except KeyboardInterrupt:
            _trace(state["debug"])
            print(_interrupted("Ctrl-C"), file=sys.stderr)
            return EXIT_INTERRUPTED
        except ImuboundsError as err:
            _trace(state["debug"])
            print(f"imubounds: error: {' '.join(str(err).split())}", file=sys.stderr)
            return err.exit_code
        except MemoryError:
            _trace(state["debug"])
            print(
                "imubounds: error: out of memory; for a large log lower --max-memory or pass "
                "--out-of-core (static, fleet), or analyse fewer --channels",
                file=sys.stderr,
            )
            return 2
        except BrokenPipeError:
            # stdout was closed by the reader (`imubounds static --json ... | head`)
            try:
                sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - silence the final flush
            except OSError:
                pass
            return EXIT_BROKEN_PIPE
        except OSError as err:
            _trace(state["debug"])
            print(f"imubounds: error: {_os_error_message(err)}", file=sys.stderr)
            return 2
        except Exception as err:  # noqa: BLE001 - a bug: say so in one line
            _trace(state["debug"])
            text = " ".join(str(err).split())[:200]
            print(
                f"imubounds: internal error ({type(err).__name__}: {text}); this is a bug: "
                "rerun with --debug and report the traceback",
                file=sys.stderr,
            )
            return EXIT_INTERNAL


def _main(argv: list[str], state: dict[str, bool]) -> int:
    if _named_command(argv) == "static":
        # One OpenBLAS thread, set before numpy loads it (parse_args does): the static
        # analysis makes only small BLAS calls, after each of which OpenBLAS's idle
        # threads spin for a while (~0.5 CPU s over a 1e6 x 6 log); a user's value wins.
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    parser = build_parser(argv)
    try:
        args = parser.parse_args(argv)
    except SystemExit as done:  # --help, --version, or an invalid option (already printed)
        return done.code if isinstance(done.code, int) else 2
    args.argv = argv
    state["debug"] = bool(getattr(args, "debug", False) or os.environ.get("IMUBOUNDS_DEBUG"))
    # The command line alone chooses the figure backend, touches numba caches and
    # tunes malloc; importing the library does none of these.
    os.environ.setdefault("MPLBACKEND", "Agg")
    from imubounds.cli import numba_cache
    from imubounds.io.outputs import reset_committed_outputs
    from imubounds.runtime import tune_malloc

    reset_committed_outputs()
    numba_cache.refresh_all()
    tune_malloc()  # freed arrays kept for reuse: ~20 % less CPU per log (imubounds.runtime)
    if not state["debug"]:
        warnings.showwarning = _one_line_warning
    return int(args.func(args) or 0)


def _trace(debug: bool) -> None:
    if debug:
        traceback.print_exc()


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
