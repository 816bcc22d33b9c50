"""Which tracks move, relative to what, and in which rigid groups (Sec. 4.3.2 on video).

* :func:`camera_motion` — the image motion of the static scene, frame to frame (a RANSAC
  similarity over all tracks: most of them lie on the scene); tracks are then expressed in the
  first frame's coordinates, so a hand-held camera is taken out before anything else.
* :func:`noise_level` — the tracks' own jitter (robust std of frame-to-frame steps), from which
  every later tolerance follows: nothing is a fixed number of pixels.
* :func:`moving_tracks` — tracks that rest at first (they belong to the scene: hands and arms enter
  moving) and later move well beyond the noise, and did not slip off their point (a hand's edge
  drags tracks along).
* :func:`rigid_parts` — groups of moving tracks that share one affine image motion per frame (the
  weak-perspective image of a rigid motion), found by RANSAC over triples of nearby tracks and
  refined over the whole video; each group is a part.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from artmotion.articulation.online import resolution, robust_scale
from artmotion.articulation.video.tracks import PointTracks
from artmotion.errors import InputError, check_range, float_array
from artmotion.geometry.affine import IDENTITY, apply, compose, invert

__all__ = ["Part", "check_part", "camera_motion", "noise_level", "moving_tracks", "rigid_parts", "chain_affines",
           "factorise_motion", "part_motion"]


def _check_tracks(tracks) -> PointTracks:
    if not isinstance(tracks, PointTracks):
        raise InputError(f"tracks must be a PointTracks (artmotion.articulation.video.tracks), got {type(tracks).__name__}")
    return tracks


def _check_sigma(sigma) -> float:
    """The tracks' noise (px): a number >= 0 (:func:`noise_level` gives at least 0.05; 0 for
    noiseless synthetic tracks)."""
    return float(check_range("sigma", sigma, 0.0, 1e6))


def _check_xy(xy) -> np.ndarray:
    """Track positions ``(frames, tracks, 2)``, NaN where a track is not seen."""
    xy = float_array(xy, "xy")
    if xy.ndim != 3 or xy.shape[2] != 2:
        raise InputError(f"xy must be track positions of shape (frames, tracks, 2), got shape {xy.shape}")
    if np.isinf(xy).any():
        raise InputError("xy must be finite positions (NaN where a track is not seen), got infinity")
    return xy


def _check_indices(idx, n: int, name: str = "idx") -> np.ndarray:
    """Track indices into ``n`` tracks (whole numbers in [-n, n), as NumPy indexes; or a boolean
    mask of length ``n``), as indices in [0, n)."""
    arr = np.asarray(idx)
    if arr.dtype == bool:
        if arr.shape != (n,):
            raise InputError(f"{name} as a mask must have one entry per track ({n}), got shape {arr.shape}")
        return np.flatnonzero(arr)
    whole = arr.dtype.kind in "iu" or (arr.dtype.kind == "f" and np.all(np.isfinite(arr)) and np.all(arr == np.round(arr)))
    if arr.ndim != 1 or (arr.size and not whole):
        raise InputError(f"{name} must be a 1-D array of track indices (whole numbers), got {arr.dtype} of shape {arr.shape}")
    if arr.size and (arr.min() < -n or arr.max() >= n):
        raise InputError(f"{name} must index the {n} tracks (-{n} to {n - 1}), got {int(arr.min())} to {int(arr.max())}")
    return arr.astype(int) % max(n, 1)


def camera_motion(tracks: PointTracks, sigma: float) -> tuple[bool, PointTracks]:
    """Whether the camera moves, and the tracks in the first frame's coordinates.

    The camera counts as still when, over most windows of a third of a second, a quarter of the
    tracks seen at both ends of the window stay within ``1 px + 4 sigma`` (a still camera leaves the
    scene still, while hands and arms may cover most of the image; a moving one moves nearly
    everything). Its motion is then taken out with frame-to-frame similarities fitted by RANSAC to
    every track seen in both frames. A still camera's tracks are returned unchanged (a moving
    camera's without the slip checks, which compare image places, not scene places)."""
    sigma = _check_sigma(sigma)
    xy = _check_tracks(tracks).xy
    F = len(xy)
    k = max(1, int(round(tracks.fps / 3)))
    if F <= k:
        return False, tracks
    d = np.linalg.norm(xy[k:] - xy[:-k], axis=2)
    seen = ~np.isnan(d)
    with np.errstate(invalid="ignore"):
        still = (d < 1.0 + 4 * sigma).sum(axis=1) / np.maximum(seen.sum(axis=1), 1)
    counted = still[seen.sum(axis=1) >= 8]
    if not counted.size or np.mean(counted >= 0.25) >= 0.9:   # (too few tracks to tell: taken as still)
        return False, tracks
    A = np.tile(IDENTITY, (F, 1, 1))
    for f in range(1, F):
        ok = ~np.isnan(xy[f - 1, :, 0]) & ~np.isnan(xy[f, :, 0])
        D = None
        if ok.sum() >= 8:
            D, _ = cv2.estimateAffinePartial2D(xy[f - 1, ok], xy[f, ok], method=cv2.RANSAC,
                                               ransacReprojThreshold=max(1.0, 3 * sigma))
        A[f] = compose(D if D is not None else IDENTITY, A[f - 1])
    return True, replace(tracks, xy=apply(invert(A)[:, None], xy), slips=None, checks=None)


