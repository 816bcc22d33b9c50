"""Long point tracks from a video: the track matrix ``W`` of Sec. 4.3.2, measured by KLT.

Features (Shi-Tomasi corners) are tracked frame to frame by pyramidal Lucas-Kanade and kept only
while the backward flow returns to within ``fb_max`` pixels of where the point started (the
forward-backward check) and the spatial gradient is strong enough to pin the point in both
directions (``min_eig``: no sliding along an edge). Empty parts of the image are re-seeded every
``reseed`` frames, so new surfaces (a lid's underside, a drawer's side) get tracks too.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

__all__ = ["PointTracks", "point_tracks"]


@dataclass
class PointTracks:
    """``xy[f, i]``: image position (pixels) of track ``i`` in frame ``f``; NaN where untracked."""

    xy: np.ndarray  # (frames, tracks, 2) float64
    fps: float
    width: int
    height: int

    @cached_property
    def visible(self) -> np.ndarray:
        return ~np.isnan(self.xy[:, :, 0])

    @cached_property
    def first(self) -> np.ndarray:
        """First frame of every track."""
        return self.visible.argmax(axis=0)

    @cached_property
    def last(self) -> np.ndarray:
        """Last frame of every track."""
        return len(self.xy) - 1 - self.visible[::-1].argmax(axis=0)

    @cached_property
    def start(self) -> np.ndarray:
        """Every track's first position, ``(tracks, 2)``."""
        return self.xy[self.first, np.arange(self.xy.shape[1])]

    @cached_property
    def excursion(self) -> np.ndarray:
        """How far (px) every track gets from its first position."""
        with np.errstate(invalid="ignore"):
            return np.nanmax(np.linalg.norm(self.xy - self.start[None], axis=2), axis=0)

    @property
    def frames(self) -> int:
        return len(self.xy)


def point_tracks(frames: Iterable[np.ndarray], fps: float, max_points: int = 1000, reseed: int = 5,
                 fb_max: float = 1.0, min_eig: float = 1e-3, spacing: int = 7,
                 on_frame: Callable[[int], None] | None = None) -> PointTracks:
    """Track corners through ``frames`` (BGR or gray uint8 images of one size)."""
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.03)

    def lk(a: np.ndarray, b: np.ndarray, p: np.ndarray):
        return cv2.calcOpticalFlowPyrLK(a, b, p, np.empty(0), winSize=(15, 15), maxLevel=3, criteria=criteria,
                                        flags=cv2.OPTFLOW_LK_GET_MIN_EIGENVALS, minEigThreshold=min_eig)

    rows: list[tuple[np.ndarray, np.ndarray]] = []  # per frame: (track ids, positions)
    ids = np.zeros(0, dtype=np.int64)
    pts = np.zeros((0, 2), dtype=np.float32)
    prev = None
    n_tracks = 0
    h = w = 0
    for f, img in enumerate(frames):
        gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img
        h, w = gray.shape
        if prev is not None and len(pts):
            nxt, st, _ = lk(prev, gray, pts)
            back, st2, _ = lk(gray, prev, nxt)
            ok = (st[:, 0] == 1) & (st2[:, 0] == 1) & (np.linalg.norm(back - pts, axis=1) < fb_max)
            ok &= (nxt[:, 0] >= 0) & (nxt[:, 1] >= 0) & (nxt[:, 0] <= w - 1) & (nxt[:, 1] <= h - 1)
            ids, pts = ids[ok], nxt[ok]
        if f % reseed == 0 and len(pts) < 0.9 * max_points:
            mask = np.full(gray.shape, 255, np.uint8)
            for x, y in pts.astype(int):
                cv2.circle(mask, (int(x), int(y)), spacing, 0, -1)
            new = cv2.goodFeaturesToTrack(gray, max_points - len(pts), 0.005, spacing, mask=mask, blockSize=5)
            if new is not None:
                new = new.reshape(-1, 2).astype(np.float32)
                ids = np.concatenate([ids, np.arange(n_tracks, n_tracks + len(new))])
                pts = np.vstack([pts, new])
                n_tracks += len(new)
        rows.append((ids.copy(), pts.astype(np.float64)))
        prev = gray
        if on_frame is not None:
            on_frame(f + 1)
    xy = np.full((len(rows), n_tracks, 2), np.nan)
    for f, (i, p) in enumerate(rows):
        xy[f, i] = p
    return PointTracks(xy, float(fps), w, h)
