"""Errors a user can act on. The CLI prints them as one line and exits with status 2."""

from __future__ import annotations

import math
import numbers
import os
from typing import Literal, overload


class ArtmotionError(Exception):
    """Base class of errors that are reported to the user as a single line."""

    exit_code = 2


class InputError(ArtmotionError, ValueError):
    """Bad input: missing or corrupt file, malformed line, NaN, empty data, wrong shape.

    ``InputError("non-positive width", path="det.txt", line=12)`` reads
    ``det.txt:12: non-positive width``.
    """

    def __init__(self, message: str, path: str | os.PathLike | None = None, line: int | None = None):
        self.path = None if path is None else os.fsdecode(path)
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

    def __init__(self, signum: int, kept: str | None = None):
        super().__init__(signum)
        self.signum = signum
        #: what the interrupted command kept, said on the one line it prints (else a general note)
        self.kept = kept


def one_line(message: str) -> str:
    """``message`` on one line: its non-blank lines stripped and joined by spaces (an error from a
    library, e.g. GTSAM's indeterminate system, can run over several); a file name's bytes that are
    not UTF-8 (lone surrogates, which a strict stream refuses to print) written as ``\\udce9``."""
    line = " ".join(part.strip() for part in message.splitlines() if part.strip())
    return line.encode("utf-8", "backslashreplace").decode("utf-8")


#: largest seed NumPy's legacy generators and scikit-learn accept (``[0, 2**32 - 1]``)
MAX_SEED = 2**32 - 1


def _interval(lo, hi, lo_open: bool, hi_open: bool) -> str:
    def fmt(v):
        return f"{v:g}" if isinstance(v, float) else str(v)

    return f"{'(' if lo_open else '['}{fmt(lo)}, {fmt(hi)}{')' if hi_open else ']'}"


def check_range(name: str, value, lo, hi, *, lo_open: bool = False, hi_open: bool = False,
                integer: bool = False, path: str | os.PathLike | None = None, line: int | None = None):
    """``value`` if it is a finite number (a whole one with ``integer``) in the interval from
    ``lo`` to ``hi`` (ends closed unless ``lo_open``/``hi_open``); else an :class:`InputError`
    that names ``name`` and the interval, e.g. ``--fps must be a number in [0.001, 1000], got inf``.

    Booleans and strings are not numbers. For command-line options, numeric fields of files
    (``path``/``line`` name where) and model parameters alike."""
    kind = "a whole number" if integer else "a number"
    if not isinstance(value, numbers.Real) or isinstance(value, bool):
        raise InputError(f"{name} must be {kind} in {_interval(lo, hi, lo_open, hi_open)}, got {value!r}",
                         path=path, line=line)
    value = value.item() if hasattr(value, "item") else value        # a NumPy scalar
    if (not math.isfinite(value) or (integer and value != int(value))
            or (value <= lo if lo_open else value < lo) or (value >= hi if hi_open else value > hi)):
        raise InputError(f"{name} must be {kind} in {_interval(lo, hi, lo_open, hi_open)}, got {value:g}"
                         if isinstance(value, float) else
                         f"{name} must be {kind} in {_interval(lo, hi, lo_open, hi_open)}, got {value}",
                         path=path, line=line)
    return int(value) if integer else value


@overload
def check_bool(name: str, value, *, none: Literal[False] = ...) -> bool: ...
@overload
def check_bool(name: str, value, *, none: bool) -> bool | None: ...
def check_bool(name: str, value, *, none: bool = False) -> bool | None:
    """``value`` as a bool if it is one (Python's or NumPy's; ``None`` too with ``none``); else an
    :class:`InputError`: a string such as ``"no"`` is true to Python, so a switch given one would
    silently be on (scikit-learn refuses it the same way)."""
    if value is None and none:
        return None
    if isinstance(value, bool) or (type(value).__module__ == "numpy" and type(value).__name__ in ("bool", "bool_")):
        return bool(value)
    raise InputError(f"{name} must be True or False{' (or None)' if none else ''}, got {value!r}")


def check_seed(seed, name: str = "--seed") -> int:
    """A random seed as NumPy and scikit-learn take it: a whole number in ``[0, 2**32 - 1]``."""
    return check_range(name, seed, 0, MAX_SEED, integer=True)


def need_package(module: str, extra: str, what: str) -> None:
    """An :class:`InputError` saying how to install an optional package (``module``, from the extra
    ``extra``) when ``what`` needs it and it is missing."""
    import importlib.util

    if importlib.util.find_spec(module) is None:
        raise InputError(f"{module} is not installed ({what} needs it): pip install 'artmotion[{extra}]' (or make install)")


def _holds_non_real(arr, np) -> bool:
    """Whether an object array holds text or a complex number of any kind (Python's, NumPy's
    scalars and arrays); by the elements' types, each type looked at once."""
    types = set(map(type, arr.flat))
    if any(issubclass(t, (str, bytes, complex, np.complexfloating)) for t in types):
        return True
    return any(issubclass(t, np.ndarray) for t in types) and any(
        isinstance(v, np.ndarray) and v.dtype.kind in "cSUV" for v in arr.flat)


def float_array(value, name: str):
    """``value`` as a float NumPy array, else an :class:`InputError` saying that ``name`` must be
    an array of numbers (text, ragged lists, objects, complex numbers: NumPy would parse ``"1.5"``
    and drop an imaginary part with only a warning). For arrays given to the Python API."""
    import numpy as np

    try:
        arr = np.asarray(value)
        if arr.dtype.kind in "cSUV" or (arr.dtype.kind == "O" and _holds_non_real(arr, np)):
            raise TypeError
        return arr.astype(float, copy=False)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be an array of numbers") from None
