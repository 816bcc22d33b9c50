"""Which tracks move, relative to what, and in which rigid groups (Sec. 4.3.2 on video).

* :func:`camera_motion` — the image motion of the static scene, frame to frame (a RANSAC
  similarity over all tracks: most of them lie on the scene); tracks are then expressed in the
  first frame's coordinates, so a hand-held camera is taken out before anything else.
* :func:`noise_level` — the tracks' own jitter (robust std of frame-to-frame steps), from which
  every later tolerance follows: nothing is a fixed number of pixels.
* :func:`moving_tracks` — tracks that rest at first (they belong to the scene: hands and arms enter
  moving) and later move well beyond the noise.
* :func:`rigid_parts` — groups of moving tracks that share one affine image motion per frame (the
  weak-perspective image of a rigid motion), found by RANSAC over triples of nearby tracks and
  refined over the whole video; each group is a part.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from artmotion.articulation.video.tracks import PointTracks

__all__ = ["Part", "camera_motion", "noise_level", "moving_tracks", "rigid_parts", "chain_affines", "part_motion"]

_EYE = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def _compose(D: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``D o A`` for 2x3 affines."""
    return np.hstack([D[:, :2] @ A[:, :2], (D[:, :2] @ A[:, 2] + D[:, 2])[:, None]])


def _invert(A: np.ndarray) -> np.ndarray:
    Li = np.linalg.inv(A[:, :2])
    return np.hstack([Li, (-Li @ A[:, 2])[:, None]])


