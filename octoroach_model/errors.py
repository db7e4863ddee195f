"""
Domain errors: every failure a user can cause ends as one of these, with a one-line reason.

The CLI and the nodes catch `OctoroachError` and print ``error: <message>``; nothing else
should reach a user as a traceback.
"""
from __future__ import annotations


class OctoroachError(Exception):
    """Base of all errors the package raises on purpose (bad input, bad parameters)."""


class BagError(OctoroachError):
    """A bag cannot be read, or holds no usable pose stream."""


class DataError(OctoroachError):
    """The runs are unusable for the request (too few, too short, non-finite)."""


class ParameterError(OctoroachError):
    """A model or validation parameter is out of its range."""
