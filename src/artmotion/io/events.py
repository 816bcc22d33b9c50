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
import os
from collections.abc import Iterable
from pathlib import Path

from artmotion.errors import InputError
from artmotion.io.atomic import atomic_write
from artmotion.io.files import read_text
from artmotion.io.mot import MAX_COORD, MAX_FRAME, MAX_ID

REQUIRED = ("type", "frame", "tracks")
#: the event types of the tracker (docs/interfaces.md)
EVENT_TYPES = ("enter", "exit", "merge", "split")
#: where an enter/exit event happens: the image border it crosses, or inside the image
SIDES = ("left", "right", "top", "bottom", "inside")


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _not_json_constant(name: str):
    raise ValueError(f"{name} is not a number JSON allows")


def event_problem(ev) -> str | None:
    """What is wrong with one event object (see the module doc), or ``None``."""
    if not isinstance(ev, dict) or any(k not in ev for k in REQUIRED):
        return f"an event needs keys {', '.join(REQUIRED)}"
    if ev["type"] not in EVENT_TYPES:
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
    if ev.get("side") is not None and ev["side"] not in SIDES:
        return f"unknown side {ev['side']!r} (sides: {', '.join(SIDES)})"
    if "group" in ev and not (_is_int(ev["group"]) and abs(ev["group"]) <= MAX_ID):
        return f"'group' must be an integer id in [-{MAX_ID}, {MAX_ID}]"
    if "end_frame" in ev and not (_is_int(ev["end_frame"]) and ev["frame"] <= ev["end_frame"] <= MAX_FRAME):
        return f"'end_frame' must be an integer in [frame, {MAX_FRAME}]"
    for key in ("x", "y"):
        v = ev.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not abs(v) <= MAX_COORD):
            return f"{key!r} must be a number in [-{MAX_COORD:g}, {MAX_COORD:g}], got {v!r}"
    return None


def read_events(path: str | os.PathLike) -> list[dict]:
    """Read and validate an events file; raise :class:`InputError` naming file and line."""
    path = Path(path)
    events = []
    for lineno, line in enumerate(read_text(path, "an events file").split("\n"), start=1):
        if not line.strip():
            continue
        try:
            ev = json.loads(line, parse_constant=_not_json_constant)
        except json.JSONDecodeError as exc:
            raise InputError(f"not JSON: {exc.msg}", path=path, line=lineno) from None
        except (ValueError, RecursionError) as exc:
            raise InputError(f"not JSON: {exc}", path=path, line=lineno) from None
        problem = event_problem(ev)
        if problem is not None:
            raise InputError(problem, path=path, line=lineno)
        events.append(ev)
    return events


def write_events(path: str | os.PathLike, events: Iterable[dict]) -> None:
    """Write events as JSON lines, atomically, in the given order; each is checked as
    :func:`read_events` checks it (never a file it would refuse)."""
    events = list(events)
    for k, ev in enumerate(events):
        problem = event_problem(ev)
        if problem is not None:
            raise InputError(f"event {k + 1} for {os.fspath(path)}: {problem}")
    with atomic_write(path) as fh:
        for ev in events:
            fh.write(json.dumps(ev, sort_keys=False, allow_nan=False) + "\n")