def noise_level(tracks: PointTracks) -> float:
    """Robust std (px) of one coordinate's frame-to-frame step over all tracks (most are static),
    at least that of the rounding of positions written on a grid (whole pixels: most steps are 0,
    and the median said no noise, so every still point's one-pixel flicker broke its rest; the
    difference of two roundings uniform over a step ``r`` has std ``r / sqrt 6``)."""
    d = np.diff(_check_tracks(tracks).xy, axis=0).reshape(-1)
    d = d[~np.isnan(d)]
    if d.size == 0:
        return 0.5
    xy = tracks.xy[~np.isnan(tracks.xy[:, :, 0])]
    rounding = resolution(xy) / math.sqrt(6.0) if len(xy) else 0.0
    return float(max(1.4826 * np.median(np.abs(d - np.median(d))), 0.05, rounding))


#: seconds a moving track must rest first (it belongs to the scene; hands and arms enter moving)
REST = 0.25

#: a part's motion is this quantile of its tracks' largest displacements (:class:`Part`); chosen among
#: 0.5, 0.75, 0.9 and 1 by leave-one-video-out on the shared videos (docs/articulation_video.md)
MOTION_QUANTILE = 0.9


def rest_frames(fps: float, rest: float = REST) -> int:
    """Frames a moving track rests first; it must live twice as long (:func:`moving_tracks`)."""
    check_range("fps", fps, 1e-3, 1e3)
    check_range("rest", rest, 0.0, 1e4)
    return max(3, int(round(rest * fps)))


def moving_tracks(tracks: PointTracks, sigma: float, rest: float = REST, move: float = 12.0) -> np.ndarray:
    """Indices of tracks that rest for their first ``rest`` seconds (within ``3 sigma + 0.5 px`` of
    where they start) and later move more than ``move sigma`` (at least 4 px) from there, leaving
    out those that slipped off their point (:attr:`PointTracks.slipped`: a hand's edge dragged them,
    or they drifted along an edge; a point that moved leaves its first place looking different)."""
    sigma = _check_sigma(sigma)
    check_range("move", move, 0.0, 1e6)
    first = _check_tracks(tracks).first
    k = rest_frames(tracks.fps, rest)
    cand = np.flatnonzero((tracks.excursion > max(4.0, move * sigma)) & (tracks.last - first >= 2 * k)
                          & ~tracks.slipped)
    keep = [i for i in cand if tracks.visible[first[i]:first[i] + k, i].all()
            and np.linalg.norm(tracks.xy[first[i]:first[i] + k, i] - tracks.start[i], axis=1).max() < 3 * sigma + 0.5]
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
    return D, float(((apply(D, P) - Q) ** 2).sum())


def chain_affines(xy: np.ndarray, idx: np.ndarray, similarity: bool = False) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Image motion of the tracks ``idx`` as one affine per frame, chained from frame-to-frame
    least-squares fits (``similarity``: rotation, scale and shift only): ``A[f]`` maps the
    group's frame-0 coordinates to frame ``f``. ``segment[f]`` numbers the runs of frames over which
    the chain is unbroken (-1: no fit, fewer than 3 of the tracks seen in both frames). Also the
    fits' residual sum of squares and number of coordinates fitted."""
    xy = _check_xy(xy)
    return _chain(xy, _check_indices(idx, xy.shape[1]), bool(similarity))


