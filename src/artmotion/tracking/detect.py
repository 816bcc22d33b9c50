"""Detections from a file: read a MOTChallenge ``det.txt`` (the built-in detectors: :mod:`.detectors`)."""

from __future__ import annotations

import os

import numpy as np

from artmotion.io import read_mot

__all__ = ["load_detections", "normalise_scores"]


def normalise_scores(scores: np.ndarray) -> np.ndarray:
    """Scores as confidences in [0, 1], read from the input's own range.

    Scores already in [0, 1] (a detector's probabilities) are kept. Others (DPM's or ACF's
    margins, whose scale depends on the detector) are replaced by their mid-rank among all the
    file's scores, ``(#below + #below-or-equal) / 2n``: the tracker's thresholds then select the
    same share of each detector's most confident detections, whatever its scale.
    """
    s = np.asarray(scores, dtype=float)
    if not len(s) or (s.min() >= 0.0 and s.max() <= 1.0):
        return s
    srt = np.sort(s)
    return (np.searchsorted(srt, s, "left") + np.searchsorted(srt, s, "right")) / (2.0 * len(s))


def load_detections(path: str | os.PathLike) -> dict[int, np.ndarray]:
    """``{frame: (N, 5) array x, y, w, h, score}`` from a MOTChallenge file (InputError if bad)."""
    rows = read_mot(path)
    if not len(rows):
        return {}
    rows = rows.copy()
    rows[:, 6] = normalise_scores(rows[:, 6])
    rows = rows[np.argsort(rows[:, 0], kind="stable")]        # grouped by frame, in file order within one
    frames = rows[:, 0].astype(int)
    cuts = np.flatnonzero(np.diff(frames)) + 1
    return {int(r[0, 0]): np.column_stack([r[:, 2:6], r[:, 6]]) for r in np.split(rows, cuts)}
