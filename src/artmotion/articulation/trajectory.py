"""Reading trajectory files and fitting them: the API behind ``artmotion articulation fit``.

A trajectory file has one sample per row, whitespace- or comma-separated:

* ``x y`` (2-D point), ``x y z`` (3-D point) or ``x y z qx qy qz qw`` (6-D pose, unit quaternion in
  ``x, y, z, w`` order);
* optionally a leading time column. It is taken as time when ``time=True`` (``--time``), when a
  header row names a time column, or when the row has 4 or 8 columns (which only a time column
  explains). With ``time=False`` (``--no-time``) a 4- or 8-column file is an error. Without a time
  column samples are one time unit apart.

Blank lines and lines starting with ``#`` are skipped. One header row is allowed; its names decide
the columns, in any order: ``x``, ``y``, ``z``, ``qx``, ``qy``, ``qz``, ``qw`` and a time column
(``t``, ``time``, ``timestamp``, ``stamp``, ``sec``, ``secs``, ``seconds``), each name possibly
followed by a unit (``time_s``, ``x_m``, also ``x(mm)``). A header with any other name is an error (a
column taken for another one gives a confident wrong answer). A unit is honoured: positions in
``km``, ``m``, ``cm``, ``mm``, ``um`` (``µm``), ``in`` or ``ft`` are converted to metres (``px``, pixel
tracks, are kept as they are), times in ``s``, ``ms``, ``us`` (``µs``), ``ns``, ``min`` or ``h`` to
seconds (also spelt out: ``meters``, ``seconds``, ``usec``); a suffix that is no unit
(``timestamp_utc``) is read as none; the position columns share one unit (or none) and a
quaternion has none. Values must be finite, coordinates (in metres when converted) within ``±1e12``
and times (in seconds when converted) within ``±1e15``. Every error names the file and line.
"""

from __future__ import annotations

import inspect
import math
import os
import re
from dataclasses import dataclass

import numpy as np

from artmotion.articulation.online import MAX_SCALE, MAX_STEP, MIN_STEP, OnlineEstimator
from artmotion.errors import InputError, check_bool, check_range
from artmotion.geometry.rotations import axis_angle_to_matrix
from artmotion.io.files import as_path, number, read_text

__all__ = ["Trajectory", "read_trajectory", "fit_trajectory", "fit_points", "fit_poses"]

#: coordinates (data units) and times of a trajectory lie within +-these: beyond, squares and
#: sums of squares of the samples lose all precision or overflow
MAX_COORD = 1e12
MAX_TIME = 1e15
_TIME_NAMES = {"t", "time", "timestamp", "stamp", "sec", "secs", "seconds"}
_SPLIT = re.compile(r"[,\s;]+")
#: a separator at the start of a row, or two commas or semicolons with nothing but spaces between
_EMPTY_FIELD = re.compile(r"^[,;]|[,;]\s*[,;]")


#: length units a header may give the position columns (``x_mm``), in metres; ``px`` (pixel tracks)
#: is kept as it is (``None``)
LENGTH_UNITS: dict[str, float | None] = {"km": 1e3, "m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "µm": 1e-6,
                                         "in": 0.0254, "ft": 0.3048, "px": None}
#: time units a header may give the time column (``time_ms``), in seconds
TIME_UNITS: dict[str, float] = {"s": 1.0, "sec": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "ns": 1e-9,
                                "min": 60.0, "h": 3600.0}
#: other spellings of those units
_UNIT_NAMES = {"meter": "m", "meters": "m", "metre": "m", "metres": "m", "millimeter": "mm", "millimeters": "mm",
               "millimetre": "mm", "millimetres": "mm", "centimeter": "cm", "centimeters": "cm", "centimetre": "cm",
               "centimetres": "cm", "μm": "µm", "second": "s", "seconds": "s", "secs": "s", "msec": "ms",
               "usec": "us", "μs": "µs", "nsec": "ns"}


