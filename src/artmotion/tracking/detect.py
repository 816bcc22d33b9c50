"""Detections from a file: read a MOTChallenge ``det.txt`` (the built-in detectors: :mod:`.detectors`)."""

from __future__ import annotations

import os

import numpy as np

from artmotion.io import read_mot

__all__ = ["load_detections", "normalise_scores", "read_detections", "scores_are_probabilities"]

#: how far outside [0, 1] a probability may be printed (rounding, a fused score's overshoot)
ROUNDING = 1e-3


def scores_are_probabilities(scores: np.ndarray) -> bool:
    """Whether ``scores`` read as probabilities: all in [0, 1] up to :data:`ROUNDING`."""
    s = np.asarray(scores, dtype=float)
    return not len(s) or bool(s.min() >= -ROUNDING and s.max() <= 1.0 + ROUNDING)


def normalise_scores(scores: np.ndarray) -> np.ndarray:
    """Scores as confidences in [0, 1], read from the input's own range.

    Scores in [0, 1] (a detector's probabilities; a rounding's overshoot of at most
    :data:`ROUNDING` clipped) are kept. Others (DPM's or ACF's margins, percentages: a scale the
    detector chose) are replaced by their mid-rank among all the file's scores,
    ``(#below + #below-or-equal) / 2n``: the tracker's thresholds then select the same share of
    each detector's most confident detections, whatever its scale.
    """
    s = np.asarray(scores, dtype=float)
    if scores_are_probabilities(s):
        return np.clip(s, 0.0, 1.0)
    srt = np.sort(s)
    return (np.searchsorted(srt, s, "left") + np.searchsorted(srt, s, "right")) / (2.0 * len(s))


def load_detections(path: str | os.PathLike) -> dict[int, np.ndarray]:
    """``{frame: (N, 5) array x, y, w, h, score}`` from a MOTChallenge file (InputError if bad)."""
    return read_detections(path)[0]


def read_detections(path: str | os.PathLike) -> tuple[dict[int, np.ndarray], bool]:
    """:func:`load_detections` and whether the file's scores were read as probabilities (else
    replaced by their mid-ranks: :func:`normalise_scores`)."""
    rows = read_mot(path)
    if not len(rows):
        return {}, True
    rows = rows.copy()
    probabilities = scores_are_probabilities(rows[:, 6])
    rows[:, 6] = normalise_scores(rows[:, 6])
    rows = rows[np.argsort(rows[:, 0], kind="stable")]        # grouped by frame, in file order within one
    frames = rows[:, 0].astype(int)
    cuts = np.flatnonzero(np.diff(frames)) + 1
    return {int(r[0, 0]): np.column_stack([r[:, 2:6], r[:, 6]]) for r in np.split(rows, cuts)}, probabilities
