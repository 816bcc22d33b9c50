"""Detections: read a MOTChallenge ``det.txt`` or run OpenCV's HOG people detector."""

from __future__ import annotations

import os

import cv2
import numpy as np

from artmotion.geometry import iou
from artmotion.io import read_mot

__all__ = ["HOGPeopleDetector", "load_detections", "normalise_scores"]


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
    out: dict[int, np.ndarray] = {}
    frames = rows[:, 0].astype(int)
    for f in np.unique(frames):
        r = rows[frames == f]
        out[int(f)] = np.column_stack([r[:, 2:6], r[:, 6]])
    return out


def nms(boxes: np.ndarray, scores: np.ndarray, threshold: float) -> np.ndarray:
    """Greedy non-maximum suppression at IoU ``threshold``; indices of the kept boxes."""
    order = np.argsort(-scores)
    keep = []
    while len(order):
        i = order[0]
        keep.append(i)
        if len(order) == 1:
            break
        rest = order[1:]
        order = rest[iou(boxes[i][None, :], boxes[rest]) <= threshold]
    return np.array(keep, dtype=int)


class HOGPeopleDetector:
    """Dalal-Triggs HOG + linear SVM (``cv2.HOGDescriptor_getDefaultPeopleDetector``).

    The detector's window is 64x128 pixels, so small images are upscaled until people of about a
    fifth of the image height fill it (``min_height`` pixels for the image). Scores are SVM
    margins mapped to [0, 1] by a logistic; boxes are shrunk from the padded window to the body.
    """

    def __init__(self, min_height: int = 720, hit_threshold: float = 0.0):
        self.hog = cv2.HOGDescriptor()
        self.hog.setSVMDetector(cv2.HOGDescriptor_getDefaultPeopleDetector())
        self.min_height = min_height
        self.hit_threshold = hit_threshold

    def __call__(self, image: np.ndarray) -> np.ndarray:
        h = image.shape[0]
        scale = max(1.0, self.min_height / float(h))
        img = image if scale == 1.0 else cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_LINEAR)
        rects, weights = self.hog.detectMultiScale(img, hitThreshold=self.hit_threshold, winStride=(8, 8),
                                                   padding=(8, 8), scale=1.05)
        if len(rects) == 0:
            return np.zeros((0, 5))
        rects = np.asarray(rects, dtype=float).reshape(-1, 4) / scale
        w = np.asarray(weights, dtype=float).reshape(-1)
        # non-maximum suppression (the HOG boxes of one person overlap heavily)
        idx = nms(rects, w, 0.4)
        rects, w = rects[idx], w[idx]
        # the 64x128 window has 16 px of margin around an upright person: tighten the box
        rects[:, 0] += rects[:, 2] * 0.125
        rects[:, 2] *= 0.75
        rects[:, 1] += rects[:, 3] * 0.05
        rects[:, 3] *= 0.9
        conf = 1.0 / (1.0 + np.exp(-2.0 * w))
        return np.column_stack([rects, conf])
