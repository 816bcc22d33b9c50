"""Axis-aligned boxes. The convention is MOTChallenge's ``[x, y, w, h]`` (top-left, size, pixels).

Every function accepts a single box of shape ``(4,)`` or a stack ``(..., 4)``.
"""

from __future__ import annotations

import math

import numpy as np

from artmotion.errors import InputError


def _boxes(b, name: str) -> np.ndarray:
    """``b`` as a float array of boxes, ``(4,)`` or ``(..., 4)``, else an :class:`InputError` (a
    MOTChallenge row of 10 columns would be read as the box ``frame, id, x, y``). The shape only:
    these run per box in the tracker's loop (:func:`iou_matrix` checks values as well)."""
    try:
        b = np.asarray(b, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name}: boxes must be numbers x, y, w, h") from None
    if b.shape[-1:] != (4,):
        if b.shape == (0,):     # (no boxes at all; rows of no columns are no boxes either: refused)
            return b.reshape(0, 4)
        raise InputError(f"{name}: boxes must have shape (4,) or (..., 4): x, y, w, h, got shape {b.shape}")
    return b


def xywh_to_xyxy(b) -> np.ndarray:
    b = _boxes(b, "xywh_to_xyxy")
    return np.concatenate([b[..., :2], b[..., :2] + b[..., 2:4]], axis=-1)


def xyxy_to_xywh(b) -> np.ndarray:
    b = _boxes(b, "xyxy_to_xywh")
    return np.concatenate([b[..., :2], b[..., 2:4] - b[..., :2]], axis=-1)


def box_center(b) -> np.ndarray:
    b = _boxes(b, "box_center")
    return b[..., :2] + 0.5 * b[..., 2:4]


def box_from_center(center, size) -> np.ndarray:
    c = np.asarray(center, dtype=float)
    s = np.asarray(size, dtype=float)
    if c.shape[-1:] != (2,) or s.shape[-1:] != (2,):
        raise InputError(f"box_from_center: centres and sizes must have shape (2,) or (..., 2), got {c.shape} "
                         f"and {s.shape}")
    return np.concatenate([c - 0.5 * s, s], axis=-1)


def box_area(b) -> np.ndarray:
    """Area of boxes ``x, y, w, h`` from their corners, ``((x + w) - x) ((y + h) - y)``: the
    arithmetic of :func:`intersection`, so that a box's IoU with itself is exactly 1 (from ``w h``,
    822 of PETS09-S2L1's 1700 ground-truth boxes gave 1 - 6e-15, and ``eval --iou 1`` scored a
    result identical to the ground truth MOTA 3.3); TrackEval computes it so."""
    b = _boxes(b, "box_area")
    return (np.maximum((b[..., 0] + b[..., 2]) - b[..., 0], 0.0)
            * np.maximum((b[..., 1] + b[..., 3]) - b[..., 1], 0.0))


def intersection(a, b) -> np.ndarray:
    """Area of the intersection of boxes ``a`` and ``b`` (broadcasting)."""
    a = _boxes(a, "intersection")
    b = _boxes(b, "intersection")
    ax, ay, bx, by = a[..., 0], a[..., 1], b[..., 0], b[..., 1]
    w = np.minimum(ax + a[..., 2], bx + b[..., 2]) - np.maximum(ax, bx)
    h = np.minimum(ay + a[..., 3], by + b[..., 3]) - np.maximum(ay, by)
    return np.maximum(w, 0.0) * np.maximum(h, 0.0)


def _not_finite(name: str) -> InputError:
    return InputError(f"{name}: boxes must be finite numbers, got NaN or infinite values")


def iou(a, b) -> np.ndarray:
    """Intersection over union (broadcasting); 0 where the union is empty (a box of negative width
    or height is empty). A box with NaN, an infinite corner or an infinite positive size is an
    :class:`~artmotion.errors.InputError` (its union is not finite), not an IoU of 0."""
    inter = intersection(a, b)
    union = box_area(a) + box_area(b) - inter
    if not np.isfinite(union).all():
        raise _not_finite("iou")
    return np.divide(inter, union, out=np.zeros_like(inter, dtype=float), where=union > 0)


def _stack(boxes, name: str) -> np.ndarray:
    """``boxes`` (one box ``(4,)`` or a stack ``(..., 4)``; nothing at all is no box) as an
    ``(N, 4)`` float array; else an :class:`~artmotion.errors.InputError` giving the shape (a
    ``(N, 5)`` or ``(N, 10)`` array of rows must not be read as other boxes)."""
    b = np.asarray(boxes, dtype=float)
    if b.shape[-1:] != (4,):
        if b.size:
            raise InputError(f"{name} must be boxes x, y, w, h (shape (4,) or (N, 4)), got shape {b.shape}")
        return b.reshape(0, 4)
    return b.reshape(-1, 4)


def iou_matrix(a, b) -> np.ndarray:
    """``(len(a), len(b))`` IoU matrix of two box stacks."""
    a = _stack(a, "iou_matrix: a")
    b = _stack(b, "iou_matrix: b")
    return iou(a[:, None, :], b[None, :, :])


