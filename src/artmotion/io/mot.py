"""MOTChallenge text files: ``frame,id,x,y,w,h,conf,X,Y,Z`` (1-based frames, top-left box, pixels)."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from artmotion.errors import InputError, float_array
from artmotion.io.atomic import atomic_write
from artmotion.io.files import as_path, number, read_text

MOT_COLUMNS = ("frame", "id", "x", "y", "w", "h", "conf", "X", "Y", "Z")
#: the largest frame number of a sequence (also the largest ``seqLength`` of a seqinfo.ini)
MAX_FRAME = 10_000_000
#: track ids are whole numbers of at most this size (SQLite and NumPy hold them exactly)
MAX_ID = 2**31 - 1
#: box coordinates and sizes in pixels lie within +-this
MAX_COORD = 1e6
#: the most boxes one frame may hold: a crowd of MOT20 has a few hundred; tens of thousands are a
#: detector's raw output before non-maximum suppression, which association and scoring (a cost
#: matrix of every pair in a frame) would take hours or all memory over
MAX_BOXES_PER_FRAME = 2000


def read_mot(path: str | os.PathLike, *, require_sorted: bool = False, allow_empty: bool = True) -> np.ndarray:
    """Read a MOTChallenge file into an ``(N, 10)`` float array.

    Rows may have 6 to 10 comma- (or whitespace-) separated numbers; missing trailing columns
    are filled with ``conf=1`` and ``X=Y=Z=-1``. Every problem is reported as an
    :class:`InputError` naming the file and line: non-numeric, NaN or infinite values, a frame
    or track id that is not a whole number in range (:data:`MAX_FRAME`, :data:`MAX_ID`),
    non-positive width or height, coordinates beyond :data:`MAX_COORD`, more than
    :data:`MAX_BOXES_PER_FRAME` boxes in one frame, frames out of order (``require_sorted``), text
    that is not UTF-8.
    """
    path = as_path(path, "a MOTChallenge file")
    text = read_text(path, "a MOTChallenge file")
    rows: list[list[float]] = []
    last_frame = -math.inf
    per_frame: dict[float, int] = {}
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        # commas or spaces separate values; a field between two commas must hold one (an empty one
        # would shift the rest); a trailing comma is common and harmless
        fields = [f.strip() for f in line.removesuffix(",").split(",")]
        if "" in fields:
            raise InputError(f"empty field {fields.index('') + 1} in {line!r}", path=path, line=lineno)
        parts = " ".join(fields).split()
        if not 6 <= len(parts) <= 10:
            raise InputError(f"expected 6 to 10 values, found {len(parts)}", path=path, line=lineno)
        try:
            values = [number(p) for p in parts]
        except ValueError:
            raise InputError(f"non-numeric value in {line!r}", path=path, line=lineno) from None
        if not all(math.isfinite(v) for v in values):
            raise InputError("NaN or infinite value", path=path, line=lineno)
        frame, tid, x, y, w, h = values[:6]
        if frame < 1 or frame != int(frame) or frame > MAX_FRAME:
            raise InputError(f"frame must be a positive integer in [1, {MAX_FRAME}], got {parts[0]}", path=path,
                             line=lineno)
        if tid != int(tid) or abs(tid) > MAX_ID:
            raise InputError(f"track id must be a whole number in [-{MAX_ID}, {MAX_ID}], got {parts[1]}", path=path,
                             line=lineno)
        if w <= 0 or h <= 0:
            raise InputError(f"non-positive box size {w:g}x{h:g}", path=path, line=lineno)
        if max(abs(x), abs(y), w, h) > MAX_COORD:
            raise InputError(f"box {x:.10g},{y:.10g},{w:.10g},{h:.10g} out of range: coordinates and sizes must lie in "
                             f"[-{MAX_COORD:g}, {MAX_COORD:g}] pixels", path=path, line=lineno)
        if require_sorted and frame < last_frame:
            raise InputError(f"frame {int(frame)} out of order (after frame {int(last_frame)})", path=path, line=lineno)
        last_frame = max(last_frame, frame)
        per_frame[frame] = per_frame.get(frame, 0) + 1
        if per_frame[frame] > MAX_BOXES_PER_FRAME:
            raise InputError(f"more than {MAX_BOXES_PER_FRAME} boxes in frame {int(frame)}, more than artmotion "
                             "reads in one frame (a detector's output before non-maximum suppression?)",
                             path=path, line=lineno)
        defaults = [1.0, -1.0, -1.0, -1.0]
        rows.append(values + defaults[len(values) - 6 :])
    if not rows and not allow_empty:
        raise InputError("empty file: no boxes", path=path)
    return np.asarray(rows, dtype=float).reshape(-1, 10)


def check_ids(arr: np.ndarray, what: str, path: str | os.PathLike | None) -> None:
    """Integer ids, each at most once per frame, in MOT rows ``arr``; else an :class:`InputError`
    naming ``what`` and its ``path``."""
    ids = arr[:, 1]
    if (ids != np.round(ids)).any():
        raise InputError(f"{what}: track ids must be integers", path=path)
    if len(arr) < 2:
        return
    pairs = arr[:, :2]
    uniq, counts = np.unique(pairs, axis=0, return_counts=True)
    if (counts > 1).any():
        f, i = uniq[np.argmax(counts > 1)]
        raise InputError(f"{what}: id {int(i)} appears more than once in frame {int(f)}", path=path)


def mot_columns(path: str | os.PathLike) -> int:
    """The most values a row of the MOTChallenge file ``path`` holds (0 when it has none): 9 for
    MOT16/17 ground truth (``frame,id,x,y,w,h,consider,class,visibility``), which :func:`read_mot`
    pads to 10 like every other file. Rows of 9 values among rows of another count are an
    :class:`InputError`: which rules score the file would hang on one line."""
    widths = [(k, len(" ".join(line.strip().removesuffix(",").split(",")).split()))
              for k, line in enumerate(read_text(Path(path), "a MOTChallenge file").splitlines(), start=1)
              if line.strip() and not line.strip().startswith("#")]
    nine = next((k for k, w in widths if w == 9), None)
    other = next(((k, w) for k, w in widths if w != 9), None)
    if nine is not None and other is not None:
        raise InputError(f"{other[1]} values on this line but 9 on line {nine} (MOT16/17 ground truth has 9 on every "
                         "line): one file, one layout", path=path, line=other[0])
    return max((w for _, w in widths), default=0)


#: MOT16/17's class of a pedestrian (column 8 of its ground truth), and its classes
MOT17_PEDESTRIAN = 1
MOT17_CLASSES = frozenset(range(1, 14))


def mot17_people(rows: np.ndarray) -> np.ndarray:
    """The rows of MOT16/17 ground truth (read by :func:`read_mot`) that are people to score or
    describe: pedestrians (class 1) with consider = 1; the others are occluders, distractors,
    vehicles and reflections (MOTChallenge's rules, as ``artmotion eval`` applies them)."""
    return rows[(rows[:, 7] == MOT17_PEDESTRIAN) & (np.trunc(rows[:, 6]) != 0)]


def check_mot_rows(rows, what: str = "tracks") -> np.ndarray:
    """``rows`` as an ``(N, >=6)`` float array that :func:`read_mot` would accept back (whole
    frames in ``[1, MAX_FRAME]`` and ids, finite values, positive sizes, coordinates within
    :data:`MAX_COORD`, at most :data:`MAX_BOXES_PER_FRAME` boxes a frame); else an
    :class:`InputError` naming ``what``. For arrays given to the API, which no file reader checked."""
    arr = float_array(rows, what)
    if arr.size == 0:
        return arr.reshape(0, 10)
    if arr.ndim != 2 or arr.shape[1] < 6:
        raise InputError(f"{what}: expected MOT rows, an (N, >=6) array (frame, id, x, y, w, h, ...), "
                         f"got shape {arr.shape}")
    head = arr[:, :min(arr.shape[1], 7)]
    if not np.isfinite(head).all():
        raise InputError(f"{what}: NaN or infinite value")
    frames, ids = arr[:, 0], arr[:, 1]
    if ((frames < 1) | (frames > MAX_FRAME) | (frames != np.round(frames))).any():
        raise InputError(f"{what}: frames must be whole numbers in [1, {MAX_FRAME}]")
    if ((np.abs(ids) > MAX_ID) | (ids != np.round(ids))).any():
        raise InputError(f"{what}: track ids must be whole numbers in [-{MAX_ID}, {MAX_ID}]")
    if (arr[:, 4:6] <= 0).any():
        raise InputError(f"{what}: non-positive box size")
    if (np.abs(arr[:, 2:6]) > MAX_COORD).any():
        raise InputError(f"{what}: coordinates and sizes must lie in [-{MAX_COORD:g}, {MAX_COORD:g}] pixels")
    order = np.sort(frames)
    counts = np.bincount(np.searchsorted(order, frames))
    if counts.max() > MAX_BOXES_PER_FRAME:
        raise InputError(f"{what}: {int(counts.max())} boxes in frame {int(order[int(np.argmax(counts))])}, more "
                         f"than artmotion reads in one frame ({MAX_BOXES_PER_FRAME})")
    return arr


def _check_written_sizes(rows: np.ndarray, what: str) -> None:
    """An :class:`InputError` for a box whose width or height :func:`write_mot` would write as
    ``0.00`` (under 0.005 pixels; :func:`read_mot` refuses a non-positive size) or whose score
    its 4 significant digits would round to infinity (beyond 1.7976e308). Only the values near
    those limits are formatted to tell, as the file is written (so the rounding is the same)."""
    for k in np.flatnonzero((rows[:, 4:6] < 0.01).any(axis=1)):
        w, h = float(rows[k, 4]), float(rows[k, 5])
        if float(f"{w:.2f}") <= 0.0 or float(f"{h:.2f}") <= 0.0:
            raise InputError(f"{what}: box size {w:g}x{h:g} (frame {int(rows[k, 0])}, id {int(rows[k, 1])}) would "
                             "be written as 0 at the file's 2 decimals, which read_mot refuses: widths and heights "
                             "must be at least 0.005 pixels")
    if rows.shape[1] > 6:
        for k in np.flatnonzero(np.abs(rows[:, 6]) > 1e308):
            conf = float(rows[k, 6])
            if not math.isfinite(float(f"{conf:.4g}")):
                raise InputError(f"{what}: score {conf:g} (frame {int(rows[k, 0])}, id {int(rows[k, 1])}) would be "
                                 "written as infinity at the file's 4 significant digits, which read_mot refuses")


def write_mot(path: str | os.PathLike, rows: np.ndarray) -> None:
    """Write ``(N, >=6)`` rows as MOTChallenge text, atomically, sorted by frame then id
    (:func:`check_mot_rows` first, and a box size that would be written as ``0.00``, the two
    decimals of the file, is refused: never a file :func:`read_mot` would refuse). These are
    results: columns 8-10 are written -1, and rows that hold anything else there are refused."""
    what = f"rows for {os.fspath(as_path(path, 'an output'))}"
    rows = check_mot_rows(rows, what)
    if rows.shape[1] > 7 and not (rows[:, 7:10] == -1).all():
        # ground truth's consider/class/visibility (MOT16/17) or a 3-D position were dropped
        # silently: a round trip through this writer changed the scores against that file
        raise InputError(f"{what}: columns 8-10 hold values other than -1 (ground truth's class and "
                         "visibility?): write_mot writes results, whose last three columns are -1")
    if rows.size:
        _check_written_sizes(rows, what)
        rows = rows[np.lexsort((rows[:, 1], rows[:, 0]))]
    with atomic_write(path) as fh:
        for r in rows:
            conf = r[6] if r.shape[0] > 6 else 1.0
            fh.write(
                f"{int(r[0])},{int(r[1])},{r[2]:.2f},{r[3]:.2f},{r[4]:.2f},{r[5]:.2f},{conf:.4g},-1,-1,-1\n"
            )
