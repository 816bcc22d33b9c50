"""Tracking events as JSON lines.

One object per line, with at least ``type`` (``enter``, ``exit``, ``merge`` or ``split``),
``frame`` (1-based) and ``tracks`` (list of track ids). Optional keys: ``side`` (``left``,
``right``, ``top``, ``bottom`` or ``inside`` for enter/exit), ``group`` (group id for merge/split),
``end_frame``, ``x``, ``y``; other keys are kept as they are. The language capability turns these
into sentences. :func:`read_events` checks every line: a type it does not know, a number that is
not finite or out of range, a value of the wrong type is an error naming the file and line, never
skipped.
"""

from __future__ import annotations

import json
import math
import numbers
import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from artmotion.errors import InputError
from artmotion.io.atomic import atomic_write
from artmotion.io.files import read_text, strict_json
from artmotion.io.mot import MAX_COORD, MAX_FRAME, MAX_ID

REQUIRED = ("type", "frame", "tracks")
#: the event types of the tracker (docs/interfaces.md)
EVENT_TYPES = ("enter", "exit", "merge", "split")
#: where an enter/exit event happens: the image border it crosses, or inside the image
SIDES = ("left", "right", "top", "bottom", "inside")


def _is_int(v) -> bool:
    """A whole number: an ``int`` or a NumPy integer, not a ``bool``."""
    return isinstance(v, numbers.Integral) and not isinstance(v, bool)


def _coordinate(v) -> bool:
    """A number (a NumPy one too, not a ``bool``) within +-:data:`MAX_COORD`, not NaN."""
    if isinstance(v, bool):
        return False
    if isinstance(v, int):
        return abs(v) <= MAX_COORD                        # (a whole number of any size)
    return isinstance(v, (float, np.integer, np.floating)) and abs(float(v)) <= MAX_COORD


def _infinite(value, where: str) -> str | None:
    """Where in a parsed JSON ``value`` a number is infinite (``1e999`` reads as ``inf``), named
    as ``'q'`` or ``'box'[2]``, or ``None``."""
    if isinstance(value, float):
        return None if math.isfinite(value) else where
    items = (value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ())
    for key, v in items:
        found = _infinite(v, (f"{where}[{key!r}]" if where else repr(key)))
        if found is not None:
            return found
    return None


class _NotJSON(ValueError):
    """A value :func:`write_events` cannot write as JSON (the message says which and why)."""


def _json_value(value, where: str):
    """``value`` in the types :mod:`json` writes, NumPy numbers as Python ones (the same digits),
    else :class:`_NotJSON`: a NaN or infinity (JSON has none), an array or another object.
    ``where`` names the value (``'x'``, ``'box'[2]``) for the message; ``""`` for an event."""
    if value is None or isinstance(value, (str, bool)):
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, numbers.Integral):              # int, NumPy integers
        return value if type(value) is int else int(value)
    if isinstance(value, float) or (isinstance(value, numbers.Real) and not isinstance(value, numbers.Rational)):
        f = float(value)                                  # (float, NumPy floats; not a Fraction)
        if not math.isfinite(f):
            raise _NotJSON(f"{where} is {f} (numbers must be finite: JSON has no NaN or infinity)")
        return value if type(value) is float else f
    if isinstance(value, (list, tuple)):
        items = [_json_value(v, f"{where}[{i}]") for i, v in enumerate(value)]
        return items if isinstance(value, list) else tuple(items)
    if isinstance(value, dict):
        out = {}
        for key, v in value.items():
            if isinstance(key, numbers.Integral) and not isinstance(key, (int, bool)):
                key = int(key)                            # a NumPy integer key, written as JSON writes an int's
            elif not (key is None or isinstance(key, (str, int, bool))
                      or isinstance(key, float) and math.isfinite(key)):
                raise _NotJSON(f"{where or 'the event'} has a key {key!r} that JSON cannot hold (keys are strings)")
            out[key] = _json_value(v, f"{where}[{key!r}]" if where else repr(key))
        return out
    if isinstance(value, np.ndarray):
        raise _NotJSON(f"{where} is a NumPy array of shape {value.shape}, which JSON cannot hold: give a list "
                       "(its .tolist())")
    raise _NotJSON(f"{where} is a {type(value).__name__}, which JSON cannot hold (numbers, strings, booleans, "
                   "lists and objects can)")