def _chain(xy: np.ndarray, idx: np.ndarray, similarity: bool = False) -> tuple[np.ndarray, np.ndarray, float, int]:
    """:func:`chain_affines` of checked arguments (the part search calls it hundreds of times)."""
    F = len(xy)
    A = np.tile(IDENTITY, (F, 1, 1))
    segment = np.full(F, -1)
    seg = -1
    rss, count = 0.0, 0
    P = xy[:, idx]
    seen = ~np.isnan(P[:, :, 0])
    both = seen[:-1] & seen[1:]
    fits = np.flatnonzero(both.sum(axis=1) >= 3) + 1  # frames with a fit from the one before
    for n, f in enumerate(fits):
        ok = both[f - 1]
        D, r = _fit_step(P[f - 1, ok], P[f, ok], similarity)
        rss += r
        count += 2 * int(ok.sum())
        if segment[f - 1] < 0:
            seg += 1
            segment[f - 1] = seg
        segment[f] = seg
        # the chain holds still until the next fit
        A[f:fits[n + 1] if n + 1 < len(fits) else F] = compose(D, A[f - 1])
    return A, segment, rss, count


def _frame_maps(X: np.ndarray, Q: np.ndarray, W: np.ndarray, similarity: bool) -> np.ndarray:
    """Weighted least-squares map (affine, or similarity) of the points ``X`` (``(n, 2)``) to their
    positions ``Q[f]`` (``(m, n, 2)``, zero where unseen) with weights ``W`` (``(m, n)``, zero where
    unseen): ``(m, 2, 3)``. One batched solve of the normal equations."""
    x, y = X[:, 0], X[:, 1]
    one, zero = np.ones_like(x), np.zeros_like(x)
    m = len(W)
    if similarity:   # x' = a x - b y + tx, y' = b x + a y + ty
        rows = [np.stack([x, -y, one, zero], -1), np.stack([y, x, zero, one], -1)]   # (n, 4) each
        N = sum(W @ (r[:, :, None] * r[:, None, :]).reshape(-1, 16) for r in rows).reshape(m, 4, 4)
        rhs = (W * Q[:, :, 0]) @ rows[0] + (W * Q[:, :, 1]) @ rows[1]
        a, b, tx, ty = (np.linalg.pinv(N) @ rhs[..., None])[..., 0].T
        return np.stack([np.stack([a, -b, tx], -1), np.stack([b, a, ty], -1)], 1)
    Xh = np.column_stack([X, one])                                 # (n, 3)
    N = (W @ (Xh[:, :, None] * Xh[:, None, :]).reshape(-1, 9)).reshape(m, 3, 3)
    rhs = Xh.T[None] @ (W[:, :, None] * Q)                         # (m, 3, 2)
    return np.swapaxes(np.linalg.pinv(N) @ rhs, 1, 2)        # pinv: three tracks in a line


