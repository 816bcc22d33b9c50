"""The joint of a part seen on video: its image motion lifted to 3-D, classified as for logs.

A part's image motion is one affine map per frame (:func:`~.segment.factorise_motion`). Under weak
perspective a rigid motion ``(R, T)`` of a (nearly) planar part maps its image by
``x' = s B x + b``, where ``B`` is the top-left 2x2 block of ``R`` and ``s`` the change of scale
(distance). ``B``'s larger singular value is 1, so ``s`` is the larger singular value of the linear
part and ``R`` is ``B`` completed to a rotation (up to the mirror ambiguity of weak perspective,
resolved by continuity from frame to frame). The reference is the frame where the part looks
largest (least foreshortened), taken as fronto-parallel: then a lid turning about a hinge in the
image plane lifts to points on circles whatever its true starting tilt, and a part turning about
an axis towards the camera to circles in the image plane. Depth from the change of scale needs the
focal length (``focal``, px; default: a 60-degree horizontal field of view).

Points of the part, lifted to 3-D (in pixels at the reference distance), are classified by the
same online model choice as trajectories from logs (:func:`~artmotion.articulation.online.estimate_online`),
one track per point, and their posteriors pooled (:func:`classify_part`).
What cannot be recovered without depth: the side towards which a lid tilts (mirror ambiguity),
and a hinge seen exactly edge-on, whose points move along image lines like a drawer's but shrink
to its line (foreshortening; the lift tells the two apart only through that shrinking).
"""

from __future__ import annotations

import math

import numpy as np

from artmotion.articulation.online import estimate_online
from artmotion.articulation.video.segment import Part, check_part
from artmotion.articulation.video.tracks import PointTracks
from artmotion.errors import InputError, check_range, float_array
from artmotion.geometry.affine import apply, invert

__all__ = ["MAX_FOCAL", "TEMPERATURE", "plane_rectifier", "lift_part", "classify_part"]

#: the largest focal length (pixels) the lift takes: the range the command line takes
MAX_FOCAL = 1e7

#: Algorithm 1's temperature ``T`` for a video's lifted point tracks: each track's ``n`` samples
#: count as ``T n / tau`` (``tau`` their residuals' autocorrelation time), so 1 is the plain count of
#: effectively independent samples. The logs' 0.25 (calibrated on marker trajectories) left every
#: point of the pliers' turning plate near a tie (a KLT track's smooth drift gives ``tau`` of 21-27
#: frames: 221 samples weighed as 2). Within one case of the best of 0.25-4 on every
#: leave-one-video-out fold (docs/articulation_video.md)
TEMPERATURE = 1.0


def _complete(B: np.ndarray, prev: np.ndarray | None) -> np.ndarray:
    """A rotation whose top-left block is ``B`` (singular values clipped to [0, 1]), the mirror
    choice closer to ``prev``."""
    U, S, Vt = np.linalg.svd(B)
    B = U @ np.diag(np.clip(S, 0.0, 1.0)) @ Vt
    r13 = math.sqrt(max(0.0, 1.0 - B[0, 0] ** 2 - B[0, 1] ** 2))
    r23 = math.sqrt(max(0.0, 1.0 - B[1, 0] ** 2 - B[1, 1] ** 2))
    best = None
    for s1, s2 in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        r1 = np.array([B[0, 0], B[0, 1], s1 * r13])
        r2 = np.array([B[1, 0], B[1, 1], s2 * r23])
        err = abs(r1 @ r2)
        R = np.vstack([r1, r2, np.cross(r1, r2)])
        key = (round(err, 6), 0.0 if prev is None else float(np.linalg.norm(R - prev)))
        if best is None or key < best[0]:
            best = (key, R)
    assert best is not None
    return best[1]


