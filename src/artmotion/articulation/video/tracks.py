"""Long point tracks from a video: the track matrix ``W`` of Sec. 4.3.2, measured by KLT.

Features (Shi-Tomasi corners) are tracked frame to frame by pyramidal Lucas-Kanade and kept only
while the backward flow returns to within ``fb_max`` pixels of where the point started (the
forward-backward check) and the spatial gradient is strong enough to pin the point in both
directions (``min_eig``: no sliding along an edge). Empty parts of the image are re-seeded every
``reseed`` frames, so new surfaces (a lid's underside, a drawer's side) get tracks too.

A hand passing over the scene drags tracks along with its edge, a few pixels a frame (the
forward-backward check passes them), and exposure changes make tracks drift along blurred edges:
the track moves, the point does not. So every ``reseed`` frames each track that has left its first
position by more than KLT's window is asked where its point is: the patch at its first position
in the current frame and the patch at its current position are both compared with the patch it
started from (normalised cross-correlation, which ignores changes of gain and offset). When the
first position looks more like it, the track has slipped off its point (``PointTracks.slipped``:
on most such checks). Only meaningful for a still camera; for a moving one the first position is
not the same place in the scene.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from artmotion.errors import InputError, check_range, float_array

__all__ = ["PointTracks", "point_tracks"]


@dataclass
class PointTracks:
    """``xy[f, i]``: image position (pixels) of track ``i`` in frame ``f``; NaN where untracked.
    ``slips[i]`` of ``checks[i]`` checks found track ``i``'s first position looking more like its
    first patch than its current position did (see the module doc; None: not checked).

    Checked when made (an :class:`InputError` naming the argument): ``xy`` of shape
    ``(frames, tracks, 2)``, both coordinates NaN or both finite, within ``±1e6`` px; ``fps`` in
    ``[0.001, 1000]``; ``width`` and ``height`` whole numbers >= 1; ``slips`` and ``checks`` whole
    numbers in [0, frames], one per track, no more slips than checks."""

    xy: np.ndarray  # (frames, tracks, 2) float64
    fps: float
    width: int
    height: int
    slips: np.ndarray | None = None
    checks: np.ndarray | None = None

    def __post_init__(self):
        from artmotion.io.media import MAX_FPS, MAX_IMAGE_PIXELS, MIN_FPS
        from artmotion.io.mot import MAX_COORD

        xy = float_array(self.xy, "xy")
        if xy.ndim != 3 or xy.shape[2] != 2:
            raise InputError(f"xy must be an array of shape (frames, tracks, 2), got shape {xy.shape}")
        nan = np.isnan(xy)
        if (nan[..., 0] != nan[..., 1]).any():
            raise InputError("xy: a position with one coordinate NaN (an untracked entry has both NaN)")
        if (np.abs(xy[~nan]) > MAX_COORD).any():     # (inf too)
            raise InputError(f"xy must hold finite positions within ±{MAX_COORD:g} px (NaN where untracked)")
        self.xy = xy
        self.fps = float(check_range("fps (frames/s)", self.fps, MIN_FPS, MAX_FPS))
        self.width = check_range("width", self.width, 1, MAX_IMAGE_PIXELS, integer=True)
        self.height = check_range("height", self.height, 1, MAX_IMAGE_PIXELS, integer=True)
        for name in ("slips", "checks"):
            v = getattr(self, name)
            if v is None:
                continue
            v = float_array(v, name)
            # (at most one check a frame: 1e30 wrapped round to -9.2e18 as an int64)
            if v.shape != (xy.shape[1],) or not np.all((v >= 0) & (v <= len(xy)) & (v == np.round(v))):
                raise InputError(f"{name} must be {xy.shape[1]} whole numbers in [0, {len(xy)}] (one per track), got "
                                 f"{'shape ' + str(v.shape) if v.shape != (xy.shape[1],) else 'other values'}")
            setattr(self, name, v.astype(np.int64))
        if (self.slips is None) != (self.checks is None) or (self.slips is not None and np.any(self.slips > self.checks)):
            raise InputError("slips and checks go together (both or neither), no more slips than checks")

    @property
    def slipped(self) -> np.ndarray:
        """Tracks that left their point on most checks (all False when nothing was checked)."""
        if self.slips is None or self.checks is None:
            return np.zeros(self.xy.shape[1], dtype=bool)
        return 2 * self.slips > self.checks

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


def _patches(gray: np.ndarray, p: np.ndarray, r: int) -> np.ndarray:
    """``(n, 2r+1, 2r+1)`` patches of ``gray`` round the rounded points ``p``, moved inside the image
    where they would leave it (an image smaller than a patch repeats its border pixels)."""
    h, w = gray.shape
    c = np.clip(np.round(p).astype(int), r, [max(w - 1 - r, r), max(h - 1 - r, r)])
    o = np.arange(-r, r + 1)
    rows = np.clip(c[:, 1, None, None] + o[None, :, None], 0, h - 1)
    cols = np.clip(c[:, 0, None, None] + o[None, None, :], 0, w - 1)
    return gray[rows, cols]


def _ncc(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Normalised cross-correlation of corresponding patches (rows of ``a`` and ``b``)."""
    a = a.reshape(len(a), -1).astype(np.float32)
    b = b.reshape(len(b), -1).astype(np.float32)
    a -= a.mean(axis=1, keepdims=True)
    b -= b.mean(axis=1, keepdims=True)
    return (a * b).sum(axis=1) / np.sqrt((a * a).sum(axis=1) * (b * b).sum(axis=1) + 1e-6)


