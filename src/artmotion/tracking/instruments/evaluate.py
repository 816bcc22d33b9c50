"""Scores of instrument predictions against ``tools.csv`` annotations.

Only annotated frames are scored (:func:`annotated_frames`). A ``tools.csv`` names a frame only
when it has an instrument (its rows); the frames it covers are those from its first to its last in
the step of the frames it names (every frame, or every 5th): a frame on that grid without a row
shows no instrument, and its predictions are false ones; a frame off the grid or outside the range
is one nobody annotated, and the predictions on it cannot be judged: they are left out of the score
and counted (``unscored_frames``, ``unscored_pred``), so that perfect predictions on every frame
against annotations of every 5th score a precision of 1, not 0.2. On each scored frame, predicted
heads are matched one-to-one to the true heads with the Hungarian algorithm on the Euclidean
distance between heads, pairs farther apart than ``radius`` px being no match. Among the matchings
the most pairs within the radius is taken; among those, the one that continues the most matches of
earlier frames (a true instrument kept on the track it was last matched to, as CLEAR MOT does);
among those, the one of least total distance. Recall is matched / true heads, precision matched /
predicted heads, and the shaft angle error of a matched pair the absolute difference of the two
angles, wrapped, in degrees in ``[0, 180]``.

The annotations' ``tool`` index is no identity (the order of the instruments changes), so the true
heads are first linked from each annotated frame to the next one into identities (Hungarian on
distance, pairs farther apart than ``link`` px not linked; an unlinked head starts a new identity).
An identity switch is counted, as in MOTChallenge, each time a true identity is matched to another
track than the one it was last matched to.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import linear_sum_assignment

from artmotion.errors import InputError, check_range
from artmotion.io.mot import MAX_BOXES_PER_FRAME, MAX_COORD

__all__ = ["evaluate_tools", "format_report"]


def _arrays(frames: dict[int, np.ndarray], width: int, what: str) -> dict[int, np.ndarray]:
    """``frames`` as float arrays ``(k, width)`` with finite values."""
    out = {}
    for frame, value in frames.items():
        arr = np.asarray(value, dtype=float)
        if arr.size == 0:
            arr = arr.reshape(0, width)
        if arr.ndim != 2 or arr.shape[1] != width:
            raise InputError(f"{what} of frame {frame} must be a (k, {width}) array, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise InputError(f"{what} of frame {frame}: NaN or infinite value")
        if len(arr) > MAX_BOXES_PER_FRAME:
            raise InputError(f"{what} of frame {frame}: {len(arr)} rows, more than artmotion scores in one frame "
                             f"({MAX_BOXES_PER_FRAME})")
        out[int(frame)] = arr
    return out


def _distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Euclidean distances between the points ``a`` (k, 2) and ``b`` (m, 2): (k, m)."""
    return np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(axis=2))


def _match(dist: np.ndarray, gate: float, keep: np.ndarray | None = None) -> list[tuple[int, int]]:
    """One-to-one pairs ``(row, column)`` with ``dist <= gate``: the most pairs; among those the most
    ``keep`` pairs (continued matches); among those the least total distance."""
    k, m = dist.shape
    valid = dist <= gate
    if not valid.any():
        return []
    n = min(k, m) + 1
    # closeness in [0, 1] sums to < n over the <= n - 1 pairs, so one kept pair (weight n) outweighs
    # any closeness, and one more pair (weight n**2) any number of kept ones
    score = n * n + (1.0 - dist / gate)
    if keep is not None:
        score = score + n * keep
    score = np.where(valid, score, 0.0)
    rows, cols = linear_sum_assignment(score, maximize=True)
    return [(int(r), int(c)) for r, c in zip(rows, cols) if valid[r, c]]