def plane_rectifier(L: np.ndarray) -> np.ndarray | None:
    """``K`` (det 1) with ``K^-1 L_t K`` a scaled rotation for every linear part ``L_t`` (2x2), or
    ``None``. A part turning in its own plane about the plane's normal (pliers on a table seen from
    above at a slant) maps by ``L_t = K R_t K^-1``: the ellipse ``S = K K^T`` (the image of a circle
    in that plane) is invariant, ``L_t S L_t^T = S`` up to scale; solved linearly over all frames,
    and accepted when it is unique (one null direction) and an ellipse (positive definite)."""
    L = float_array(L, "L")
    if L.ndim != 3 or L.shape[1:] != (2, 2) or not len(L):
        raise InputError(f"L must be linear maps of shape (frames, 2, 2), got shape {L.shape}")
    if not np.isfinite(L).all():
        raise InputError("L must be finite maps")
    rows = []
    for M in L:
        M = M / math.sqrt(abs(np.linalg.det(M)) or 1.0)
        a, b, c, d = M.ravel()
        # entries (0,0), (0,1), (1,1) of M S M^T - S in the unknowns (S00, S01, S11)
        rows.append([a * a - 1, 2 * a * b, b * b])
        rows.append([a * c, a * d + b * c - 1, b * d])
        rows.append([c * c, 2 * c * d, d * d - 1])
    _, sv, Vt = np.linalg.svd(np.asarray(rows))
    if sv[1] <= 0 or sv[2] > 0.1 * sv[1]:
        return None
    s00, s01, s11 = Vt[2] * np.sign(Vt[2][0] or 1.0)
    S = np.array([[s00, s01], [s01, s11]])
    if np.linalg.eigvalsh(S)[0] <= 0.05 * np.linalg.eigvalsh(S)[1]:
        return None
    K = np.linalg.cholesky(S)
    return K / math.sqrt(np.linalg.det(K))


def _part_points(tracks: PointTracks, part: Part) -> np.ndarray:
    """The part's points in its frame-0 coordinates: each track's first position carried there."""
    return apply(invert(part.A[tracks.first[part.tracks]]), tracks.start[part.tracks])


def _focal(focal, tracks: PointTracks) -> float:
    """The focal length given (checked), or a 60-degree horizontal field of view's."""
    if focal is not None:
        return float(check_range("focal", focal, 0.0, MAX_FOCAL, lo_open=True))
    return tracks.width / (2 * math.tan(math.radians(30)))


def lift_part(tracks: PointTracks, part: Part, focal: float | None = None):
    """Reference frame ``r``, frames used, and the part's points lifted to 3-D at each of them:
    ``(r, frames, P)`` with ``P`` of shape ``(len(frames), n_points, 3)`` (px at the reference
    distance; x right, y down, z away from the camera)."""
    part = check_part(tracks, part)
    return _lift(tracks, part, _focal(focal, tracks))


def _lift(tracks: PointTracks, part: Part, focal: float):
    """:func:`lift_part` of checked arguments."""
    used = np.flatnonzero(part.segment >= 0)
    A = part.A
    dets = np.abs(np.linalg.det(A[used, :, :2]))
    r = int(used[np.argmax(dets)])
    ref = apply(A[r], _part_points(tracks, part))   # the part's points in the reference frame
    centre = ref.mean(axis=0)
    pp = np.array([tracks.width / 2.0, tracks.height / 2.0])
    Ar_inv = invert(A[r])
    L = A[used, :, :2] @ Ar_inv[:, :2]  # linear parts, reference -> f
    K = plane_rectifier(L)
    Ki = np.eye(2) if K is None else np.linalg.inv(K)
    p = np.hstack([(ref - centre) @ Ki.T, np.zeros((len(ref), 1))])
    out = []
    R_prev = None
    for f, M in zip(used, L):
        M = Ki @ M @ (np.eye(2) if K is None else K)
        c = apply(A[f], apply(Ar_inv, centre))
        s = float(np.linalg.svd(M, compute_uv=False)[0])
        R = _complete(M / s, R_prev)
        R_prev = R
        C = np.array([*((c - pp) / s + pp), focal * (1.0 / s - 1.0)])
        out.append(p @ R.T + C)
    return r, used, np.asarray(out)


