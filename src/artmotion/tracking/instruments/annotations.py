"""Surgical instrument annotations (``tools.csv``) and prediction files.

An annotation file has the header ``frame,tool,y,x,scale,angle`` (the columns in any order) and one
row per instrument per frame:

* ``frame`` -- the frame number (the number in the PNG file's name), a whole number ``>= 0``;
* ``tool`` -- the index of the annotation within its frame (0, 1, ...): not an identity, the order
  of the instruments may change from frame to frame;
* ``y``, ``x`` -- the instrument's head in pixels (row, column);
* ``scale`` -- the apparent size of the head in pixels (``> 0``);
* ``angle`` -- the orientation of the shaft seen from the head, in radians, measured from ``+x``
  towards ``+y`` (image coordinates: x right, y down).

A predictions file has the header ``frame,track,x,y,scale,angle,score``: ``track`` is a persistent
identity (a whole number ``>= 0``) and ``score`` a confidence in ``[0, 1]``.

Both are CSV: a field may be quoted (``"frame","tool",...``, as spreadsheets export), the column
names are read in any case (``Frame``) and blank lines are skipped. An annotation file may have
further columns (an export's ``label``, ``visible``): they are not read, and ``read_tools_csv``
names them to its caller (``artmotion tool train|eval`` say so) -- every column it needs must be
there, so a misspelt one is still an error, while a column such as ``visible`` is not silently
taken into account. A predictions file, artmotion's own, has its columns only.

Every problem -- a missing, unknown (predictions) or repeated column, a row with the
wrong number of fields, a value that is not a finite number, a frame, tool or track that is not a
whole number in range, a non-positive scale, a coordinate beyond ``+-1e6`` px, a tool or track
given twice in one frame, a file without rows -- is an :class:`InputError` naming the file and line.
"""

from __future__ import annotations

import csv
import io
import math
import os
from pathlib import Path

import numpy as np

from artmotion.errors import InputError, check_range
from artmotion.io.atomic import atomic_write
from artmotion.io.files import number, read_text
from artmotion.io.mot import MAX_BOXES_PER_FRAME, MAX_COORD, MAX_FRAME, MAX_ID

__all__ = ["TOOLS_COLUMNS", "PREDICTION_COLUMNS", "read_tools_csv", "read_predictions", "write_predictions", "wrap_angle"]

#: the columns of an annotation file (in the order of the shared ``tools.csv``)
TOOLS_COLUMNS = ("frame", "tool", "y", "x", "scale", "angle")
#: the largest angle (radians, either sign) a file may give
MAX_RADIANS = 1e6
#: the columns of a predictions file, in the order :func:`write_predictions` writes them
PREDICTION_COLUMNS = ("frame", "track", "x", "y", "scale", "angle", "score")

_Rows = dict[int, dict[int, dict[str, float]]]


def wrap_angle(angle: float) -> float:
    """``angle`` (radians) wrapped to ``[0, 2*pi)``."""
    a = math.fmod(angle, math.tau)
    if a < 0:
        a += math.tau
    return 0.0 if a >= math.tau else a      # -1e-17 + 2*pi rounds to 2*pi


def _header(fields: list[str], columns: tuple[str, ...], path: Path, lineno: int, extra: list[str] | None) -> list[str]:
    """The column names of a header row (lower case), checked against ``columns`` (any order, any
    case, each once); other columns are an error, or, given a list ``extra``, added to it."""
    names = [f.strip().lower() for f in fields]
    seen: set[str] = set()
    for field, name in zip(fields, names):
        if name in seen:
            raise InputError(f"duplicate column {field.strip()!r}", path=path, line=lineno)
        seen.add(name)
        if name not in columns:
            if extra is None:
                raise InputError(f"unknown column {field.strip()!r} (expected {','.join(columns)})", path=path,
                                 line=lineno)
            extra.append(field.strip())
    missing = [c for c in columns if c not in seen]
    if missing:
        raise InputError(f"missing column{'s' if len(missing) > 1 else ''} {', '.join(map(repr, missing))}",
                         path=path, line=lineno)
    return names