def _apply(A: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Apply 2x3 affines ``A`` (..., 2, 3) to points ``X`` (..., 2)."""
    return np.einsum("...ij,...j->...i", A[..., :2], X) + A[..., 2]


def camera_motion(tracks: PointTracks, sigma: float) -> tuple[bool, PointTracks]:
    """Whether the camera moves, and the tracks in the first frame's coordinates.

    The camera counts as still when, over most windows of a third of a second, a quarter of the
    tracks seen at both ends of the window stay within ``1 px + 4 sigma`` (a still camera leaves the
    scene still, while hands and arms may cover most of the image; a moving one moves nearly
    everything). Its motion is then taken out with frame-to-frame similarities fitted by RANSAC to
    every track seen in both frames. A still camera's tracks are returned unchanged."""
    xy = tracks.xy
    F = len(xy)
    k = max(1, int(round(tracks.fps / 3)))
    if F <= k:
        return False, tracks
    d = np.linalg.norm(xy[k:] - xy[:-k], axis=2)
    seen = ~np.isnan(d)
    with np.errstate(invalid="ignore"):
        still = (d < 1.0 + 4 * sigma).sum(axis=1) / np.maximum(seen.sum(axis=1), 1)
    if np.mean(still[seen.sum(axis=1) >= 8] >= 0.25) >= 0.9:
        return False, tracks
    A = np.tile(_EYE, (F, 1, 1))
    for f in range(1, F):
        ok = ~np.isnan(xy[f - 1, :, 0]) & ~np.isnan(xy[f, :, 0])
        D = None
        if ok.sum() >= 8:
            D, _ = cv2.estimateAffinePartial2D(xy[f - 1, ok], xy[f, ok], method=cv2.RANSAC,
                                               ransacReprojThreshold=max(1.0, 3 * sigma))
        A[f] = _compose(D if D is not None else _EYE, A[f - 1])
    inv = np.stack([_invert(a) for a in A])
    return True, PointTracks(_apply(inv[:, None], xy), tracks.fps, tracks.width, tracks.height)


def noise_level(tracks: PointTracks) -> float:
    """Robust std (px) of one coordinate's frame-to-frame step over all tracks (most are static)."""
    d = np.diff(tracks.xy, axis=0).reshape(-1)
    d = d[~np.isnan(d)]
    if d.size == 0:
        return 0.5
    return float(max(1.4826 * np.median(np.abs(d - np.median(d))), 0.05))


def moving_tracks(tracks: PointTracks, sigma: float, rest: float = 0.25, move: float = 12.0) -> np.ndarray:
    """Indices of tracks that rest for their first ``rest`` seconds (within ``3 sigma + 0.5 px`` of
    where they start) and later move more than ``move sigma`` (at least 4 px) from there."""
    xy = tracks.xy
    first = tracks.first
    N = xy.shape[1]
    start = xy[first, np.arange(N)]
    disp = np.linalg.norm(xy - start[None], axis=2)
    with np.errstate(invalid="ignore"):
        far = np.nanmax(disp, axis=0)
    k = max(3, int(round(rest * tracks.fps)))
    cand = np.flatnonzero((far > max(4.0, move * sigma)) & (tracks.last - first >= 2 * k))
    keep = [i for i in cand
            if tracks.visible[first[i]:first[i] + k, i].all() and disp[first[i]:first[i] + k, i].max() < 3 * sigma + 0.5]
    return np.asarray(keep, dtype=int)


def _fit_step(P: np.ndarray, Q: np.ndarray, similarity: bool) -> tuple[np.ndarray, float]:
    """Least-squares 2x3 map ``P -> Q`` (affine, or similarity) and its residual sum of squares."""
    n = len(P)
    if similarity:
        M = np.zeros((2 * n, 4))
        M[0::2] = np.column_stack([P[:, 0], -P[:, 1], np.ones(n), np.zeros(n)])
        M[1::2] = np.column_stack([P[:, 1], P[:, 0], np.zeros(n), np.ones(n)])
        (a, b, tx, ty), *_ = np.linalg.lstsq(M, Q.reshape(-1), rcond=None)
        D = np.array([[a, -b, tx], [b, a, ty]])
    else:
        sol, *_ = np.linalg.lstsq(np.hstack([P, np.ones((n, 1))]), Q, rcond=None)
        D = sol.T
    return D, float(((_apply(D, P) - Q) ** 2).sum())


def chain_affines(xy: np.ndarray, idx: np.ndarray, similarity: bool = False) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Image motion of the tracks ``idx`` as one affine per frame, chained from frame-to-frame
    least-squares fits (``similarity``: rotation, scale and shift only): ``A[f]`` maps the
    group's frame-0 coordinates to frame ``f``. ``segment[f]`` numbers the runs of frames over which
    the chain is unbroken (-1: no fit, fewer than 3 of the tracks seen in both frames). Also the
    fits' residual sum of squares and number of coordinates fitted."""
    F = len(xy)
    A = np.tile(_EYE, (F, 1, 1))
    segment = np.full(F, -1)
    seg = -1
    rss, count = 0.0, 0
    P = xy[:, idx]
    for f in range(1, F):
        ok = ~np.isnan(P[f - 1, :, 0]) & ~np.isnan(P[f, :, 0])
        if ok.sum() >= 3:
            D, r = _fit_step(P[f - 1, ok], P[f, ok], similarity)
            rss += r
            count += 2 * int(ok.sum())
            if segment[f - 1] < 0:
                seg += 1
                segment[f - 1] = seg
            segment[f] = seg
            A[f] = _compose(D, A[f - 1])
        else:
            A[f] = A[f - 1]
    return A, segment, rss, count


def part_motion(xy: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, str]:
    """The part's chained motion under the image-motion model that the Bayesian information
    criterion prefers: a similarity (4 parameters per frame: a part turning or sliding in a plane
    facing the camera, and thin parts, whose affine is ill-determined across them) or an affine
    (6: foreshortening, a lid turning about a hinge in the image plane)."""
    best = None
    for sim in (True, False):
        A, seg, rss, n = chain_affines(xy, idx, similarity=sim)
        k = (4 if sim else 6) * int((seg >= 0).sum())
        bic = n * math.log(max(rss, 1e-12) / max(n, 1)) + k * math.log(max(n, 2))
        if best is None or bic < best[0]:
            best = (bic, A, seg, "similarity" if sim else "affine")
    assert best is not None
    return best[1], best[2], best[3]


def _residuals(xy: np.ndarray, A: np.ndarray, segment: np.ndarray, cand: np.ndarray) -> np.ndarray:
    """Largest distance (px) over its life between each candidate track and where the group's
    motion carries its first position in each unbroken run (NaN: never seen while the chain runs)."""
    P = xy[:, cand]
    out = np.full(len(cand), np.nan)
    worst = np.full(len(cand), -1.0)
    for s in np.unique(segment[segment >= 0]):
        fr = np.flatnonzero(segment == s)
        Ps = P[fr]
        vis = ~np.isnan(Ps[:, :, 0])
        has = vis.any(axis=0)
        if not has.any():
            continue
        k0 = vis.argmax(axis=0)
        j = np.arange(len(cand))
        # each track's first position in the run, moved to the group's frame-0 coordinates
        A0 = A[fr[k0]]
        x0 = _apply(np.stack([_invert(a) for a in A0]), Ps[k0, j])
        pred = _apply(A[fr][:, None], x0[None])
        r = np.linalg.norm(pred - Ps, axis=2)
        r = np.where(vis, r, -1.0)
        m = np.where(vis.sum(axis=0) >= 2, r.max(axis=0), np.nan)
        better = has & ~np.isnan(m)
        worst[better] = np.maximum(worst[better], m[better])
    out[worst >= 0] = worst[worst >= 0]
    return out


@dataclass
class Part:
    """A rigid group of tracks: ``tracks`` (indices), ``A`` (frames, 2, 3) its image motion from
    frame-0 coordinates, ``segment`` the unbroken runs of ``A``, ``motion`` how far (px) its tracks
    move (median of their largest displacement)."""

    tracks: np.ndarray
    A: np.ndarray
    segment: np.ndarray
    motion: float
    kind: str = "affine"  # the image-motion model of ``A`` (see :func:`part_motion`)

    @property
    def frames(self) -> tuple[int, int]:
        f = np.flatnonzero(self.segment >= 0)
        return (int(f[0]), int(f[-1])) if f.size else (0, 0)


def rigid_parts(tracks: PointTracks, cand: np.ndarray, sigma: float, max_parts: int = 3, iters: int = 200,
                min_tracks: int = 8, seed: int = 0) -> list[Part]:
    """Rigid groups among the moving tracks ``cand``, largest motion first (see the module doc).

    A hypothesis is the chained affine motion of three nearby tracks over their common life; its
    inliers are the candidates that stay within ``tol = 3 sigma + 1 px + 5%`` of their own motion
    of where it carries them. The best hypothesis (inliers weighted by how far they move) is
    refined twice over the whole video with all its inliers."""
    rng = np.random.default_rng(seed)
    xy = tracks.xy
    first = tracks.first
    N = xy.shape[1]
    start = xy[first, np.arange(N)]
    with np.errstate(invalid="ignore"):
        far = np.nanmax(np.linalg.norm(xy - start[None], axis=2), axis=0)
    parts: list[Part] = []
    left = np.asarray(cand, dtype=int)
    base_tol = 3 * sigma + 1.0
    while len(parts) < max_parts and len(left) >= min_tracks:
        tol = base_tol + 0.02 * far[left]
        pos = start[left]
        best = None
        for _ in range(iters):
            i = rng.integers(len(left))
            near = np.argsort(np.linalg.norm(pos - pos[i], axis=1))[1:20]
            j, k = rng.choice(near, 2, replace=False)
            s = left[[i, j, k]]
            tri = start[s]
            if abs(np.cross(np.append(tri[1] - tri[0], 0), np.append(tri[2] - tri[0], 0))[2]) < 50:
                continue
            A, seg, _, _ = chain_affines(xy, s)
            r = _residuals(xy, A, seg, left)
            inl = ~np.isnan(r) & (r < tol)
            score = far[left][inl].sum()
            if best is None or score > best[0]:
                best = (score, inl)
        if best is None or best[1].sum() < min_tracks:
            break
        inl = best[1]
        for _ in range(2):
            A, seg, _, _ = chain_affines(xy, left[inl])
            r = _residuals(xy, A, seg, left)
            new = ~np.isnan(r) & (r < tol)
            if new.sum() < min_tracks:
                break
            inl = new
        A, seg, kind = part_motion(xy, left[inl])
        parts.append(Part(left[inl], A, seg, float(np.median(far[left[inl]])), kind))
        left = left[~inl]
    parts.sort(key=lambda p: -p.motion * np.sqrt(len(p.tracks)))
    return parts