def _unit(suffix: str | None, known) -> str | None:
    """The unit ``suffix`` (what follows a column's name) names among ``known``, or ``None``: a
    marker's number first is not part of it (``x1_mm``: mm), and a suffix that is no unit
    (``timestamp_utc``, ``time_from_start``) is read as before units were honoured: as none."""
    if suffix is None:
        return None
    u = re.sub(r"^[\d_\-.()\[\] ]+", "", suffix).strip("_-.()[] ")
    u = _UNIT_NAMES.get(u, u)
    return u if u in known else None


@dataclass
class Trajectory:
    """Positions (metres when the header gave a length unit to convert), quaternions, times (seconds
    when the header gave a time unit); ``length_unit``/``time_unit``: the units the header gave
    (``None``: none, the data's own units)."""

    points: np.ndarray  # (n, 2) or (n, 3)
    quats: np.ndarray | None  # (n, 4) or None
    time: np.ndarray | None
    lines: np.ndarray  # 1-based line number of every sample
    path: str | None = None
    length_unit: str | None = None
    time_unit: str | None = None

    @property
    def kind(self) -> str:
        return "pose" if self.quats is not None else f"point{self.points.shape[1]}d"


_COORDS = ("x", "y", "z", "qx", "qy", "qz", "qw")


def _header_columns(header: list[str], path, line: int) -> tuple[int | None, list[int], str | None, str | None]:
    """The time column's index (``None``: none), the coordinate columns' indices in the order
    ``x y [z] [qx qy qz qw]``, and the units the header gives the time and the positions (``None``:
    none), from a header's names (``time_ms``, ``x_mm``, ``x(mm)``)."""
    names = [re.sub(r"[^a-z].*", "", h) for h in header]          # the letters before a unit
    units = [h[len(n):].strip("_-.()[] ") or None for h, n in zip(header, names)]
    times = [i for i, n in enumerate(names) if n in _TIME_NAMES]
    where = {n: i for i, n in enumerate(names) if n in _COORDS}
    unknown = [header[i] for i, n in enumerate(names) if n not in _TIME_NAMES and n not in _COORDS]
    if unknown or len(times) > 1 or len(where) + len(times) != len(names):
        what = (f"unknown column name {unknown[0]!r}" if unknown else
                "two time columns" if len(times) > 1 else "a column named twice")
        raise InputError(f"header: {what} (columns are named x, y, z, qx, qy, qz, qw and a time column t or "
                         "time, each possibly with a unit: time_s)", path=path, line=line)
    time_unit = _unit(units[times[0]], TIME_UNITS) if times else None
    quat_units = [header[i] for n, i in where.items()
                  if n.startswith("q") and (_unit(units[i], LENGTH_UNITS) or _unit(units[i], TIME_UNITS))]
    if quat_units:
        raise InputError(f"header: {quat_units[0]!r}: a quaternion has no unit", path=path, line=line)
    declared = {_unit(units[i], LENGTH_UNITS) for n, i in where.items() if not n.startswith("q")}
    if len(declared) > 1:
        given = ", ".join(header[i] for n, i in where.items() if not n.startswith("q"))
        raise InputError(f"header: the position columns {given} must have one unit (or none)", path=path, line=line)
    length_unit = declared.pop() if declared else None
    for wanted in (_COORDS[:2], _COORDS[:3], _COORDS):
        if set(where) == set(wanted):
            return (times[0] if times else None), [where[n] for n in wanted], time_unit, length_unit
    raise InputError(f"header: columns {', '.join(sorted(where, key=_COORDS.index))}: expected x, y; x, y, z; or "
                     "x, y, z, qx, qy, qz, qw (and a time column)", path=path, line=line)


def _is_number(text: str) -> bool:
    try:
        number(text)
    except ValueError:
        return False
    return True


