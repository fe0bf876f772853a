"""The project's small exception hierarchy.

Only *bad input* raises: a solver that cannot solve an instance returns a
:class:`~hierplan_opt.core.result.Result` whose status says so.
"""

from __future__ import annotations


class HierplanError(Exception):
    """Base class of every error this package raises on purpose."""


class InputError(HierplanError, ValueError):
    """Bad input: a malformed file, an impossible instance, a bad option or argument.

    The message is one line that names what is wrong (and, for files, the file and
    line), so the CLI can print it as it is and exit with code 2.

    Example
    -------
    >>> raise InputError("map.map:3: row 1 has 4 cells, expected 5")
    Traceback (most recent call last):
    ...
    hierplan_opt.core.errors.InputError: map.map:3: row 1 has 4 cells, expected 5
    """


class UnknownSolverError(InputError):
    """A solver name that is not in the registry."""


class OptionError(InputError):
    """An option a solver does not know, or a value it cannot take."""


class OutputError(InputError):
    """An output that cannot be written: a missing folder, a device, a full disk, ...

    Raised before any work when the path is checked, or when writing fails; the
    message names the file, and the CLI exits with code 2 like for bad input.
    """