def _csv_rows(text: str, path: Path, what: str):
    """``(line number, fields)`` of the CSV ``text``'s rows that are not blank (quoted fields read
    as the :mod:`csv` module reads them, as :func:`artmotion.io.table.read_csv` does)."""
    reader = csv.reader(io.StringIO(text, newline=""))
    try:
        for row in reader:
            if any(f.strip() for f in row):
                yield reader.line_num, row
    except csv.Error as exc:
        raise InputError(f"not {what} (CSV): {exc}", path=path, line=reader.line_num) from None


def _read_rows(path: Path, columns: tuple[str, ...], ident: str, what: str, nothing: str | None,
               extra: list[str] | None = None) -> _Rows:
    """The checked rows of a CSV file with the header ``columns``: frame -> ``ident`` -> values
    (``nothing``: the error when it has no rows; ``None``: none is fine, a header is needed;
    ``extra``: a list to which the names of further columns are added, which are then not read;
    ``None``: they are an error)."""
    text = read_text(path, what)
    names: list[str] | None = None
    rows: _Rows = {}
    first_line: dict[tuple[int, int], int] = {}
    for lineno, fields in _csv_rows(text, path, what):
        if names is None:
            names = _header(fields, columns, path, lineno, extra)
            continue
        if len(fields) != len(names):
            raise InputError(f"expected {len(names)} columns, got {len(fields)}", path=path, line=lineno)
        values: dict[str, float] = {}
        for name, field in zip(names, fields):
            if name not in columns:  # a further column (``extra``): not read
                continue
            try:
                v = number(field.strip())
            except ValueError:
                raise InputError(f"{name} is not a number: {field.strip()!r}", path=path, line=lineno) from None
            if not math.isfinite(v):
                raise InputError(f"{name} is not finite: {field.strip()!r}", path=path, line=lineno)
            values[name] = v
        frame = check_range("frame", values["frame"], 0, MAX_FRAME, integer=True, path=path, line=lineno)
        key = check_range(ident, values[ident], 0, MAX_ID, integer=True, path=path, line=lineno)
        for name in ("x", "y"):
            if abs(values[name]) > MAX_COORD:
                raise InputError(f"{name} out of range: coordinates must lie in [-{MAX_COORD:g}, {MAX_COORD:g}] px, "
                                 f"got {values[name]:g}", path=path, line=lineno)
        if not 0 < values["scale"] <= MAX_COORD:
            raise InputError(f"scale must be a number in (0, {MAX_COORD:g}] px, got {values['scale']:g}",
                             path=path, line=lineno)
        if "score" in values:
            check_range("score", values["score"], 0.0, 1.0, path=path, line=lineno)
        # (radians, any turn: beyond 1e6 a float no longer says where in the turn it is)
        check_range("angle", values["angle"], -MAX_RADIANS, MAX_RADIANS, path=path, line=lineno)
        if (frame, key) in first_line:
            raise InputError(f"duplicate {ident} {key} in frame {frame} (first on line {first_line[frame, key]})",
                             path=path, line=lineno)
        first_line[frame, key] = lineno
        in_frame = rows.setdefault(frame, {})
        if len(in_frame) >= MAX_BOXES_PER_FRAME:
            raise InputError(f"more than {MAX_BOXES_PER_FRAME} rows in frame {frame}, more than artmotion reads "
                             "in one frame", path=path, line=lineno)
        in_frame[key] = values
    if names is None:
        raise InputError(f"no header (expected {','.join(columns)})", path=path)
    if not rows and nothing is not None:
        raise InputError(nothing, path=path)
    return rows


def read_tools_csv(path: str | os.PathLike, extra: list[str] | None = None) -> dict[int, np.ndarray]:
    """Read instrument annotations (see the module doc).

    Returns frame number -> float array ``(k, 4)`` of ``x, y, scale, angle`` (angle wrapped to
    ``[0, 2*pi)``), frames ascending, the rows of a frame in the order of their ``tool`` index.
    Further columns are not read; their names are added to ``extra`` when it is given (a list).
    """
    path = Path(path)
    extra = [] if extra is None else extra
    rows = _read_rows(path, TOOLS_COLUMNS, "tool", "an instrument annotation file", "no annotations", extra)
    return {frame: np.array([[v["x"], v["y"], v["scale"], wrap_angle(v["angle"])]
                             for _, v in sorted(rows[frame].items())], dtype=float).reshape(-1, 4)
            for frame in sorted(rows)}