def read_trajectory(path, time: bool | None = None) -> Trajectory:
    """Parse a trajectory file (see the module doc); raises :class:`InputError` naming the line."""
    time = check_bool("time", time, none=True)   # ("no" would be true: its first column read as time)
    path = os.fspath(as_path(path, "a trajectory file"))
    text = read_text(path, "a trajectory file")
    rows: list[list[float]] = []
    line_list: list[int] = []
    header = None
    header_line = 0
    ncol = None
    for no, raw in enumerate(text.splitlines(), start=1):
        s = raw.strip()
        if not s or s.startswith("#"):
            continue
        if _EMPTY_FIELD.search(s):  # (the rest would shift into its place)
            raise InputError(f"empty field in row: {s[:60]!r}", path=path, line=no)
        tok = [t for t in _SPLIT.split(s) if t]
        try:
            vals = [number(t) for t in tok]
        except ValueError:
            if not rows and header is None and not any(_is_number(t) for t in tok):
                header = [t.lower() for t in tok]   # names only: a row with a number in it is a bad row
                header_line = no
                continue
            raise InputError(f"not a number in row: {s[:60]!r}", path=path, line=no) from None
        if ncol is None:
            ncol = len(vals)
            if header is not None and len(header) != ncol:
                raise InputError(f"header has {len(header)} names but the row has {ncol} values", path=path, line=no)
        elif len(vals) != ncol:
            raise InputError(f"expected {ncol} columns, got {len(vals)}", path=path, line=no)
        if not all(math.isfinite(v) for v in vals):
            raise InputError("NaN or infinite value", path=path, line=no)
        rows.append(vals)
        line_list.append(no)
    if not rows:
        raise InputError("no samples", path=path)
    data = np.array(rows, dtype=float)
    lines = np.array(line_list)
    tcol = None
    time_unit = length_unit = None
    if header is not None:
        t_at, coords, time_unit, length_unit = _header_columns(header, path, header_line)
        if time is not None and time != (t_at is not None):
            raise InputError(f"the header {'names no' if time else 'names a'} time column, but "
                             f"{'--time' if time else '--no-time'} was given", path=path, line=header_line)
        if t_at is not None:
            tcol = data[:, t_at]
        data = data[:, coords]
        has_time = t_at is not None
    else:
        has_time = time if time is not None else ncol in (4, 8)
        if has_time:
            tcol, data = data[:, 0], data[:, 1:]
    width = data.shape[1]
    if width not in (2, 3, 7):
        what = "after the time column " if has_time else ""
        raise InputError(f"expected 2 (x y), 3 (x y z) or 7 (x y z qx qy qz qw) columns {what}but got {width}",
                         path=path, line=int(lines[0]))
    if LENGTH_UNITS.get(length_unit or "m") not in (None, 1.0):     # to metres
        data[:, :min(width, 3)] *= LENGTH_UNITS[length_unit or "m"]
    if time_unit is not None and tcol is not None:                   # to seconds
        tcol = tcol * TIME_UNITS[time_unit]
    for values, limit, what in ((data, MAX_COORD, "coordinate"), (tcol, MAX_TIME, "time")):
        if values is not None and np.any(np.abs(values) > limit):
            row = int(np.flatnonzero(np.any(np.abs(values.reshape(len(values), -1)) > limit, axis=1))[0])
            unit = ((" m" if length_unit not in (None, "px") else "") if what == "coordinate" else
                    " s" if time_unit is not None else
                    " (stamps in micro- or nanoseconds? name the time column with its unit in a header row: "
                    "time_us, time_ns)")
            raise InputError(f"{what} out of range: values must lie in [-{limit:g}, {limit:g}]{unit}", path=path,
                             line=int(lines[row]))
    if tcol is not None:
        steps = np.diff(tcol)
        bad = np.flatnonzero(steps <= 0)
        if bad.size:
            raise InputError("time must increase from row to row", path=path, line=int(lines[bad[0] + 1]))
        bad = np.flatnonzero((steps < MIN_STEP) | (steps > MAX_STEP))
        if bad.size:
            raise InputError(f"time step {steps[bad[0]]:g} from the row before: steps must lie in "
                             f"[{MIN_STEP:g}, {MAX_STEP:g}]", path=path, line=int(lines[bad[0] + 1]))
    quats = None
    if width == 7:
        quats = data[:, 3:]
        norms = np.linalg.norm(quats, axis=1)
        bad = np.flatnonzero(np.abs(norms - 1.0) > 1e-3)
        if bad.size:
            raise InputError(f"non-unit quaternion (norm {norms[bad[0]]:.4g})", path=path, line=int(lines[bad[0]]))
        data = data[:, :3]
    return Trajectory(data, quats, tcol, lines, path, length_unit=length_unit, time_unit=time_unit)


