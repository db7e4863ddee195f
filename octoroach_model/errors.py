"""
Domain errors and exit codes: every failure a user can cause ends as one of these.

The CLI and the nodes catch `OctoroachError` and print ``error: <message>``; nothing else
should reach a user as a traceback. Every program (offline commands and ROS nodes) ends with
the exit code of the kind of failure (`exit_code`), the one table README.md and docs/index.md
show:

====  ==============================================================================
code  meaning
====  ==============================================================================
0     done
1     the data or a value cannot be used (a bad input file, too few runs, a bad spec)
2     usage: the command line or a ROS parameter given at start is malformed or out
      of range
3     the output cannot be written: it exists already, is not writable, or another
      run is writing it
130   interrupted (Ctrl-C, SIGTERM where a program stops early)
====  ==============================================================================
"""
from __future__ import annotations

EXIT_OK = 0
EXIT_DATA = 1
EXIT_USAGE = 2
EXIT_OUTPUT = 3
EXIT_INTERRUPTED = 130
# code -> what it means, for --help texts and the docs' table (test_docs checks the docs)
EXIT_CODES: dict[int, str] = {
    EXIT_OK: 'done',
    EXIT_DATA: 'the data or a value cannot be used',
    EXIT_USAGE: 'usage error (command line, ROS parameter at start)',
    EXIT_OUTPUT: 'the output cannot be written (exists, not writable, in use)',
    EXIT_INTERRUPTED: 'interrupted',
}


class OctoroachError(Exception):
    """Base of all errors the package raises on purpose (bad input, bad parameters)."""

    exit_code = EXIT_DATA


class BagError(OctoroachError):
    """A bag cannot be read, or holds no usable pose stream."""


class DataError(OctoroachError):
    """The runs are unusable for the request (too few, too short, non-finite)."""


class ShapeError(DataError, ValueError):
    """Arrays of a shape or kind `Paths` cannot hold (a ValueError too, as Paths raised one)."""


class ParameterError(OctoroachError):
    """A model or validation parameter is out of its range."""


class OutputError(OctoroachError):
    """An output path cannot be written: it exists, is not writable, or is in use."""

    exit_code = EXIT_OUTPUT


def exit_code(error: BaseException) -> int:
    """Return the exit code of a failure (the table in the module docstring)."""
    if isinstance(error, KeyboardInterrupt):
        return EXIT_INTERRUPTED
    return getattr(error, 'exit_code', EXIT_DATA)