def overlap_ratio(a, b) -> np.ndarray:
    """Fraction of box ``a`` covered by box ``b``: ``|a ∩ b| / |a|``."""
    inter = intersection(a, b)
    area = box_area(a)
    if not np.isfinite(area + inter + box_area(b)).all():
        raise _not_finite("overlap_ratio")
    return np.divide(inter, area, out=np.zeros_like(inter, dtype=float), where=area > 0)


def _overlap_terms(a: list, b: list) -> tuple[float, float, float]:
    """Intersection and areas of two boxes given as lists of floats: the arithmetic of
    :func:`intersection` and :func:`box_area` on Python floats (the same numbers, without NumPy's
    fixed cost per call, which dominates on one box)."""
    ax, ay, aw, ah = a
    bx, by, bw, bh = b
    w = min(ax + aw, bx + bw) - max(ax, bx)
    h = min(ay + ah, by + bh) - max(ay, by)
    inter = max(w, 0.0) * max(h, 0.0)
    return (inter, max((ax + aw) - ax, 0.0) * max((ay + ah) - ay, 0.0),
            max((bx + bw) - bx, 0.0) * max((by + bh) - by, 0.0))


def max_iou(box, boxes) -> float:
    """Largest IoU of one ``box`` with any of ``boxes`` (``(N, 4)``; 0 when there are none):
    ``iou_matrix(box, boxes).max()``, on Python floats for the few boxes of one frame (the same
    arithmetic, so the same numbers) and with NumPy for many."""
    boxes = _stack(boxes, "max_iou: boxes")
    one = np.asarray(box, dtype=float)
    if one.shape[-1:] != (4,) or one.size != 4:
        raise InputError(f"max_iou: box must be one box x, y, w, h, got shape {one.shape}")
    if len(boxes) > 16:
        return float(iou(one.reshape(4), boxes).max())
    a = one.reshape(4).tolist()
    best = 0.0
    for b in boxes.tolist():
        inter, area_a, area_b = _overlap_terms(a, b)
        union = area_a + area_b - inter
        if not math.isfinite(union):  # a box with NaN or an infinity (as iou)
            raise _not_finite("max_iou")
        best = max(best, inter / union if union > 0 else 0.0)
    return best


def box_overlap(a, b) -> float:
    """:func:`overlap_ratio` of two single boxes, as a float."""
    inter, area, area_b = _overlap_terms(_boxes(a, "box_overlap").reshape(4).tolist(),
                                         _boxes(b, "box_overlap").reshape(4).tolist())
    if not math.isfinite(area + area_b - inter):  # a box with NaN or an infinity (as iou)
        raise _not_finite("box_overlap")
    return inter / area if area > 0 else 0.0


def union_box(boxes) -> np.ndarray:
    """Smallest box spanning all ``boxes`` (a group node's extent, Eq. 2.12-2.13)."""
    b = _stack(boxes, "union_box: boxes")
    if not len(b):
        raise InputError("union_box needs at least one box, got none")
    xyxy = xywh_to_xyxy(b)
    return xyxy_to_xywh(np.concatenate([xyxy[:, :2].min(0), xyxy[:, 2:].max(0)]))


def _size(fn: str, name: str, v, zero: bool = False, no_limit: bool = False) -> float:
    """A size given to ``fn`` as a float: a real number (a NumPy scalar or 0-d array too, not a
    bool) above 0 (or at least 0 with ``zero``), finite (or infinite with ``no_limit``: no bound)."""
    try:
        if isinstance(v, (bool, np.bool_)) or np.ndim(v) != 0:
            raise TypeError
        f = float(v)
    except (TypeError, ValueError):
        f = math.nan
    if not ((f >= 0.0 if zero else f > 0.0) and (no_limit or f < math.inf)):
        raise InputError(f"{fn}: {name} must be a number {'>= 0' if zero else '> 0'}"
                         f"{'' if no_limit else ' and finite'}, got {v!r}")
    return f


def fit_size(width: int, height: int, max_width: float, max_height: float) -> tuple[float, tuple[int, int]]:
    """The scale (at most 1) that fits an image of ``width`` x ``height`` within ``max_width`` x
    ``max_height``, and the scaled size, at least 1 pixel a side."""
    w, h = _size("fit_size", "width", width), _size("fit_size", "height", height)
    scale = min(1.0, _size("fit_size", "max_width", max_width, no_limit=True) / w,
                _size("fit_size", "max_height", max_height, no_limit=True) / h)
    return scale, (max(1, round(w * scale)), max(1, round(h * scale)))


def clip_box(b, width: float, height: float) -> np.ndarray:
    """Clip boxes to the image ``[0, width] x [0, height]``."""
    width = _size("clip_box", "width", width, zero=True, no_limit=True)
    height = _size("clip_box", "height", height, zero=True, no_limit=True)
    xyxy = xywh_to_xyxy(b)
    xyxy[..., [0, 2]] = np.clip(xyxy[..., [0, 2]], 0, width)
    xyxy[..., [1, 3]] = np.clip(xyxy[..., [1, 3]], 0, height)
    return xyxy_to_xywh(xyxy)