def event_problem(ev) -> str | None:
    """What is wrong with one event object (see the module doc), or ``None``."""
    if not isinstance(ev, dict) or any(k not in ev for k in REQUIRED):
        return f"an event needs keys {', '.join(REQUIRED)}"
    if not isinstance(ev["type"], str) or ev["type"] not in EVENT_TYPES:    # (text: an array "enter" compares equal)
        return f"unknown event type {ev['type']!r} (types: {', '.join(EVENT_TYPES)})"
    if not _is_int(ev["frame"]) or not 1 <= ev["frame"] <= MAX_FRAME:
        return f"'frame' must be a positive integer in [1, {MAX_FRAME}], got {ev['frame']!r}"
    tracks = ev["tracks"]
    if not isinstance(tracks, list) or not tracks or not all(_is_int(t) and abs(t) <= MAX_ID for t in tracks):
        return f"'tracks' must be a non-empty list of integer ids in [-{MAX_ID}, {MAX_ID}]"
    if len(set(tracks)) < len(tracks):
        return f"'tracks' names a track twice: {tracks}"
    if ev["type"] in ("merge", "split") and len(tracks) < 2:
        return f"a {ev['type']} is of two tracks or more, got {tracks}"
    if ev.get("side") is not None and (not isinstance(ev["side"], str) or ev["side"] not in SIDES):
        return f"unknown side {ev['side']!r} (sides: {', '.join(SIDES)})"
    if "group" in ev and not (_is_int(ev["group"]) and abs(ev["group"]) <= MAX_ID):
        return f"'group' must be an integer id in [-{MAX_ID}, {MAX_ID}]"
    if "end_frame" in ev and not (_is_int(ev["end_frame"]) and ev["frame"] <= ev["end_frame"] <= MAX_FRAME):
        return f"'end_frame' must be an integer in [frame, {MAX_FRAME}]"
    for key in ("x", "y"):
        v = ev.get(key)
        if v is not None and not _coordinate(v):
            return f"{key!r} must be a number in [-{MAX_COORD:g}, {MAX_COORD:g}], got {v!r}"
    return None


def read_events(path: str | os.PathLike) -> list[dict]:
    """Read and validate an events file; raise :class:`InputError` naming file and line. An event
    repeated (the same object on two lines) is an error, as a repeated row of a results file is:
    it would be told twice."""
    path = Path(path)
    events = []
    seen: dict[str, int] = {}
    for lineno, line in enumerate(read_text(path, "an events file").split("\n"), start=1):
        if not line.strip():
            continue
        try:
            ev = strict_json(line)
        except json.JSONDecodeError as exc:
            raise InputError(f"not JSON: {exc.msg}", path=path, line=lineno) from None
        except (ValueError, RecursionError) as exc:
            raise InputError(f"not JSON: {exc}", path=path, line=lineno) from None
        problem = event_problem(ev)
        if problem is None:
            where = _infinite(ev, "")
            if where is not None:
                problem = f"{where} is a number out of range: it overflows to infinity (numbers must be finite)"
        if problem is not None:
            raise InputError(problem, path=path, line=lineno)
        key = json.dumps(ev, sort_keys=True)
        if key in seen:
            raise InputError(f"the same event as line {seen[key]} (a line repeated)", path=path, line=lineno)
        seen[key] = lineno
        events.append(ev)
    return events


def write_events(path: str | os.PathLike, events: Iterable[dict]) -> None:
    """Write events as JSON lines, atomically, in the given order; each is checked as
    :func:`read_events` checks it (never a file it would refuse). NumPy numbers are written as
    Python's; a NaN or infinity, an array or another value JSON cannot hold is an
    :class:`InputError` naming the event and the key."""
    events = list(events)
    plain = []
    for k, ev in enumerate(events):
        problem = event_problem(ev)
        if problem is None:
            try:
                plain.append(_json_value(ev, ""))
            except _NotJSON as exc:
                problem = str(exc)
            except RecursionError:
                problem = "a value is nested too deeply (or holds itself)"
        if problem is not None:
            raise InputError(f"event {k + 1} for {os.fspath(path)}: {problem}")
    with atomic_write(path) as fh:
        for ev in plain:
            fh.write(json.dumps(ev, sort_keys=False, allow_nan=False) + "\n")
