"""Appearance model of Sec. 2.5.2/2.5.4: RGB histograms (16 bins per channel) compared by KL divergence."""

from __future__ import annotations

import math

import numpy as np

BINS = 16
_SHIFT = 4          # 256 / BINS = 2**4
_EPS = 1e-3

__all__ = ["BINS", "kl_divergence", "kl_matrix", "rgb_histogram"]


def rgb_histogram(image: np.ndarray, box, scale: float = 1.0, shrink: float = 0.1, parts: int = 1) -> np.ndarray | None:
    """Per-channel 16-bin histograms (``(3 * parts, 16)``, each row sums to 1) of the box's pixels
    in an 8-bit image (BGR, or grey).

    ``box`` is in full-image pixels and ``image`` may be a copy downscaled by ``scale``; the box
    is shrunk by ``shrink`` on each side to leave out most of the background. ``parts`` > 1 splits
    the box into that many horizontal bands (e.g. 2: upper body and legs, whose colours differ),
    each with its own histograms. ``None`` when the box is (almost) outside the image.
    """
    if image.dtype != np.uint8:
        raise ValueError(f"rgb_histogram needs an 8-bit image, got {image.dtype}")
    x, y, w, h = (v * scale for v in np.asarray(box, dtype=float).reshape(4).tolist())
    x0 = max(0, math.floor(x + shrink * w))
    y0 = max(0, math.floor(y + shrink * h))
    x1 = min(image.shape[1], math.ceil(x + (1 - shrink) * w))
    y1 = min(image.shape[0], math.ceil(y + (1 - shrink) * h))
    if x1 - x0 < 2 or y1 - y0 < 2 * parts:
        return None
    step = 2 if (x1 - x0) * (y1 - y0) > 400 else 1      # subsample large boxes
    channels = image.shape[2] if image.ndim == 3 else 1
    edges = [y0, y1] if parts == 1 else np.linspace(y0, y1, parts + 1).round().astype(int).tolist()
    offsets = np.arange(channels, dtype=np.intp) * BINS
    hists = []
    for a, b in zip(edges[:-1], edges[1:]):
        # the bin of an 8-bit value is its top four bits; one count over the channels' bins
        q = (image[a:b:step, x0:x1:step].reshape(-1, channels) >> _SHIFT) + offsets
        hists.append(np.bincount(q.ravel(), minlength=channels * BINS).reshape(channels, BINS))
    hist = (hists[0] if parts == 1 else np.concatenate(hists)).astype(float)
    hist += _EPS * hist.sum(axis=1, keepdims=True) + 1e-9
    return hist / hist.sum(axis=1, keepdims=True)


def kl_divergence(p: np.ndarray | None, q: np.ndarray | None) -> float:
    """``KL(p || q)`` summed over the channels (``inf`` if either is ``None``)."""
    if p is None or q is None:
        return float("inf")
    return float(np.sum(p * np.log(p / q)))


def kl_matrix(ps: list, qs: list, cap: float = np.inf, where: np.ndarray | None = None) -> np.ndarray:
    """``(len(ps), len(qs))`` matrix of ``min(KL(p || q), cap)`` (``cap`` where either is ``None``,
    and where the boolean matrix ``where`` is False: pairs the caller will not look at)."""
    out = np.full((len(ps), len(qs)), float(cap))
    mask = np.array([p is not None for p in ps])[:, None] & np.array([q is not None for q in qs])[None, :]
    i, j = np.nonzero(mask if where is None else mask & where)
    if len(i):      # pair by pair: the cost of a crowd's frame grows with its pairs, not tracks x detections
        one = np.ones(ps[int(i[0])].size)
        P = np.stack([one if p is None else p.ravel() for p in ps])
        Q = np.stack([one if q is None else q.ravel() for q in qs])
        # the same sum as kl_divergence, term by term (not via a matrix product: equal costs stay equal)
        for a in range(0, len(i), 4096):              # bounded memory
            Pa, Qa = P[i[a:a + 4096]], Q[j[a:a + 4096]]
            out[i[a:a + 4096], j[a:a + 4096]] = np.minimum(np.sum(Pa * np.log(Pa / Qa), axis=1), cap)
    return out