def classify_part(tracks: PointTracks, part: Part, focal: float | None = None,
                  radius_range: tuple[float, float] | None = None, temperature: float = TEMPERATURE,
                  **choice) -> dict:
    """Joint of ``part`` relative to the static scene: the online model choice on the lifted track
    of every point of the part, pooled. ``radius_range`` (px) defaults to 2%-100% of the image
    diagonal (a hinge's radius, as the logs' 5 cm-1 m); ``temperature``: Algorithm 1's, see
    :data:`TEMPERATURE`; ``choice``: the other options of
    :class:`~artmotion.articulation.online.OnlineEstimator`.

    All the points of a rigid part follow one joint, but each lifted track is noisy in its own way
    (depth comes from the change of scale), and the answer of any single point — e.g. the one
    that moves furthest — can flip with a tiny change of the data. The points' posteriors are
    averaged (a linear opinion pool): ``p(m) = sum_k w_k p_k(m)``, with ``w_k`` the point's image
    motion over the part's total. (A weighted product of them, the logarithmic pool, lets one
    point that gives a model a probability of 1e-200 veto all the others.) The axis and range
    come from the point with the largest ``w_k p_k(m)`` for the chosen model."""
    part = check_part(tracks, part)
    diag = math.hypot(tracks.width, tracks.height)
    radius_range = radius_range or (0.02 * diag, 1.0 * diag)
    r, used, P = _lift(tracks, part, _focal(focal, tracks))
    img = apply(part.A[used][:, None], _part_points(tracks, part)[None])
    span = np.linalg.norm(img - img[:1], axis=2).max(axis=0)   # each point's motion in the image
    w = span / max(float(span.sum()), 1e-12)
    results = [estimate_online(P[:, k], used / tracks.fps, radius_range=radius_range, temperature=temperature, **choice)
               for k in range(P.shape[1])]
    names = list(results[0].probabilities)
    probs = np.array([[res.probabilities.get(m, 0.0) for m in names] for res in results])
    pooled = w @ probs
    j = int(np.argmax(pooled))
    model = names[j]
    k = int(np.argmax(w * probs[:, j]))
    fit = results[k].fits[model]        # that point's fit of the chosen model
    cfg = fit.configuration(3)
    motion = np.asarray(fit.motion(P[:, k]), dtype=float)
    out = {"model": model, "confidence": float(pooled[j]),
           "probabilities": {m: float(x) for m, x in zip(names, pooled)}, "points": int(len(part.tracks)),
           "frames": [int(used[0]), int(used[-1])], "reference_frame": r}
    if model == "revolute" and "axis" in cfg:
        axis = np.asarray(cfg["axis"], dtype=float)
        c3 = np.asarray(cfg["centre"], dtype=float)
        out["axis"] = {"point": [float(c3[0]), float(c3[1])], "direction": [float(v) for v in axis / np.linalg.norm(axis)],
                       "towards_camera": bool(abs(axis[2]) / np.linalg.norm(axis) > math.cos(math.radians(30)))}
        ang = motion[:, 0] if motion.size else np.zeros(1)
        out["range"] = {"degrees": float(np.degrees(np.nanmax(ang) - np.nanmin(ang)))}
    elif model == "prismatic" and "direction" in cfg:
        d = np.asarray(cfg["direction"], dtype=float)
        d = d / np.linalg.norm(d)
        out["axis"] = {"point": [float(v) for v in np.asarray(cfg["origin"])[:2]],
                       "direction": [float(v) for v in d]}
        q = motion[:, 0] if motion.size else np.zeros(1)
        out["range"] = {"pixels": float(np.nanmax(q) - np.nanmin(q))}
    else:
        out["axis"] = None
        out["range"] = None
    out["motion_px"] = part.motion
    out["image_motion"] = part.kind
    return out