def fit_points(points, time=None, **kwargs) -> dict:
    """Algorithm 1 on a point track; the result dictionary of ``articulation fit --json``."""
    from artmotion.articulation.online import estimate_online

    res = estimate_online(points, time, **kwargs)
    out = res.to_dict()
    out["input"] = f"point{res.dim}d"
    if not res.fits:     # too few samples to fit: not estimated, as for a pose track (0.0 and [[]] were)
        out["motion"] = []
        if kwargs.get("noise") is None:
            out["noise"] = None
    out["note"] = _radius_note(res, kwargs.get("radius_range") or (0.05, 1.0))
    return out


#: how many times the track's median step a sample must lie from both its neighbours to be told
SPIKE = 50.0


def _spikes(points: np.ndarray) -> np.ndarray:
    """Indices of samples that leave the track and come back: both steps to and from them over
    :data:`SPIKE` times the median step, their neighbours within a tenth of that of each other."""
    P = np.asarray(points, dtype=float)
    if len(P) < 3:
        return np.zeros(0, dtype=int)
    steps = np.linalg.norm(np.diff(P, axis=0), axis=1)
    scale = max(float(np.median(steps)), 1e-12)
    across = np.linalg.norm(P[2:] - P[:-2], axis=1)
    far = (steps[:-1] > SPIKE * scale) & (steps[1:] > SPIKE * scale) & (across < 0.1 * np.minimum(steps[:-1], steps[1:]))
    return np.flatnonzero(far) + 1


def _radius_note(res, radius_range: tuple[float, float]) -> str | None:
    """A word when the prior on a hinge's radius, not the data, is what rules the circle out or
    weighs against it: the circle fits at least twice as closely as the line but its radius lies
    above ``radius_range`` or at or below its low end, whatever the answer (a door written in
    millimetres against the default 5 cm - 1 m was prismatic with 1.0; one in kilometres was
    revolute with 0.57, and said nothing)."""
    fit = res.fits.get("revolute")
    radius = getattr(fit, "radius", None)
    lo, hi = radius_range
    if radius is None or lo < radius <= hi:
        return None
    if not res.noise.get("revolute", math.inf) * 2.0 <= res.noise.get("prismatic", 0.0):
        return None
    return (f"the track bends on a circle of radius {radius:.4g} (noise {res.noise['revolute']:.3g}, the line's "
            f"{res.noise['prismatic']:.3g}), {'above' if radius > hi else 'at or below'} the prior range of a "
            f"hinge's radius [{lo:g}, {hi:g}]: give --radius-range in the data's units")