def point_tracks(frames: Iterable[np.ndarray], fps: float, max_points: int = 1000, reseed: int = 5,
                 fb_max: float = 1.0, min_eig: float = 1e-3, spacing: int = 7,
                 on_frame: Callable[[int], None] | None = None) -> PointTracks:
    """Track corners through ``frames`` (BGR or gray uint8 images of one size)."""
    check_range("fps", fps, 1e-3, 1e3)
    check_range("max_points", max_points, 1, 10**6, integer=True)
    check_range("reseed", reseed, 1, 10**6, integer=True)
    check_range("fb_max", fb_max, 0.0, 1e6, lo_open=True)
    check_range("min_eig", min_eig, 0.0, 1.0)
    check_range("spacing", spacing, 1, 10**4, integer=True)
    win = 15  # KLT's window; also the patch that tells whether a track is still on its point
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.03)

    def lk(a: np.ndarray, b: np.ndarray, p: np.ndarray):
        return cv2.calcOpticalFlowPyrLK(a, b, p, np.empty(0), winSize=(win, win), maxLevel=3, criteria=criteria,
                                        flags=cv2.OPTFLOW_LK_GET_MIN_EIGENVALS, minEigThreshold=min_eig)

    rows: list[tuple[np.ndarray, np.ndarray]] = []  # per frame: (track ids, positions)
    ids = np.zeros(0, dtype=np.int64)
    pts = np.zeros((0, 2), dtype=np.float32)
    home = np.zeros((0, 2), dtype=np.float32)          # every track's first position, by id
    first = np.zeros((0, win, win), dtype=np.uint8)    # and its patch there
    slips: list[np.ndarray] = []                       # per check: ids that slipped, ids checked
    checked: list[np.ndarray] = []
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
        if f % reseed == 0 and len(pts):
            away = np.linalg.norm(pts - home[ids], axis=1) > win   # the two patches do not overlap
            if away.any():
                i = ids[away]
                at_home = _ncc(first[i], _patches(gray, home[i], win // 2))
                here = _ncc(first[i], _patches(gray, pts[away], win // 2))
                slips.append(i[at_home > here])
                checked.append(i)
        if f % reseed == 0 and len(pts) < 0.9 * max_points:
            mask = np.full(gray.shape, 255, np.uint8)
            for x, y in pts.astype(int):
                cv2.circle(mask, (int(x), int(y)), spacing, 0, -1)
            new = cv2.goodFeaturesToTrack(gray, max_points - len(pts), 0.005, spacing, mask=mask, blockSize=5)
            if new is not None:
                new = new.reshape(-1, 2).astype(np.float32)
                ids = np.concatenate([ids, np.arange(n_tracks, n_tracks + len(new))])
                pts = np.vstack([pts, new])
                home = np.vstack([home, new])
                first = np.concatenate([first, _patches(gray, new, win // 2)])
                n_tracks += len(new)
        rows.append((ids.copy(), pts.astype(np.float64)))
        prev = gray
        if on_frame is not None:
            on_frame(f + 1)
    if not rows:
        raise InputError("no frames to track")
    xy = np.full((len(rows), n_tracks, 2), np.nan)
    for f, (i, p) in enumerate(rows):
        xy[f, i] = p
    count = [np.bincount(np.concatenate(c or [np.zeros(0, np.int64)]), minlength=n_tracks) for c in (slips, checked)]
    return PointTracks(xy, float(fps), w, h, slips=count[0], checks=count[1])
