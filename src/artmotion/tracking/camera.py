"""Camera-motion compensation: the global image motion between frames.

A moving camera moves every box in the image; a tracker that predicts boxes with a motion model
of the people alone then loses them (thesis Sec. 2.7.4 lists camera motion among the failure
modes). :class:`CameraMotion` estimates the global motion between consecutive frames as a 2×3
similarity (rotation, scale, translation): Shi–Tomasi corners of the background (outside the
tracked boxes) of the previous downscaled grey image are followed by pyramidal Lucas–Kanade into
the current one and a similarity is fitted with RANSAC (``cv2.estimateAffinePartial2D``) — the
camera-motion compensation of BoT-SORT, on the images the experts already use. The tracker
applies it to every track's state before predicting (:meth:`KalmanBank.warp`).

Whether the camera moves is decided from the data: while it is still, the motion is checked only
every ``check`` seconds, against the last checked frame (a still camera costs almost nothing);
once the accumulated motion moves image points by more than ``moving_px`` (relative to the image
diagonal) the estimator runs on every frame until the camera has been still for ``settle``
seconds.
"""

from __future__ import annotations

import bisect
from typing import Any

import cv2
import numpy as np

from artmotion.tracking.state import boxes_to_z, z_to_boxes

__all__ = ["CameraMotion", "CameraPath", "estimate_motion"]


_LK: dict[str, Any] = dict(winSize=(11, 11), maxLevel=3, criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 10, 0.03))


def _box_mask(shape, exclude) -> np.ndarray:
    h, w = shape[:2]
    mask = np.full((h, w), 255, np.uint8)
    if exclude is not None:
        for x, y, bw, bh in np.asarray(exclude, dtype=float).reshape(-1, 4):
            x0, y0 = max(0, int(x)), max(0, int(y))
            x1, y1 = min(w, int(np.ceil(x + bw))), min(h, int(np.ceil(y + bh)))
            if x1 > x0 and y1 > y0:
                mask[y0:y1, x0:x1] = 0
    return mask


def _outside_boxes(pts: np.ndarray, exclude) -> np.ndarray:
    """Which of ``pts`` (N, 1, 2) lie outside every box of ``exclude``."""
    keep = np.ones(len(pts), bool)
    if exclude is None or not len(pts):
        return keep
    p = pts.reshape(-1, 2)
    for x, y, bw, bh in np.asarray(exclude, dtype=float).reshape(-1, 4):
        keep &= ~((p[:, 0] >= x) & (p[:, 0] <= x + bw) & (p[:, 1] >= y) & (p[:, 1] <= y + bh))
    return keep


def estimate_motion(prev: np.ndarray, cur: np.ndarray, exclude=None, max_points: int = 200,
                    min_inliers: int = 12, points: np.ndarray | None = None, min_share: float = 0.5):
    """The similarity ``A`` (2×3) with ``cur ≈ A @ [prev; 1]`` for background points, or ``None``.

    ``prev`` and ``cur`` are grey uint8 images of the same size; ``exclude`` optional ``(N, 4)``
    boxes ``x, y, w, h`` (in these images' pixels) whose points are left out (the tracked people
    move on their own). ``points``: corners of ``prev`` to follow (e.g. the inliers of the
    previous call); new Shi–Tomasi corners are detected when fewer than half of ``max_points`` are
    given. Returns ``(A, inliers)``: ``A`` is ``None`` when too few points agree (a blank or
    blurred frame) or fewer than ``min_share`` of the followed points (the background is most of
    what is left outside the boxes: a motion only a minority follows is something else moving);
    ``inliers`` are the agreeing points in ``cur`` (``(K, 1, 2)`` float32), to be followed into
    the next frame.
    """
    none = (None, np.zeros((0, 1, 2), np.float32))
    p0 = None
    if points is not None and len(points):
        p0 = points[_outside_boxes(points, exclude)]
    if p0 is None or len(p0) < max_points // 2:
        h, w = prev.shape[:2]
        p0 = cv2.goodFeaturesToTrack(prev, max_points, 0.01, max(3.0, min(w, h) / 40.0),
                                     mask=_box_mask(prev.shape, exclude), blockSize=3)
    if p0 is None or len(p0) < min_inliers:
        return none
    # the stubs want nextPts, which OpenCV accepts as None (no initial guess)
    p1, st, _ = cv2.calcOpticalFlowPyrLK(prev, cur, p0, None, **_LK)  # type: ignore[call-overload]
    if p1 is None:
        return none
    ok = st.ravel() == 1
    if ok.sum() < min_inliers:
        return none
    A, inl = cv2.estimateAffinePartial2D(p0[ok], p1[ok], method=cv2.RANSAC, ransacReprojThreshold=1.0,
                                         maxIters=200, confidence=0.99)
    if A is None or inl is None or int(inl.sum()) < max(min_inliers, min_share * ok.sum()):
        return none
    return A.astype(float), p1[ok][inl.ravel() == 1]


def _displacement(A: np.ndarray, w: float, h: float) -> float:
    """Largest displacement of the image corners under ``A`` (pixels)."""
    corners = np.array([[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]])
    moved = corners @ A[:, :2].T + A[:, 2]
    return float(np.max(np.linalg.norm(moved - corners, axis=1)))