def fit_poses(positions, quats, *, noise: float | None = None, min_samples: int = 7, horizon: int = 5,
              noise_floor: float = 0.0) -> dict:
    """Rigid-body classification (4.3.2) of a 6-D pose track, re-run on growing prefixes to tell when
    the answer settled (``decided_at``: first sample from which every later prefix agrees).
    ``noise``: the positional noise std (data units); ``None``: estimated from the whole track with
    the angular noise (:func:`~artmotion.articulation.rigid.pose_noise`), at least ``noise_floor``.
    ``min_samples``: a whole number >= 2 (a shorter track is undecided); ``horizon``: predicted samples.
    The classification is geometric: it takes no time stamps (``decided_at`` counts samples)."""
    from artmotion.articulation.rigid import _check_noise_size, check_poses, classify_poses, pose_noise

    min_samples = check_range("min_samples", min_samples, 2, 10**9, integer=True)
    horizon = check_range("horizon", horizon, 0, 10**6, integer=True)
    check_range("noise_floor", noise_floor, 0.0, MAX_SCALE)
    if noise is not None:
        _check_noise_size(noise)
    P, Q = check_poses(positions, quats, min_poses=0)
    n = len(P)
    angular = None
    if noise is None and n >= 2:
        noise, angular = pose_noise(P, Q)
        noise = max(noise, noise_floor)
    base = {"input": "pose", "samples": n, "noise": noise, "angular_noise": angular, "probabilities": None,
            "first_decision": None}
    if n < max(min_samples, 2):
        return {**base, "model": "undecided", "decided_at": None, "configuration": {}, "motion": [], "prediction": []}
    final = classify_poses(P, Q, noise=noise, angular_noise=angular)
    step = max(1, n // 200)
    ks = list(range(min_samples, n, step)) + [n]
    labels = [classify_poses(P[:k], Q[:k], noise=noise, angular_noise=angular).model for k in ks]
    decided_at = None
    for j in range(len(ks) - 1, -1, -1):
        if labels[j] != final.model:
            break
        decided_at = ks[j] - 1
    motion = np.asarray(final.motion, dtype=float).reshape(n, -1)
    # short prediction: constant velocity of the motion variables over the last samples, mapped back
    pred = []
    if final.model == "static":
        pred = [P[0].tolist()] * horizon
    elif n >= 2:
        span = max(1, min(4, n - 1))
        if final.model == "revolute":
            ax = np.asarray(final.configuration["axis"])
            c = np.asarray(final.configuration["point"])
            w = (motion[-1, 0] - motion[max(0, n - 5), 0]) / span
            pred = [(axis_angle_to_matrix(ax, w * (h + 1)) @ (P[-1] - c) + c).tolist() for h in range(horizon)]
        else:
            v = (P[-1] - P[max(0, n - 5)]) / span
            pred = [(P[-1] + v * (h + 1)).tolist() for h in range(horizon)]
    return {**base, "model": final.model, "decided_at": decided_at,
            "first_decision": {"model": labels[0], "at": ks[0] - 1},  # the shortest prefix's answer
            "configuration": final.configuration, "residuals": final.residuals,
            "motion": motion.tolist(), "prediction": pred}


def fit_trajectory(path, time: bool | None = None, threshold: float = 0.75, min_samples: int = 7, **kwargs) -> dict:
    """Read ``path`` and fit it (points: Algorithm 1; poses: rigid-body classification).

    ``threshold``, ``min_samples`` and ``kwargs`` are the options of
    :class:`~artmotion.articulation.online.OnlineEstimator`, checked as it checks them whatever the
    file holds (an unknown keyword is a TypeError, a value out of range an InputError). A pose track
    uses ``min_samples``, ``noise`` and ``noise_floor``; the others apply to point tracks alone and
    are ignored for it (as ``artmotion articulation fit`` says)."""
    known = set(inspect.signature(OnlineEstimator).parameters) - {"threshold", "min_samples"}
    unknown = sorted(set(kwargs) - known)
    if unknown:
        raise TypeError(f"fit_trajectory() got an unexpected keyword argument {unknown[0]!r} "
                        f"(options: threshold, min_samples, {', '.join(sorted(known))})")
    OnlineEstimator(threshold=threshold, min_samples=min_samples, **kwargs)  # checks the options
    traj = read_trajectory(path, time=time)
    if traj.quats is not None:
        out = fit_poses(traj.points, traj.quats, noise=kwargs.get("noise"), min_samples=min_samples,
                        noise_floor=kwargs.get("noise_floor") or 0.0)
    else:
        out = fit_points(traj.points, traj.time, threshold=threshold, min_samples=min_samples, **kwargs)
    # (a name's bytes that are not UTF-8 written as \udce9: JSON of a lone surrogate is refused by
    # strict readers, or the name lost)
    out["file"] = str(path).encode("utf-8", "backslashreplace").decode("utf-8")
    spikes = _spikes(traj.points)
    if spikes.size:     # (one sample 1 km off turned a door prismatic with 1.000 and no word said)
        lines = ", ".join(str(int(traj.lines[i])) for i in spikes[:5]) + (", ..." if spikes.size > 5 else "")
        said = (f"line{'s' if spikes.size > 1 else ''} {lines}: a sample far from both its neighbours, which agree "
                f"(over {SPIKE:g} times the track's median step): a corrupt line? The answer may follow it")
        out["note"] = f"{out['note']}; {said}" if out.get("note") else said
    out["time_column"] = traj.time is not None
    out["units"] = {"length": traj.length_unit, "time": traj.time_unit}   # as the header gave them (converted)
    return out
