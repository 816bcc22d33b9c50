"""Errors a user can act on. The CLI prints them as one line and exits with status 2."""

from __future__ import annotations

import os


class ArtmotionError(Exception):
    """Base class of errors that are reported to the user as a single line."""

    exit_code = 2


class InputError(ArtmotionError, ValueError):
    """Bad input: missing or corrupt file, malformed line, NaN, empty data, wrong shape.

    ``InputError("non-positive width", path="det.txt", line=12)`` reads
    ``det.txt:12: non-positive width``.
    """

    def __init__(self, message: str, path: str | os.PathLike | None = None, line: int | None = None):
        self.path = None if path is None else os.fspath(path)
        self.line = line
        self.reason = message
        where = ""
        if self.path is not None:
            where = self.path + (f":{line}" if line is not None else "") + ": "
        super().__init__(where + message)


class Interrupted(BaseException):
    """The user or the system asked the program to stop (SIGINT, SIGTERM, SIGHUP): raised by the
    command line's signal handlers so that every ``finally`` runs and temporary outputs are
    removed. Not an :class:`Exception`: nothing catches it by accident."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum
