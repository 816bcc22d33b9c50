"""Appearance model of Sec. 2.5.2/2.5.4: RGB histograms (16 bins per channel) compared by KL divergence."""

from __future__ import annotations

import numpy as np

BINS = 16
_EPS = 1e-3

__all__ = ["BINS", "kl_divergence", "rgb_histogram"]


def rgb_histogram(image: np.ndarray, box, scale: float = 1.0, shrink: float = 0.1, parts: int = 1) -> np.ndarray | None:
    """Per-channel 16-bin histograms (``(3 * parts, 16)``, each row sums to 1) of the box's pixels.

    ``box`` is in full-image pixels and ``image`` may be a copy downscaled by ``scale``; the box
    is shrunk by ``shrink`` on each side to leave out most of the background. ``parts`` > 1 splits
    the box into that many horizontal bands (e.g. 2: upper body and legs, whose colours differ),
    each with its own histograms. ``None`` when the box is (almost) outside the image.
    """
    x, y, w, h = np.asarray(box, dtype=float) * scale
    x0 = int(max(0, np.floor(x + shrink * w)))
    y0 = int(max(0, np.floor(y + shrink * h)))
    x1 = int(min(image.shape[1], np.ceil(x + (1 - shrink) * w)))
    y1 = int(min(image.shape[0], np.ceil(y + (1 - shrink) * h)))
    if x1 - x0 < 2 or y1 - y0 < 2 * parts:
        return None
    step = 2 if (x1 - x0) * (y1 - y0) > 400 else 1      # subsample large boxes
    channels = image.shape[2] if image.ndim == 3 else 1
    edges = np.linspace(y0, y1, parts + 1).round().astype(int)
    hists = []
    for a, b in zip(edges[:-1], edges[1:]):
        patch = image[a:b:step, x0:x1:step].reshape(-1, channels)
        q = (patch.astype(np.int32) * BINS) >> 8
        hists += [np.bincount(q[:, c], minlength=BINS) for c in range(channels)]
    hist = np.stack(hists).astype(float)
    hist += _EPS * hist.sum(axis=1, keepdims=True) + 1e-9
    return hist / hist.sum(axis=1, keepdims=True)


def kl_divergence(p: np.ndarray | None, q: np.ndarray | None) -> float:
    """``KL(p || q)`` summed over the channels (``inf`` if either is ``None``)."""
    if p is None or q is None:
        return float("inf")
    return float(np.sum(p * np.log(p / q)))