def read_predictions(path: str | os.PathLike) -> dict[int, np.ndarray]:
    """Read instrument predictions (see the module doc).

    Returns frame number -> float array ``(k, 6)`` of ``track, x, y, scale, angle, score`` (angle
    wrapped to ``[0, 2*pi)``), frames ascending, the rows of a frame by increasing track.
    """
    path = Path(path)
    # (no rows is an answer: 'tool track' found no instrument)
    rows = _read_rows(path, PREDICTION_COLUMNS, "track", "an instrument predictions file", None)
    return {frame: np.array([[track, v["x"], v["y"], v["scale"], wrap_angle(v["angle"]), v["score"]]
                             for track, v in sorted(rows[frame].items())], dtype=float).reshape(-1, 6)
            for frame in sorted(rows)}


def _scale_text(scale: float) -> str:
    """``scale`` with 2 decimals, or 3 significant digits when 2 decimals would read as 0."""
    text = f"{scale:.2f}"
    return text if float(text) > 0 else f"{scale:.3g}"


def _check_predictions(path: Path, pred: dict[int, np.ndarray]) -> list[tuple[int, np.ndarray]]:
    """The frames of ``pred`` ascending, each a checked ``(k, 6)`` array sorted by track: what
    :func:`read_predictions` would accept back (an :class:`InputError` naming ``path`` if not)."""
    out = []
    for key, value in pred.items():
        if isinstance(key, bool) or not isinstance(key, (int, np.integer)) or not 0 <= key <= MAX_FRAME:
            raise InputError(f"frame must be a whole number in [0, {MAX_FRAME}], got {key!r}", path=path)
        frame = int(key)
        arr = np.asarray(value, dtype=float)
        if arr.size == 0:
            continue
        if arr.ndim != 2 or arr.shape[1] != 6:
            raise InputError(f"frame {frame}: predictions must be a (k, 6) array "
                             f"(track, x, y, scale, angle, score), got shape {arr.shape}", path=path)
        if not np.all(np.isfinite(arr)):
            raise InputError(f"frame {frame}: NaN or infinite value", path=path)
        tracks = arr[:, 0]
        if np.any((tracks < 0) | (tracks != np.round(tracks)) | (tracks > MAX_ID)):
            raise InputError(f"frame {frame}: track must be a whole number in [0, {MAX_ID}]", path=path)
        if len(np.unique(tracks)) != len(tracks):
            raise InputError(f"frame {frame}: duplicate track", path=path)
        if np.any(np.abs(arr[:, 1:3]) > MAX_COORD):
            raise InputError(f"frame {frame}: coordinates must lie in [-{MAX_COORD:g}, {MAX_COORD:g}] px", path=path)
        if np.any((arr[:, 3] <= 0) | (arr[:, 3] > MAX_COORD)):
            raise InputError(f"frame {frame}: scale must be a number in (0, {MAX_COORD:g}] px", path=path)
        if np.any((arr[:, 5] < 0) | (arr[:, 5] > 1)):
            raise InputError(f"frame {frame}: score must be a number in [0, 1]", path=path)
        out.append((frame, arr[np.argsort(tracks, kind="stable")]))
    return sorted(out, key=lambda item: item[0])


def write_predictions(path: str | os.PathLike, pred: dict[int, np.ndarray]) -> None:
    """Write ``pred`` (frame -> ``(k, 6)`` rows ``track, x, y, scale, angle, score``) as a
    predictions file, atomically: frames ascending, tracks ascending within a frame; x and y with 1
    decimal, scale 2, angle (wrapped to ``[0, 2*pi)``) 4 and score 4.

    The rows are checked first, as :func:`read_predictions` would check them (whole tracks
    ``>= 0``, unique in their frame, finite values, positive scale, coordinates within ``+-1e6``,
    scores in ``[0, 1]``).
    Frames without rows write nothing; a file of no rows has only the header (reading it back
    gives no predictions: nothing was found).
    """
    path = Path(path)
    frames = _check_predictions(path, pred)
    with atomic_write(path) as fh:
        fh.write(",".join(PREDICTION_COLUMNS) + "\n")
        for frame, arr in frames:
            for track, x, y, scale, angle, score in arr:
                fh.write(f"{frame},{int(track)},{x:.1f},{y:.1f},{_scale_text(scale)},"
                         f"{wrap_angle(angle):.4f},{score:.4f}\n")