def _gt_identities(gt: dict[int, np.ndarray], link: float) -> dict[int, np.ndarray]:
    """An identity for every true head: heads linked from each annotated frame to the next."""
    ids: dict[int, np.ndarray] = {}
    prev_xy = np.zeros((0, 2))
    prev_ids = np.zeros(0, dtype=int)
    next_id = 0
    for frame in sorted(gt):
        xy = gt[frame][:, :2]
        cur = np.full(len(xy), -1, dtype=int)
        if len(prev_xy) and len(xy):
            for r, c in _match(_distances(prev_xy, xy), link):
                cur[c] = prev_ids[r]
        for i in np.flatnonzero(cur < 0):
            cur[i] = next_id
            next_id += 1
        ids[frame] = cur
        prev_xy, prev_ids = xy, cur
    return ids


def _check_common_frames(gt: dict[int, np.ndarray], pred: dict[int, np.ndarray]) -> None:
    """An :class:`InputError` when both sides have heads but on no frame in common: the frame
    numbers do not match (a video numbered from 1 against annotations of its frames' file names),
    and a recall of 0 would blame the predictor."""
    annotated = sorted(f for f, a in gt.items() if len(a))
    predicted = sorted(f for f, a in pred.items() if len(a))
    if annotated and predicted and not set(annotated) & set(predicted):
        raise InputError(f"no predicted frame is an annotated one (annotated frames {annotated[0]}-{annotated[-1]}, "
                         f"predicted {predicted[0]}-{predicted[-1]}): do the frame numbers match?")


def _angle_error_deg(a: float, b: float) -> float:
    d = abs(a - b) % math.tau
    return math.degrees(min(d, math.tau - d))


def annotated_frames(gt: dict[int, np.ndarray]) -> list[int]:
    """The frames an annotation covers: from its first frame to its last in the step every frame
    it names lies on (the greatest common divisor of their gaps: 1 for annotations of every frame,
    5 for every 5th). A frame on that grid without a row is annotated as showing no instrument (its
    predictions are false ones); a frame off it, or outside the range, nobody annotated."""
    named = sorted(gt)
    if not named:
        return []
    step = int(np.gcd.reduce(np.diff(named))) if len(named) > 1 else 1
    return list(range(named[0], named[-1] + 1, max(step, 1)))


def grid_note(gt: dict[int, np.ndarray]) -> str:
    """What to tell a user whose annotations' frames mostly lie further apart than the grid
    :func:`annotated_frames` reads from them (a stray row off a grid of every 5th frame makes every
    frame count as annotated, the rowless ones as showing no instrument): the frames off the
    commonest gap's grid; ``""`` when the grid is the commonest gap's."""
    named = sorted(gt)
    if len(named) < 3:
        return ""
    gaps = np.diff(named)
    values, counts = np.unique(gaps, return_counts=True)
    usual = int(values[np.argmax(counts)])
    grid = annotated_frames(gt)
    if 2 * counts.max() <= len(gaps) or len(grid) < 2 or grid[1] - grid[0] >= usual:
        return ""       # (no gap most frames share, or the grid is theirs)
    residues, many = np.unique(np.asarray(named) % usual, return_counts=True)
    off = [f for f in named if f % usual != residues[np.argmax(many)]]
    return (f"most annotated frames are {usual} apart, but frame{'s' if len(off) > 1 else ''} "
            f"{', '.join(map(str, off[:5]))}{', ...' if len(off) > 5 else ''} lie{'' if len(off) > 1 else 's'} off "
            f"that grid: every {grid[1] - grid[0]} frame(s) from {grid[0]} to {grid[-1]} count as annotated "
            f"({len(grid) - len(named)} without a row as showing no instrument)")


