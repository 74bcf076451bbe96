"""Exceptions that the CLI turns into one-line messages with exit code 2.

The library raises these for anything the user can fix (bad input, bad options,
data that cannot support the requested analysis). Programming errors stay as
ordinary exceptions so that they are not disguised as user errors.
"""

from __future__ import annotations


class ImuboundsError(Exception):
    """Base class: a problem the user can act on. ``str(err)`` is one line."""

    exit_code: int = 2


class InputError(ImuboundsError):
    """The input data (a file, a column, a row) cannot be used as given."""


class OptionError(ImuboundsError):
    """A command-line option or function argument is invalid or inconsistent."""


class AnalysisError(ImuboundsError):
    """The data are valid but cannot support the requested analysis
    (for example a log too short for the requested averaging time)."""