class CameraMotion:
    """Frame-to-frame camera motion, estimated only where the camera moves.

    ``fps`` sets the check interval; :meth:`step` takes the current downscaled grey image and its
    scale (small pixels per full pixel) and returns the 2×3 map of **full-image** pixels from the
    previous frame to this one, ``None`` while the camera is still. ``moving`` says whether the
    camera is currently judged to move; ``moved_frames`` counts the frames it moved.
    """

    def __init__(self, fps: float, check: float = 0.5, settle: float = 2.0, moving_px: float = 0.004):
        self.check = max(1, int(round(check * fps)))
        self.settle = max(1, int(round(settle * fps)))
        self.moving_px = moving_px
        self.moving = False
        self.moved_frames = 0
        self._ref: np.ndarray | None = None      # grey image of the last check (still camera)
        self._ref_boxes: np.ndarray | None = None  # the tracked boxes when it was taken
        self._ref_n = 0
        self._prev: np.ndarray | None = None     # previous grey image (moving camera)
        self._points: np.ndarray | None = None   # background corners of the previous image, followed on
        self._still = 0
        self._n = 0

    def _big(self, A: np.ndarray | None, grey: np.ndarray, frames: int = 1) -> bool:
        if A is None:
            return False
        h, w = grey.shape[:2]
        return _displacement(A, w, h) > self.moving_px * float(np.hypot(w, h)) * frames ** 0.5

    def step(self, grey, scale: float, exclude=None) -> np.ndarray | None:
        """Motion from the previous call's image to ``grey`` in full-image pixels.

        ``grey``: the image, or a function without arguments that returns it (called only on
        the frames the estimator looks at: a still camera's image is needed every ``check``
        seconds only). ``exclude``: boxes (full-image pixels) of the tracked objects, left out of
        the estimate.
        """
        self._n += 1
        if not self.moving and self._ref is not None and self._n - self._ref_n < self.check:
            return None         # a still camera between two checks: nothing to look at
        if callable(grey):
            grey = grey()
        ex = None if exclude is None else np.asarray(exclude, dtype=float).reshape(-1, 4) * scale
        A_small: np.ndarray | None = None
        if self.moving:
            if self._prev is not None:
                A_small, self._points = estimate_motion(self._prev, grey, ex, points=self._points)
            if self._big(A_small, grey):
                self._still = 0
            else:
                self._still += 1
                if self._still >= self.settle:
                    self.moving = False
                    self._ref, self._ref_n, self._ref_boxes = grey, self._n, ex
        elif self._ref is None:
            self._ref, self._ref_n, self._ref_boxes = grey, self._n, ex
        else:  # a still camera's check (between two checks it returned above)
            # corners are taken in the reference image: leave out where the people were then;
            # over several frames a walking camera's parallax leaves fewer points on one
            # similarity than from frame to frame (ETH-Sunnyday: 22-50 % against 65-84 %)
            A_ref, self._points = estimate_motion(self._ref, grey, self._ref_boxes, min_share=0.2)
            if self._big(A_ref, grey, self._n - self._ref_n):
                # the camera started moving since the last check: from now on, every frame; the
                # motion accumulated since the check is applied at once
                self.moving = True
                self._still = 0
                A_small = A_ref
            self._ref, self._ref_n, self._ref_boxes = grey, self._n, ex
        self._prev = grey
        if A_small is None:
            return None
        self.moved_frames += 1
        A = A_small.copy()
        A[:, 2] /= scale
        return A


class CameraPath:
    """The camera's motion over a whole sequence, for the offline pass: :meth:`add` records each
    frame's 2×3 similarity (previous frame -> this one, in frame order; frames without one did not
    move), and :meth:`to_ref` / :meth:`from_ref` map boxes between a frame's pixels and those of
    the first frame (the composed similarities), so that a trajectory through a gap is extrapolated
    and interpolated where the camera's own motion has been taken out (Sec. 2.5.3 on a moving
    camera).
    """

    def __init__(self) -> None:
        self._frames: list[int] = []            # frames with a step, increasing
        self._to_first: list[np.ndarray] = []   # 3×3 map of each one's pixels to the first frame's

    def add(self, frame: int, A: np.ndarray) -> None:
        if self._frames and frame <= self._frames[-1]:
            raise ValueError(f"camera steps must come in frame order ({frame} after {self._frames[-1]})")
        step = np.vstack([np.asarray(A, dtype=float), [0.0, 0.0, 1.0]])
        G = self._to_first[-1] if self._to_first else np.eye(3)
        self._frames.append(int(frame))
        self._to_first.append(G @ np.linalg.inv(step))

    def __bool__(self) -> bool:
        return bool(self._frames)

    def _to_ref(self, frame: int) -> np.ndarray:
        """3×3 map of ``frame``'s pixels to the first frame's: that of the last step up to it."""
        i = bisect.bisect_right(self._frames, frame) - 1
        return self._to_first[i] if i >= 0 else np.eye(3)

    @staticmethod
    def _map(G: np.ndarray, boxes) -> np.ndarray:
        z = boxes_to_z(boxes)
        z[:, :2] = z[:, :2] @ G[:2, :2].T + G[:2, 2]
        z[:, 2:4] *= float(np.sqrt(abs(np.linalg.det(G[:2, :2]))))
        return z_to_boxes(z)

    def to_ref(self, frame: int, boxes) -> np.ndarray:
        """``boxes`` (x, y, w, h) of ``frame`` in the first frame's pixels."""
        return self._map(self._to_ref(frame), boxes)

    def from_ref(self, frame: int, boxes) -> np.ndarray:
        """Inverse of :meth:`to_ref`."""
        return self._map(np.linalg.inv(self._to_ref(frame)), boxes)
