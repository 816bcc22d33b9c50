"""Say what happened: tracks, tracking events and pose sequences to subject–verb–adjective triplets.

Thesis 5.1. Inputs are the tracker's MOT results (``frame,id,x,y,w,h,...``), optionally its events
(JSON lines: enter/exit with a side, merge/split with the members and a group) and a pose sequence
(``PRED.csv`` from ``artmotion pose predict``). Without events, entering and exiting are derived
from the tracks: a track that starts (ends) after the first (before the last) frame of the file
enters (exits) from the image border its box touches, or appears (vanishes) inside the image.

Motion sentences come from each track's smoothed centre: the track is cut where its direction of
motion changes (runs shorter than ``min_segment`` frames are absorbed by their neighbours) and each
piece is told by its net displacement (``moves right``, ``moves left and upwards``, ``stays in
place``). Interactions come from pairs of tracks that stay near each other (centre distance below
``near`` box heights) with similar velocity for at least ``min_together`` frames: two tracks of the
same class "walk together" (persons) or "move together"; otherwise one "interacts with" the other.
Two moving tracks whose distance shrinks (grows) steadily for at least ``min_segment`` frames, by at least
``min_move`` box heights, until they are (since they were) ``near`` each other, "move towards each
other" ("move apart").
The pose attribute "opens"/"closes" is read from the opening angle with hysteresis.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from artmotion.errors import InputError, check_bool, check_range, float_array
from artmotion.geometry import box_center
from artmotion.io.events import EVENT_TYPES, event_problem
from artmotion.io.media import MAX_FPS, MIN_FPS
from artmotion.io.mot import MAX_COORD, MAX_FRAME, MAX_ID, check_ids, check_mot_rows
from artmotion.io.table import MAX_ANGLE, cell_number, read_csv
from artmotion.language.grammar import SIDES, Triplet, join_subjects, noun_phrase, render


@dataclass
class DescribeParams:
    smooth: int = 5  # moving-average window of the centre, frames
    window: int = 10  # displacement window for the per-frame direction, frames
    still: float = 0.02  # below this speed (box heights per frame) a track counts as still
    diagonal: float = 0.5  # minor/major displacement ratio above which both directions are said
    min_segment: int = 10  # shortest motion segment, frames
    min_move: float = 0.5  # net displacement (box heights) below which a segment "stays in place"
    near: float = 1.0  # centre distance (box heights) for two tracks to be together
    same_velocity: float = 0.03  # velocity difference (box heights per frame) to move together
    min_together: int = 25  # frames two tracks must be together to say so
    max_gap: int = 5  # frames of not-together tolerated inside a together run
    border: float = 0.03  # margin (fraction of the smaller image side, at least 8 px) to call a border

    def checked(self, name: str = "params") -> DescribeParams:
        """A copy with every field checked (an :class:`InputError` naming ``params.FIELD``
        otherwise) and the frame counts made ints (a whole float such as ``5.0`` counts too):
        ``smooth`` and ``max_gap`` whole numbers >= 0 (``smooth`` 0 or 1: no smoothing),
        ``window``, ``min_segment`` and ``min_together`` whole numbers >= 1, the other fields
        finite numbers >= 0 (``border`` a fraction, at most 1)."""
        counts = {"smooth": 0, "window": 1, "min_segment": 1, "min_together": 1, "max_gap": 0}
        values: dict[str, int] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in counts:
                values[f.name] = check_range(f"{name}.{f.name}", v, counts[f.name], MAX_FRAME, integer=True)
            else:
                check_range(f"{name}.{f.name}", v, 0.0, 1.0 if f.name == "border" else math.inf,
                            hi_open=f.name != "border")
        return replace(self, **values)


# --------------------------------------------------------------------------------------------
# classes


def parse_classes(specs: list[str] | None, default: str = "person") -> tuple[str, dict[int, str]]:
    """``["person", "3=cart"]`` -> ``("person", {3: "cart"})``; a bare name sets the default."""
    per_track: dict[int, str] = {}
    bare: str | None = None
    for spec in specs or []:
        spec = spec.strip()
        tid, _, name = spec.rpartition("=")
        try:
            k, word = (int(tid), _class_word(name)) if "=" in spec else (None, _class_word(spec))
        except ValueError:
            raise InputError(f"--class {spec!r}: expected NAME or ID=NAME (a name of letters, spaces "
                             "and hyphens)") from None
        earlier = bare if k is None else per_track.get(k)
        if earlier not in (None, word):     # (which of the two was meant is not known)
            raise InputError(f"--class {spec!r}: {'every track' if k is None else f'track {k}'} was given the "
                             f"class {earlier!r} already")
        if k is None:
            default = bare = word
        else:
            per_track[k] = word
    return default, per_track


def _is_class_name(name) -> bool:
    """Letters of any script ("café", "Überwagen"), spaces and hyphens: a noun a sentence can hold
    (a line break in it split a sentence over two lines)."""
    return isinstance(name, str) and re.fullmatch(r"[^\W\d_](?:[^\W\d_]|[ \-])*", name.strip()) is not None


def _class_word(name: str) -> str:
    if not _is_class_name(name):
        raise ValueError(name)
    return name.strip().lower()


# --------------------------------------------------------------------------------------------
# tracks


@dataclass
class Track:
    tid: int
    frames: np.ndarray  # contiguous frames from first to last
    cx: np.ndarray  # centre, linearly interpolated over gaps
    cy: np.ndarray
    height: float  # median box height
    first_box: np.ndarray  # x, y, w, h at the first and last observed frame
    last_box: np.ndarray


def tracks_from_mot(rows: np.ndarray) -> dict[int, Track]:
    """Group an ``(N, >=6)`` MOT array by track id, interpolating the centre over gaps."""
    rows = np.asarray(rows, dtype=float)
    out: dict[int, Track] = {}
    if not len(rows):
        return out
    rows = rows[np.lexsort((rows[:, 0], rows[:, 1]))]           # by track, then frame (stable)
    cuts = np.flatnonzero(np.diff(rows[:, 1])) + 1
    for r in np.split(rows, cuts):
        tid = int(r[0, 1])
        f = r[:, 0].astype(int)
        f, first = np.unique(f, return_index=True)  # duplicate frames: keep the first box
        r = r[first]
        c = box_center(r[:, 2:6])
        frames = np.arange(f[0], f[-1] + 1)
        out[int(tid)] = Track(
            tid=int(tid),
            frames=frames,
            cx=np.interp(frames, f, c[:, 0]),
            cy=np.interp(frames, f, c[:, 1]),
            height=float(max(np.median(r[:, 5]), 1.0)),
            first_box=r[0, 2:6].copy(),
            last_box=r[-1, 2:6].copy(),
        )
    return out


def _smooth(v: np.ndarray, k: int) -> np.ndarray:
    if k <= 1 or len(v) < 3:
        return v.copy()
    k = min(k, len(v))
    pad = np.pad(v, (k // 2, k - 1 - k // 2), mode="edge")
    return np.convolve(pad, np.ones(k) / k, mode="valid")


def direction_word(dx: float, dy: float, diagonal: float = 0.5) -> str:
    """Image coordinates (y down) to ``left``/``right``/``upwards``/``downwards`` or a pair."""
    h = "right" if dx > 0 else "left"
    v = "downwards" if dy > 0 else "upwards"
    ax, ay = abs(dx), abs(dy)
    if ax >= ay:
        return f"{h} and {v}" if ay > diagonal * ax else h
    return f"{h} and {v}" if ax > diagonal * ay else v


def _velocity(t: Track, p: DescribeParams) -> tuple[np.ndarray, np.ndarray]:
    sx, sy = _smooth(t.cx, p.smooth), _smooth(t.cy, p.smooth)
    n = len(sx)
    w = max(1, min(p.window, n - 1)) if n > 1 else 1
    idx = np.arange(n)
    a = np.clip(idx - w // 2, 0, n - 1)
    b = np.clip(a + w, 0, n - 1)
    a = np.clip(b - w, 0, n - 1)
    span = np.maximum(b - a, 1)
    return (sx[b] - sx[a]) / span, (sy[b] - sy[a]) / span


def motion_segments(
    t: Track, p: DescribeParams, velocity: tuple[np.ndarray, np.ndarray] | None = None
) -> list[tuple[int, int, str | None]]:
    """Cut a track into pieces of constant direction: ``(first, last, adjective or None=still)``.

    ``velocity`` is the track's ``_velocity(t, p)`` when the caller has it already.
    """
    n = len(t.frames)
    if n < 2:
        return [(int(t.frames[0]), int(t.frames[-1]), None)]
    vx, vy = _velocity(t, p) if velocity is None else velocity
    speed = np.hypot(vx, vy) / t.height
    labels = [None if s < p.still else direction_word(x, y, p.diagonal) for s, x, y in zip(speed, vx, vy)]
    # run-length encode, then absorb short runs into the longer neighbour
    runs: list[list] = []
    for i, lab in enumerate(labels):
        if runs and runs[-1][2] == lab:
            runs[-1][1] = i
        else:
            runs.append([i, i, lab])
    changed = True
    while changed and len(runs) > 1:
        changed = False
        lengths = [r[1] - r[0] + 1 for r in runs]
        k = int(np.argmin(lengths))
        if lengths[k] < p.min_segment:
            if k == 0:
                j = 1
            elif k == len(runs) - 1:
                j = k - 1
            else:
                j = k - 1 if lengths[k - 1] >= lengths[k + 1] else k + 1
            lo, hi = min(runs[k][0], runs[j][0]), max(runs[k][1], runs[j][1])
            runs[j] = [lo, hi, runs[j][2]]
            del runs[k]
            merged: list[list] = []
            for r in runs:
                if merged and merged[-1][2] == r[2]:
                    merged[-1][1] = r[1]
                else:
                    merged.append(r)
            runs = merged
            changed = True
    out: list[tuple[int, int, str | None]] = []
    for i0, i1, _ in runs:
        dx, dy = t.cx[i1] - t.cx[i0], t.cy[i1] - t.cy[i0]
        adj = None if math.hypot(dx, dy) < p.min_move * t.height else direction_word(dx, dy, p.diagonal)
        if out and out[-1][2] == adj:  # re-labelled neighbours that now agree
            out[-1] = (out[-1][0], int(t.frames[i1]), adj)
        else:
            out.append((int(t.frames[i0]), int(t.frames[i1]), adj))
    return out


def border_side(box: np.ndarray, size: tuple[float, float], p: DescribeParams) -> str:
    """Which image border a box ``x, y, w, h`` touches, or ``inside``."""
    W, H = size
    x, y, w, h = box
    margin = max(8.0, p.border * min(W, H))
    d = {"left": x, "right": W - (x + w), "top": y, "bottom": H - (y + h)}
    side = min(d, key=d.__getitem__)
    return side if d[side] <= margin else "inside"


def _image_size(size) -> tuple[float, float]:
    """``size`` as ``(width, height)``, two numbers in ``(0, MAX_COORD]`` (a NumPy pair too); else an
    :class:`InputError` (an array was "ambiguous", a number a TypeError)."""
    try:
        s = np.asarray(size, dtype=float)
    except (TypeError, ValueError):
        s = np.zeros(0)
    if s.shape != (2,) or not all(0 < v <= MAX_COORD for v in s):
        raise InputError(f"image size must be (width, height) in pixels, got {size!r}")
    return float(s[0]), float(s[1])


def check_image_size(rows: np.ndarray, size, path: str | os.PathLike | None = None) -> None:
    """An :class:`InputError` (naming ``path``, the tracks' file) unless ``size`` is an image
    ``(width, height)`` the boxes of ``rows`` fit: a box may stand partly out of the image, its
    centre hardly; a quarter of the image beyond a border means the size is wrong (entries and
    exits would be said at the wrong sides)."""
    w, h = _image_size(size)
    if not len(rows):
        return
    c = box_center(rows[:, 2:6])
    off = (c[:, 0] < -w / 4) | (c[:, 0] > 1.25 * w) | (c[:, 1] < -h / 4) | (c[:, 1] > 1.25 * h)
    if off.any():
        x, y = c[off][0]
        raise InputError(f"a box's centre ({x:g}, {y:g}) lies far outside the {w:g}x{h:g} image: is the image "
                         f"size right?", path=path)


def infer_image_size(rows: np.ndarray) -> tuple[float, float]:
    """Image width and height guessed from the extent of the boxes."""
    return float(np.max(rows[:, 2] + rows[:, 4])), float(np.max(rows[:, 3] + rows[:, 5]))


@dataclass
class _Pair:
    """Two tracks over the frames they share: the first shared frame ``f0``, each track's slice of
    them (``ia``, ``ib``), their mean box height ``h`` and centre distance ``dist`` in heights."""

    f0: int
    ia: slice
    ib: slice
    h: float
    dist: np.ndarray


def _pair(a: Track, b: Track) -> _Pair | None:
    """:class:`_Pair` of tracks ``a`` and ``b``, or None if they share no frame."""
    f0, f1 = max(a.frames[0], b.frames[0]), min(a.frames[-1], b.frames[-1])
    if f1 < f0:
        return None
    ia = slice(int(f0 - a.frames[0]), int(f1 - a.frames[0]) + 1)
    ib = slice(int(f0 - b.frames[0]), int(f1 - b.frames[0]) + 1)
    h = 0.5 * (a.height + b.height)
    return _Pair(int(f0), ia, ib, h, np.hypot(a.cx[ia] - b.cx[ib], a.cy[ia] - b.cy[ib]) / h)


def _near_pairs(tracks: list[Track], near: float) -> Iterator[tuple[int, int]]:
    """The ids ``(a, b)`` of the pairs of ``tracks`` (``a`` listed first) that share a frame and whose
    centres' extents come within ``near`` of their mean height: every pair that can be together or
    approach each other (both need a frame closer than ``near``); the others are not looked at,
    which keeps many tracks (a long video) from costing a Python call per pair."""
    if len(tracks) < 2:
        return
    ids = np.array([t.tid for t in tracks])
    first = np.array([t.frames[0] for t in tracks])
    last = np.array([t.frames[-1] for t in tracks])
    x0, x1 = np.array([t.cx.min() for t in tracks]), np.array([t.cx.max() for t in tracks])
    y0, y1 = np.array([t.cy.min() for t in tracks]), np.array([t.cy.max() for t in tracks])
    h = np.array([t.height for t in tracks])
    for i in range(len(tracks) - 1):
        j = np.arange(i + 1, len(tracks))
        gx = np.maximum(0.0, np.maximum(x0[i], x0[j]) - np.minimum(x1[i], x1[j]))
        gy = np.maximum(0.0, np.maximum(y0[i], y0[j]) - np.minimum(y1[i], y1[j]))
        ok = (np.maximum(first[i], first[j]) <= np.minimum(last[i], last[j])) & \
            (np.hypot(gx, gy) <= near * 0.5 * (h[i] + h[j]))
        for k in j[ok]:
            yield int(ids[i]), int(ids[k])


def _together_runs(
    pair: _Pair, va: tuple[np.ndarray, np.ndarray], vb: tuple[np.ndarray, np.ndarray], p: DescribeParams
) -> list[tuple[int, int, bool]]:
    """Runs ``(first, last, moving)`` in which the tracks of ``pair`` (velocities ``va``, ``vb``) are together."""
    if len(pair.dist) < p.min_together:
        return []
    f0, ia, ib, h, dist = pair.f0, pair.ia, pair.ib, pair.h, pair.dist
    vax, vay = va
    vbx, vby = vb
    dv = np.hypot(vax[ia] - vbx[ib], vay[ia] - vby[ib]) / h
    moving = 0.5 * (np.hypot(vax[ia], vay[ia]) + np.hypot(vbx[ib], vby[ib])) / h >= p.still
    ok = (dist < p.near) & (dv < p.same_velocity)
    runs, start, gap = [], None, 0
    for i, v in enumerate(ok):
        if v:
            if start is None:
                start = i
            gap, last = 0, i
        elif start is not None:
            gap += 1
            if gap > p.max_gap:
                runs.append((start, last))
                start, gap = None, 0
    if start is not None:
        runs.append((start, last))
    return [
        (int(f0 + s), int(f0 + e), bool(np.mean(moving[s : e + 1]) > 0.5))
        for s, e in runs
        if e - s + 1 >= p.min_together
    ]


def _approach_runs(
    pair: _Pair, va: tuple[np.ndarray, np.ndarray], vb: tuple[np.ndarray, np.ndarray], p: DescribeParams
) -> list[tuple[int, int, str]]:
    """Runs ``(first, last, verb)`` in which the tracks of ``pair`` (velocities ``va``, ``vb``), both
    moving, steadily close in on each other ("move towards each other") or draw apart ("move apart")."""
    n = len(pair.dist)
    if n < p.min_segment:
        return []
    f0, ia, ib, h, dist = pair.f0, pair.ia, pair.ib, pair.h, pair.dist
    w = max(1, min(p.window, n // 2))
    rate = np.zeros(n)
    rate[w:n - w] = (dist[2 * w:] - dist[: n - 2 * w]) / (2 * w)
    label = np.where(rate < -p.still, -1, np.where(rate > p.still, 1, 0))
    both = np.minimum(np.hypot(va[0][ia], va[1][ia]), np.hypot(vb[0][ib], vb[1][ib])) / h >= p.still
    label[~both] = 0  # one of them stands still: that one is not moving towards (away from) the other
    runs = []
    i = 0
    while i < n:
        j = i
        while j + 1 < n and label[j + 1] == label[i]:
            j += 1
        if label[i] != 0 and j - i + 1 >= p.min_segment and abs(dist[j] - dist[i]) >= p.min_move:
            if label[i] < 0 and dist[j] <= p.near:
                runs.append((int(f0 + i), int(f0 + j), "move towards each other"))
            elif label[i] > 0 and dist[i] <= p.near:
                runs.append((int(f0 + i), int(f0 + j), "move apart"))
        i = j + 1
    return runs


def _groups(walks: list[tuple[int, int, int, int]], overlap: float = 0.7):
    """Join pairwise "together" runs ``(a, b, first, last)`` sharing a track and overlapping in time
    (intersection over union >= ``overlap``) into groups; yield ``(members, (first, last))``, the
    frames when all members walk together. A chain of runs with no such frame (each person beside
    the next, the first and last never together) yields its runs one by one."""
    parent = list(range(len(walks)))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, (a1, b1, f1, l1) in enumerate(walks):
        for j in range(i + 1, len(walks)):
            a2, b2, f2, l2 = walks[j]
            if not {a1, b1} & {a2, b2}:
                continue
            inter = min(l1, l2) - max(f1, f2) + 1
            union = max(l1, l2) - min(f1, f2) + 1
            if inter > 0 and inter / union >= overlap:
                parent[find(i)] = find(j)
    comps: dict[int, list[int]] = {}
    for i in range(len(walks)):
        comps.setdefault(find(i), []).append(i)
    for idx in comps.values():
        first = max(walks[i][2] for i in idx)
        last = min(walks[i][3] for i in idx)
        if last - first < 1:
            for i in idx:
                yield sorted(walks[i][:2]), (walks[i][2], walks[i][3])
            continue
        yield sorted({t for i in idx for t in walks[i][:2]}), (first, last)


# --------------------------------------------------------------------------------------------
# pose


def read_pose(path: str | os.PathLike, column: str | None = None) -> tuple[np.ndarray, np.ndarray, str]:
    """Frames, angles and the chosen column of a ``PRED.csv`` (``image,<name>,<name>_std,...``).

    ``column`` defaults to the first angle column whose name contains ``open``. Frames are the
    last number in each image name when those are distinct and increasing, else the row number.
    """
    header, rows = read_csv(path, what="pose prediction CSV")
    if "image" not in header:
        raise InputError("not a pose prediction CSV: no 'image' column in the header", path=path, line=1)
    # (a column is a std when its angle is there too: an angle may be named 'open_std' itself)
    angles = [h for h in header if h != "image" and not (h.endswith("_std") and h[:-4] in header)]
    if column is None:
        cands = [h for h in angles if "open" in h.lower()]
        if not cands:
            raise InputError(f"no opening-angle column (name containing 'open') among {angles}; use --pose-column",
                             path=path, line=1)
        column = cands[0]
    elif column not in angles:
        what = "no column" if column not in header else "not an angle column:"
        raise InputError(f"{what} {column!r} (angle columns: {', '.join(angles) or 'none'})", path=path, line=1)
    ci, ii = header.index(column), header.index("image")
    names, values = [], []
    seen: dict[str, int] = {}
    for lineno, row in rows:
        # every angle and its std is checked, read or not: a damaged row is not half believed
        cells = [None if j == ii else cell_number(row[j], h, path, lineno, 0.0 if h.endswith("_std") else -MAX_ANGLE,
                                                  MAX_ANGLE) for j, h in enumerate(header)]
        values.append(cells[ci])
        if row[ii] in seen:    # (a repeated row shifted every later frame by one)
            raise InputError(f"image {row[ii]!r} twice (lines {seen[row[ii]]} and {lineno})", path=path, line=lineno)
        seen[row[ii]] = lineno
        names.append(row[ii])
    if not values:
        raise InputError("empty: no predictions", path=path)
    nums = [re.findall(r"\d+", Path(n).stem) for n in names]
    frames = np.arange(1, len(values) + 1)
    if all(nums) and all(len(n[-1]) <= 7 for n in nums):     # frame numbers up to MAX_FRAME's digits
        cand = np.array([int(n[-1]) for n in nums])
        if np.all(np.diff(cand) > 0) and cand[0] >= 0:
            frames = cand + (1 if cand[0] == 0 else 0)
    return frames.astype(int), np.asarray(values), column


def check_pose(frames, angles, what: str = "pose") -> tuple[np.ndarray, np.ndarray]:
    """A pose sequence checked: ``frames`` (an int array) whole numbers in ``[1, MAX_FRAME]``,
    increasing, and ``angles`` (a float array) finite, in ``[-MAX_ANGLE, MAX_ANGLE]`` degrees, one
    per frame (both 1-D, of the same length; empty is allowed); else an :class:`InputError`
    naming ``what`` (``pose`` of :func:`describe`)."""
    f, a = float_array(frames, f"{what} frames"), float_array(angles, f"{what} angles")
    if f.ndim != 1 or a.ndim != 1:
        raise InputError(f"{what} frames and angles must be 1-D sequences, got shapes {f.shape} and {a.shape}")
    if len(f) != len(a):
        raise InputError(f"{what} frames and angles must be as many, one angle per frame, got {len(f)} frames "
                         f"and {len(a)} angles")
    if not np.all(np.isfinite(f) & (f >= 1) & (f <= MAX_FRAME) & (f == np.round(f))):
        bad = f[~(np.isfinite(f) & (f >= 1) & (f <= MAX_FRAME) & (f == np.round(f)))][0]
        raise InputError(f"{what} frames must be whole numbers in [1, {MAX_FRAME}], got {bad:g}")
    if np.any(np.diff(f) <= 0):
        i = int(np.flatnonzero(np.diff(f) <= 0)[0])
        raise InputError(f"{what} frames must increase, got frame {f[i + 1]:g} after frame {f[i]:g}")
    ok = np.isfinite(a) & (np.abs(a) <= MAX_ANGLE)
    if not np.all(ok):
        i = int(np.flatnonzero(~ok)[0])
        raise InputError(f"{what} angles must be finite numbers in [-{MAX_ANGLE:g}, {MAX_ANGLE:g}] degrees, "
                         f"got {a[i]:g} at frame {f[i]:g}")
    return f.astype(np.int64), a


def _threshold(name: str, value) -> float | None:
    """An opening or closing angle: None, or a finite number in ``[-MAX_ANGLE, MAX_ANGLE]``."""
    return None if value is None else float(check_range(name, value, -MAX_ANGLE, MAX_ANGLE))


MIN_POSE_RANGE = 10.0  # degrees: a smaller spread of the opening angle is noise, not opening/closing


def pose_changes(
    frames: np.ndarray, angles: np.ndarray, open_above: float | None = None, close_below: float | None = None,
    min_range: float = MIN_POSE_RANGE,
) -> list[tuple[int, str, float]]:
    """``(frame, "opens"|"closes", angle)`` at each state change, with hysteresis.

    The state becomes open when the angle rises to ``open_above`` and closed when it falls to
    ``close_below``; in between it keeps its state. Defaults: 65% and 35% of the way between the
    10th and 90th percentile of the angles, provided they lie at least ``min_range`` degrees apart
    (else the jaw held still and nothing is said). The initial state is not an event.

    ``frames`` and ``angles`` are checked by :func:`check_pose` (whole increasing frames, finite
    angles, as many of each); an empty sequence has no changes. The thresholds are None or finite
    numbers in ``[-MAX_ANGLE, MAX_ANGLE]``, ``close_below`` not above ``open_above``, and
    ``min_range`` a finite number >= 0; else an :class:`InputError`.
    """
    frames, angles = check_pose(frames, angles)
    open_above, close_below = _threshold("open_above", open_above), _threshold("close_below", close_below)
    check_range("min_range", min_range, 0.0, math.inf, hi_open=True)
    if not len(angles):
        return []
    lo, hi = np.percentile(angles, [10, 90])
    auto_open, auto_close = open_above is None, close_below is None
    if open_above is None or close_below is None:
        if hi - lo < min_range:
            return []
        open_above = lo + 0.65 * (hi - lo) if open_above is None else open_above
        close_below = lo + 0.35 * (hi - lo) if close_below is None else close_below
    if close_below > open_above:
        raise InputError(f"close_below {close_below:g}{' (automatic)' if auto_close else ''} is above "
                         f"open_above {open_above:g}{' (automatic)' if auto_open else ''}")
    state, out = None, []
    for f, a in zip(frames, angles):
        new = state
        if a >= open_above:
            new = "open"
        elif a <= close_below:
            new = "closed"
        if state is not None and new != state:
            out.append((int(f), "opens" if new == "open" else "closes", float(a)))
        state = new
    return out


# --------------------------------------------------------------------------------------------
# all together


def events_from_tracks(tracks: np.ndarray, size: tuple[float, float] | None = None,
                       params: DescribeParams | None = None) -> list[dict]:
    """Enter and exit events of MOTChallenge ``tracks`` for a tracker that gives none: a track that
    starts after the first frame enters (by the image border its first box touches, else
    ``inside``: it appears); one that ends before the last frame exits (or vanishes)."""
    p = _params(params)
    tracks = check_mot_rows(tracks, "tracks")       # (NaN rows, 3 columns, text: errors from deep inside)
    if size is not None:
        size = _image_size(size)
    if not len(tracks):
        return []
    return _track_events(tracks_from_mot(tracks), tracks, size, p)


def _track_events(table: dict, tracks: np.ndarray, size, p: DescribeParams) -> list[dict]:
    """:func:`events_from_tracks` on the tracks' ``table`` (:func:`tracks_from_mot` of ``tracks``)."""
    size = size or infer_image_size(tracks)
    first, last = int(tracks[:, 0].min()), int(tracks[:, 0].max())
    events = []
    for tid, t in table.items():
        if t.frames[0] > first:
            events.append({"type": "enter", "frame": int(t.frames[0]), "tracks": [tid],
                           "side": border_side(t.first_box, size, p)})
        if t.frames[-1] < last:
            events.append({"type": "exit", "frame": int(t.frames[-1]), "tracks": [tid],
                           "side": border_side(t.last_box, size, p)})
    return sorted(events, key=lambda e: (e["frame"], e["type"]))


def _params(params) -> DescribeParams:
    """``params`` (None: the defaults) checked, its counts as ints."""
    if params is None:
        return DescribeParams()
    if not isinstance(params, DescribeParams):
        raise InputError(f"params must be a DescribeParams, got {type(params).__name__}")
    return params.checked()


def _check_classes(classes) -> tuple[str, dict[int, str]]:
    """``classes`` = ``(default class, {track id: class})`` checked: names text, ids whole numbers."""
    if not (isinstance(classes, tuple) and len(classes) == 2 and isinstance(classes[1], dict)):
        raise InputError(f"classes must be (default class, {{track id: class}}), got {classes!r}")
    default_cls, per_track = classes
    if not _is_class_name(default_cls):
        raise InputError(f"classes: the default class must be text (a class name: letters, spaces and hyphens), "
                         f"got {default_cls!r}")
    for tid, name in per_track.items():
        check_range("classes: a track id", tid, -MAX_ID, MAX_ID, integer=True)
        if not _is_class_name(name):
            raise InputError(f"classes: the class of track {tid} must be text (a class name: letters, spaces and "
                             f"hyphens), got {name!r}")
    return default_cls.strip(), {tid: name.strip() for tid, name in per_track.items()}


def _told(ev: dict) -> tuple:
    """What :func:`describe` tells of a valid event, as plain values: two events with one key would
    be told alike (``1`` and ``np.int64(1)`` alike; a position and keys outside the grammar are
    not told)."""
    def whole(v):
        return None if v is None else int(v)

    side = ev.get("side")
    return (str(ev["type"]), int(ev["frame"]), tuple(int(t) for t in ev["tracks"]),
            None if side is None else str(side), whole(ev.get("group")), whole(ev.get("end_frame")))


def describe(
    tracks: np.ndarray,
    events: list[dict] | None = None,
    *,
    pose: tuple[np.ndarray, np.ndarray] | None = None,
    classes: tuple[str, dict[int, str]] = ("person", {}),
    pose_subject: str = "tool",
    pose_track: int | None = None,
    open_above: float | None = None,
    close_below: float | None = None,
    image_size: tuple[float, float] | None = None,
    fps: float | None = None,
    params: DescribeParams | None = None,
    size_known: bool = False,
) -> list[Triplet]:
    """Triplets (with their sentences) for tracks, events and a pose sequence, ordered by frame.

    ``pose``: ``(frames, angles)`` of the opening angle, checked by :func:`check_pose` (whole
    frames in increasing order, one finite angle each; an empty sequence says nothing about the
    pose); ``open_above``/``close_below`` None (automatic) or finite angles (:func:`pose_changes`).
    ``classes``: ``(default class, {track id: class})``, names as text. ``params``: a
    :class:`DescribeParams` (checked by :meth:`DescribeParams.checked`). Bad input is an
    :class:`InputError` naming the parameter. ``image_size`` is checked against the boxes
    (:func:`check_image_size`: a centre far outside means a wrong size) unless ``size_known``: the
    frames' own size, e.g. a run's, where a detector's box may well reach far beyond the image."""
    p = _params(params)
    tracks = check_mot_rows(tracks, "tracks")
    check_ids(tracks, "tracks", None)
    if events is not None:
        try:
            events = list(events)       # (read twice: a generator was empty the second time, its events lost)
        except TypeError:
            raise InputError(f"events must be a list of event dicts, got {type(events).__name__}") from None
    seen: dict[tuple, int] = {}
    for k, ev in enumerate(events or []):       # types outside the grammar are passed over, unread
        if isinstance(ev, dict) and ev.get("type") not in EVENT_TYPES:
            continue
        problem = event_problem(ev)
        if problem is not None:
            raise InputError(f"event {k + 1}: {problem}")
        key = _told(ev)         # (read_events refuses a repeated line: it would be told twice)
        if key in seen:
            raise InputError(f"event {k + 1}: the same event as event {seen[key]} (repeated)")
        seen[key] = k + 1
    if fps is not None:
        check_range("fps", fps, MIN_FPS, MAX_FPS)
    if check_bool("size_known", size_known) and image_size is not None:
        _image_size(image_size)     # (the frames' own size: only the size itself, no boxes to fit it)
    elif image_size is not None:
        check_image_size(tracks, image_size)
    default_cls, per_track = _check_classes(classes)
    if not _is_class_name(pose_subject):
        raise InputError(f"pose_subject must be a class name (letters, spaces and hyphens), got {pose_subject!r}")
    pose_subject = _class_word(pose_subject)
    if pose_track is not None:
        pose_track = check_range("pose_track", pose_track, -MAX_ID, MAX_ID, integer=True)
    if pose is not None:
        try:
            frames, angles = pose
        except (TypeError, ValueError):
            raise InputError(f"pose must be a pair (frames, angles), got {type(pose).__name__}") from None
        pose = check_pose(frames, angles)
    open_above, close_below = _threshold("open_above", open_above), _threshold("close_below", close_below)
    cls_of = lambda tid: per_track.get(tid, default_cls)  # noqa: E731
    subj = lambda tid, cap=True: noun_phrase(cls_of(tid), tid, capital=cap)  # noqa: E731
    times = (lambda a, b: ((a - 1) / fps, (b - 1) / fps)) if fps else (lambda a, b: None)
    out: list[Triplet] = []

    def add(t: Triplet) -> None:
        t.times = times(*t.frames)
        render(t)
        out.append(t)

    table = tracks_from_mot(tracks) if len(tracks) else {}

    # enter / exit / merge / split (without a tracker's events: entries and exits of the tracks)
    if events is None and table:
        events = _track_events(table, tracks, image_size, p)
    if events is not None:
        for ev in events:
            if ev["type"] not in EVENT_TYPES:
                continue            # not in the grammar: nothing is said about it
            kind, f, ids = ev["type"], int(ev["frame"]), [int(i) for i in ev["tracks"]]
            span = (f, int(ev.get("end_frame", f)))
            if kind in ("enter", "exit") and ids:
                side = ev.get("side")
                side = side if side in SIDES else None
                verb = {"enter": "enters", "exit": "exits"}[kind]
                if side == "inside":
                    verb = "appears" if kind == "enter" else "vanishes"
                for tid in ids:
                    add(Triplet(subj(tid), verb, side, None, span, [tid]))
            elif kind in ("merge", "split") and ids:
                names = [subj(t, i == 0) for i, t in enumerate(ids)]
                trip = Triplet(join_subjects(names), kind, None, None, span, ids)
                if "group" in ev:
                    trip.object = f"group {ev['group']}"
                add(trip)
    # motion of each track
    vel = {tid: _velocity(t, p) for tid, t in table.items()}
    for tid, t in table.items():
        for a, b, adj in motion_segments(t, p, vel[tid]):
            if b - a + 1 < 2:
                continue
            add(Triplet(subj(tid), "stays" if adj is None else "moves", adj, None, (a, b), [tid]))

    # interactions between pairs of tracks; co-moving pairs that overlap in time form groups
    ids = sorted(table)
    walks: list[tuple[int, int, int, int]] = []
    for ta, tb in _near_pairs([table[t] for t in ids], p.near):
        pair = _pair(table[ta], table[tb])
        if pair is None:
            continue
        for a, b, moving in _together_runs(pair, vel[ta], vel[tb], p):
            if cls_of(ta) == cls_of(tb) and moving:
                walks.append((ta, tb, a, b))
            else:
                add(Triplet(subj(ta), "interacts with", None, subj(tb, False), (a, b), [ta, tb]))
        for a, b, verb in _approach_runs(pair, vel[ta], vel[tb], p):
            add(Triplet(join_subjects([subj(ta), subj(tb, False)]), verb, None, None, (a, b), [ta, tb]))
    for members, (a, b) in _groups(walks):
        dx = np.mean([table[m].cx[b - table[m].frames[0]] - table[m].cx[a - table[m].frames[0]] for m in members])
        dy = np.mean([table[m].cy[b - table[m].frames[0]] - table[m].cy[a - table[m].frames[0]] for m in members])
        h = np.mean([table[m].height for m in members])
        adj = direction_word(dx, dy, p.diagonal) if math.hypot(dx, dy) >= p.min_move * h else None
        verb = "walk together" if cls_of(members[0]) == "person" else "move together"
        names = [subj(m, k == 0) for k, m in enumerate(members)]
        add(Triplet(join_subjects(names), verb, adj, None, (a, b), list(members)))

    # pose attribute
    if pose is not None:
        frames, angles = pose
        for f, verb, _angle in pose_changes(frames, angles, open_above, close_below):
            add(Triplet(noun_phrase(pose_subject, pose_track, capital=True), verb, None, None, (f, f),
                        [] if pose_track is None else [pose_track]))

    order = {"enters": 0, "appears": 0, "merge": 1, "split": 1}
    out.sort(key=lambda t: (t.frames[0], order.get(t.verb, 2), t.tracks, t.frames[1]))
    return out