def evaluate_tools(gt: dict[int, np.ndarray], pred: dict[int, np.ndarray], radius: float = 15.0,
                   fps: float | None = None, link: float = 40.0) -> dict:
    """Score predicted instrument heads against annotations (see the module doc).

    ``gt``: frame -> ``(k, 4)`` ``x, y, scale, angle`` (:func:`read_tools_csv`); ``pred``: frame ->
    ``(k, 6)`` ``track, x, y, scale, angle, score`` (:func:`read_predictions`). ``radius``: the
    largest distance (px) of a matched head; ``link``: the largest distance (px) a true head moves
    from one annotated frame to the next and keeps its identity; ``fps``: the predictor's speed,
    only reported.

    Returns ``frames`` (scored: :func:`annotated_frames`), ``gt``, ``pred``, ``matched`` (counts on
    them), ``recall``, ``precision`` (None when there is no true, resp. predicted, head),
    ``median_angle_error_deg`` (None without matches), ``id_switches``, ``unscored_frames`` and
    ``unscored_pred`` (the predicted frames with heads that ``gt`` does not have, and their heads),
    and the ``radius``, ``link`` and ``fps`` used.
    """
    radius = float(check_range("radius", radius, 0, MAX_COORD, lo_open=True))
    link = float(check_range("link", link, 0, MAX_COORD, lo_open=True))
    if fps is not None:
        fps = float(check_range("fps", fps, 0, 1e9, lo_open=True))
    gt = _arrays(gt, 4, "annotations")
    pred = _arrays(pred, 6, "predictions")
    _check_common_frames(gt, pred)
    identities = _gt_identities(gt, link)
    empty_gt, empty_pred = np.zeros((0, 4)), np.zeros((0, 6))
    last_track: dict[int, int] = {}          # true identity -> track it was last matched to
    frames = annotated_frames(gt)
    scored = set(frames)
    unscored = [len(p) for f, p in pred.items() if f not in scored and len(p)]
    n_gt = n_pred = switches = 0
    errors: list[float] = []
    for frame in frames:
        g = gt.get(frame, empty_gt)
        p = pred.get(frame, empty_pred)
        n_gt += len(g)
        n_pred += len(p)
        if not len(g) or not len(p):
            continue
        ids = identities[frame]
        before = np.array([last_track.get(int(i), -1) for i in ids], dtype=float)
        keep = (before[:, None] == p[None, :, 0]).astype(float)      # tracks are >= 0, never -1
        for r, c in _match(_distances(g[:, :2], p[:, 1:3]), radius, keep):
            errors.append(_angle_error_deg(g[r, 3], p[c, 4]))
            identity, track = int(ids[r]), int(p[c, 0])
            if identity in last_track and last_track[identity] != track:
                switches += 1
            last_track[identity] = track
    matched = len(errors)
    return {
        "frames": len(frames),
        "gt": n_gt,
        "pred": n_pred,
        "matched": matched,
        "recall": matched / n_gt if n_gt else None,
        "precision": matched / n_pred if n_pred else None,
        "median_angle_error_deg": float(np.median(errors)) if errors else None,
        "id_switches": switches,
        "unscored_frames": len(unscored),
        "unscored_pred": sum(unscored),
        "radius": radius,
        "link": link,
        "fps": fps,
    }


def format_report(result: dict) -> str:
    """A few lines for people from an :func:`evaluate_tools` result."""

    def ratio(value: float | None, num: int, den: int) -> str:
        return f"{'n/a' if value is None else f'{value:.3f}'} ({num}/{den})"

    lines = [
        f"frames: {result['frames']}, true heads: {result['gt']}, predicted heads: {result['pred']}",
        f"heads within {result['radius']:g} px: recall {ratio(result['recall'], result['matched'], result['gt'])}, "
        f"precision {ratio(result['precision'], result['matched'], result['pred'])}",
    ]
    if result["median_angle_error_deg"] is None:
        lines.append("shaft angle: no matched heads")
    else:
        lines.append(f"shaft angle: median error {result['median_angle_error_deg']:.1f}° "
                     f"over {result['matched']} matched heads")
    lines.append(f"identity switches: {result['id_switches']}")
    if result.get("unscored_frames"):
        lines.append(f"not scored: {result['unscored_pred']} predicted heads on {result['unscored_frames']} frames "
                     "that are not annotated")
    if result.get("fps") is not None:
        lines.append(f"speed: {result['fps']:.1f} frames/s")
    return "\n".join(lines)