def _squared_residuals(M: np.ndarray, X: np.ndarray, Q: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """``|M[f] X[i] - Q[f, i]|^2`` where ``seen``, 0 elsewhere: ``(m, n)``."""
    return np.where(seen, ((apply(M[:, None], X[None]) - Q) ** 2).sum(axis=2), 0.0)


def factorise_motion(xy: np.ndarray, idx: np.ndarray, similarity: bool = False, nu: float | None = 4.0,
                     tol: float = 1e-6, max_iters: int = 200) -> tuple[np.ndarray, np.ndarray, float, int]:
    """The image motion of the tracks ``idx`` as the factorisation of their track matrix (Sec.
    4.3.2, Eq. 4.2: ``W = M S``), with its missing entries: one map ``A[f]`` per frame (affine, or
    ``similarity``) and one position per track in common coordinates. A chain of frame-to-frame
    fits (:func:`chain_affines`) adds up every step's error; here every ``A[f]`` is fitted to all
    the part's points seen at ``f``, by alternating least squares started from the chain and run
    until the weighted residual sum of squares changes by less than ``tol`` (relative). Residuals
    are weighted as a Student-t with ``nu`` degrees of freedom (None: Gaussian), its scale from the
    data, as in the model choice (:func:`~artmotion.articulation.online.robust_scale`): a track
    dragged off its point by an occluding hand for a few frames is down-weighted there.

    ``A[f]`` maps the coordinates of the first frame with a fit to frame ``f`` (held between fits);
    ``segment`` is 0 on the frames with a fit (at least 3 tracks seen), -1 elsewhere. Also the
    weighted residual sum of squares and the number of coordinates fitted."""
    xy = _check_xy(xy)
    idx = _check_indices(idx, xy.shape[1])
    if nu is not None:
        nu = check_range("nu", nu, 0.0, 1e6, lo_open=True)
    tol = check_range("tol", tol, 0.0, 1.0)      # (0: run all max_iters)
    max_iters = check_range("max_iters", max_iters, 1, 10**6, integer=True)
    return _factorise(xy, idx, bool(similarity), nu, tol, max_iters)


def _factorise(xy: np.ndarray, idx: np.ndarray, similarity: bool, nu: float | None, tol: float,
               max_iters: int) -> tuple[np.ndarray, np.ndarray, float, int]:
    """:func:`factorise_motion` of checked arguments."""
    A, _, _, _ = _chain(xy, idx, similarity)
    P = xy[:, idx]
    vis = ~np.isnan(P[:, :, 0])
    frames = np.flatnonzero(vis.sum(axis=1) >= 3)
    segment = np.full(len(xy), -1)
    if not frames.size:
        return A, segment, 0.0, 0
    first = vis.argmax(axis=0)
    X = apply(invert(A[first]), P[first, np.arange(len(idx))])      # each track's place, via the chain
    seen = vis[frames]
    Q = np.where(seen[:, :, None], P[frames], 0.0)
    W = seen.astype(float)
    last = np.inf
    for _ in range(max_iters):
        M = _frame_maps(X, Q, W, similarity)
        # each track's place: weighted least squares over the frames that see it
        L, t = M[:, :, :2], M[:, :, 2]
        N = (W.T @ (np.swapaxes(L, 1, 2) @ L).reshape(-1, 4)).reshape(-1, 2, 2)
        WD = (W[:, :, None] * (Q - t[:, None, :])).transpose(1, 0, 2).reshape(len(X), -1)   # (n, m * 2)
        rhs = WD @ L.reshape(-1, 2)
        X = (np.linalg.pinv(N) @ rhs[..., None])[..., 0]
        e2 = _squared_residuals(M, X, Q, seen)
        rss = float((W * e2).sum())
        _, W[seen] = robust_scale(e2[seen], 2, nu)
        if abs(last - rss) <= tol * rss:
            break
        last = rss
    M = _frame_maps(X, Q, W, similarity)
    e2 = _squared_residuals(M, X, Q, seen)
    base = invert(M[0])
    held = np.searchsorted(frames, np.arange(len(xy)), side="right") - 1   # the last fit at or before f
    A = compose(M[np.maximum(held, 0)], base[None])
    A[held < 0] = IDENTITY
    segment[frames] = 0
    return A, segment, float((W * e2).sum()), 2 * int(seen.sum())


def part_motion(xy: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, str]:
    """The part's factorised motion (:func:`factorise_motion`) under the image-motion model that
    the Bayesian information criterion prefers: a similarity (4 parameters per frame: a part
    turning or sliding in a plane facing the camera, and thin parts, whose affine is
    ill-determined across them) or an affine (6: foreshortening, a lid turning about a hinge in
    the image plane)."""
    xy = _check_xy(xy)
    idx = _check_indices(idx, xy.shape[1])
    if idx.size < 3:
        raise InputError(f"a part's motion needs at least 3 tracks, got {idx.size}")
    return _part_motion(xy, idx)


def _part_motion(xy: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, str]:
    best = None
    for sim in (True, False):
        A, seg, rss, n = _factorise(xy, idx, sim, 4.0, 1e-6, 200)
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
    worst = np.full(len(cand), -1.0)
    j = np.arange(len(cand))
    for s in np.unique(segment[segment >= 0]):
        fr = np.flatnonzero(segment == s)
        Ps = P[fr]
        vis = ~np.isnan(Ps[:, :, 0])
        if not vis.any():
            continue
        k0 = vis.argmax(axis=0)
        # each track's first position in the run, moved to the group's frame-0 coordinates
        x0 = apply(invert(A[fr[k0]]), Ps[k0, j])
        r = np.where(vis, np.linalg.norm(apply(A[fr][:, None], x0[None]) - Ps, axis=2), -1.0)
        twice = vis.sum(axis=0) >= 2
        worst[twice] = np.maximum(worst[twice], r.max(axis=0)[twice])
    return np.where(worst >= 0, worst, np.nan)


@dataclass
class Part:
    """A rigid group of tracks: ``tracks`` (indices), ``A`` (frames, 2, 3) its image motion from
    frame-0 coordinates, ``segment`` the unbroken runs of ``A``, ``motion`` how far (px) the part
    moves: the 90th percentile of its tracks' largest displacements (a robust largest: the points
    of a part turning about a hinge move less the nearer they lie to it, so their median says
    more about where the tracks sit than how far the part moves)."""

    tracks: np.ndarray
    A: np.ndarray
    segment: np.ndarray
    motion: float
    kind: str  # the image-motion model of ``A``: "similarity" or "affine" (see :func:`part_motion`)

    @property
    def frames(self) -> tuple[int, int]:
        f = np.flatnonzero(self.segment >= 0)
        return (int(f[0]), int(f[-1])) if f.size else (0, 0)


def check_part(tracks: PointTracks, part) -> Part:
    """``part`` as a :class:`Part` of ``tracks`` with its track indices in [0, n) (given as
    :func:`chain_affines` takes them), if it has one map and one segment number per frame; else
    an :class:`InputError`."""
    _check_tracks(tracks)
    if not isinstance(part, Part):
        raise InputError(f"part must be a Part (artmotion.articulation.video.segment), got {type(part).__name__}")
    F, n = tracks.xy.shape[:2]
    idx = _check_indices(part.tracks, n, "part.tracks")
    if not idx.size:
        raise InputError("part.tracks must name at least one track")
    A, seg = np.asarray(part.A), np.asarray(part.segment)
    if A.shape != (F, 2, 3) or seg.shape != (F,):
        raise InputError(f"a part of {F}-frame tracks needs part.A of shape ({F}, 2, 3) and part.segment of ({F},), "
                         f"got {A.shape} and {seg.shape}")
    if not np.isfinite(A).all():
        raise InputError("part.A must be finite maps")
    return replace(part, tracks=idx)


def rigid_parts(tracks: PointTracks, cand: np.ndarray, sigma: float, max_parts: int = 3, iters: int = 200,
                min_tracks: int = 8, seed: int = 0) -> list[Part]:
    """Rigid groups among the moving tracks ``cand``, the largest ``motion`` times the square root of
    their track count first (see the module doc).

    A hypothesis is the chained affine motion of three nearby tracks over their common life; its
    inliers are the candidates that stay within ``tol = 3 sigma + 1 px + 2%`` of their own motion
    of where it carries them. The best hypothesis (inliers weighted by how far they move) is
    refined twice over the whole video with all its inliers."""
    _check_tracks(tracks)
    sigma = _check_sigma(sigma)
    max_parts = check_range("max_parts", max_parts, 1, 10**4, integer=True)
    iters = check_range("iters", iters, 1, 10**7, integer=True)
    min_tracks = check_range("min_tracks", min_tracks, 3, 10**6, integer=True)
    cand = _check_indices(cand, tracks.xy.shape[1], "cand")
    try:        # a seed as NumPy's generators take it (a whole number >= 0, None, a Generator, a SeedSequence ...)
        if isinstance(seed, (bool, np.bool_)):
            raise TypeError
        rng = np.random.default_rng(seed)
    except (TypeError, ValueError):
        raise InputError(f"seed must be what numpy.random.default_rng takes (a whole number >= 0, None, a "
                         f"Generator), got {seed!r}") from None
    xy, start, far = tracks.xy, tracks.start, tracks.excursion
    parts: list[Part] = []
    left = cand
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
            (u, v), (p, q) = start[s[1]] - start[s[0]], start[s[2]] - start[s[0]]
            if abs(u * q - v * p) < 50:  # twice the triangle's area
                continue
            A, seg, _, _ = _chain(xy, s)
            r = _residuals(xy, A, seg, left)
            inl = ~np.isnan(r) & (r < tol)
            score = far[left][inl].sum()
            if best is None or score > best[0]:
                best = (score, inl)
        if best is None or best[1].sum() < min_tracks:
            break
        inl = best[1]
        for _ in range(2):
            A, seg, _, _ = _chain(xy, left[inl])
            r = _residuals(xy, A, seg, left)
            new = ~np.isnan(r) & (r < tol)
            if new.sum() < min_tracks:
                break
            inl = new
        A, seg, kind = _part_motion(xy, left[inl])
        parts.append(Part(left[inl], A, seg, float(np.quantile(far[left[inl]], MOTION_QUANTILE)), kind))
        left = left[~inl]
    parts.sort(key=lambda p: -p.motion * np.sqrt(len(p.tracks)))
    return parts
