"""Tracking events as JSON lines.

One object per line, with at least ``type`` (``enter``, ``exit``, ``merge``, ``split``, or another
verb), ``frame`` (1-based) and ``tracks`` (list of track ids). Optional keys: ``side`` (``left``,
``right``, ``top``, ``bottom`` or ``inside`` for enter/exit), ``group`` (group id for merge/split),
``end_frame``, ``x``, ``y``. The language capability turns these into sentences.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Iterable

from artmotion.errors import InputError
from artmotion.io.atomic import atomic_write

REQUIRED = ("type", "frame", "tracks")


def read_events(path: str | os.PathLike) -> list[dict]:
    """Read and validate an events file; raise :class:`InputError` naming file and line."""
    path = Path(path)
    if not path.is_file():
        raise InputError("no such file", path=path)
    events = []
    with open(path, encoding="utf-8") as fh:
        for lineno, line in enumerate(fh, start=1):
            if not line.strip():
                continue
            try:
                ev = json.loads(line)
            except json.JSONDecodeError as exc:
                raise InputError(f"not JSON: {exc.msg}", path=path, line=lineno) from None
            if not isinstance(ev, dict) or any(k not in ev for k in REQUIRED):
                raise InputError(f"an event needs keys {', '.join(REQUIRED)}", path=path, line=lineno)
            if not isinstance(ev["tracks"], list) or not all(isinstance(t, int) for t in ev["tracks"]):
                raise InputError("'tracks' must be a list of integer ids", path=path, line=lineno)
            if not isinstance(ev["frame"], int) or ev["frame"] < 1:
                raise InputError("'frame' must be a positive integer", path=path, line=lineno)
            events.append(ev)
    return events


def write_events(path: str | os.PathLike, events: Iterable[dict]) -> None:
    """Write events as JSON lines, atomically, in the given order."""
    with atomic_write(path) as fh:
        for ev in events:
            fh.write(json.dumps(ev, sort_keys=False) + "\n")
