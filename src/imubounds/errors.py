"""Exceptions that the CLI turns into one-line messages with exit code 2.

The library raises these for anything the user can fix (bad input, bad options,
data that cannot support the requested analysis). Programming errors stay as
ordinary exceptions so that they are not disguised as user errors.

Every class subclasses :class:`ValueError`, so ``except ValueError`` in a
notebook catches them too::

    ImuboundsError(ValueError)
    ├── InputError          a file, column or row cannot be used as given
    │   └── UnitsError      a value's unit is unknown or implausible
    ├── OptionError         an option or argument is invalid or inconsistent
    ├── AnalysisError       valid data that cannot support the analysis asked for
    └── OutputError         the results cannot be written where asked
"""

from __future__ import annotations


class ImuboundsError(ValueError):
    """Base class: a problem the user can act on. ``str(err)`` is one line."""

    exit_code: int = 2


class InputError(ImuboundsError):
    """The input data (a file, a column, a row) cannot be used as given."""


class UnitsError(InputError):
    """A unit is unknown, or the values are implausible for the unit they claim."""


class OptionError(ImuboundsError):
    """A command-line option or function argument is invalid or inconsistent."""


class AnalysisError(ImuboundsError):
    """The data are valid but cannot support the requested analysis
    (for example a log too short for the requested averaging time)."""


class OutputError(ImuboundsError):
    """The output cannot be written: it would overwrite something the run did not create,
    another run is writing the same directory, or the file system refused."""
