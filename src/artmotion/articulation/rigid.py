"""Rigid-body articulation classification, Section 4.3.2.

Points ``p_i`` of one rigid body tracked in 3-D over ``F`` frames give ``W = M S`` (Eq. 4.3-4.4):
``W`` is ``3F x N`` (all u rows, then all v rows, then all w rows), ``M`` stacks the rows of
``[R_f | t_f]`` and ``S`` the homogeneous points. The SVD gives ``M^ = U S^1/2`` and
``S^ = S^1/2 V^T`` (Eq. 4.5-4.6), defined up to an invertible ``A`` (4x4); the metric upgrade finds
``A`` from the constraints that every frame's rows ``i_f, j_f, k_f`` are orthonormal (Eq. 4.7,
here in its homogeneous form: ``Q = A_R A_R^T`` is solved linearly, then factored) and that the last
row of ``S`` is all ones.

From the recovered motions, relative to the first frame (``x^{t} = R x^{t0} + T``, Eq. 4.8), a body is

* static (4.3.2.5): ``R = I`` and ``T = 0`` at every frame (within noise);
* prismatic (4.3.2.1): ``R = I``, translations along one line;
* revolute (4.3.2.2): one fixed rotation axis and a line of fixed points ``(R - I) c + T = 0``
  (the translation is the one the rotation about that line implies at every frame);
* plane constrained (4.3.2.3): rotation only about one normal ``n`` and ``T . n = 0`` after
  accounting for the rotation (``(R x_0 + T - x_0) . n = 0``);
* general (4.3.2.4, reported as ``rigid``): anything else.

6-D pose tracks (position + unit quaternion) skip the factorisation: the poses are the motions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from artmotion.articulation.models import MAX_COORD, _orthonormal_to
from artmotion.errors import InputError, check_range, float_array
from artmotion.geometry.rotations import check_rotations, quat_to_matrix

__all__ = ["factorize", "classify_motion", "classify_points", "classify_poses", "RigidResult", "stack_w"]

#: the factorisation methods of :func:`factorize`
METHODS = ("auto", "orthonormal", "anchor")


def stack_w(tracks: np.ndarray) -> np.ndarray:
    """``W`` of Eq. 4.3 from ``tracks`` of shape ``(F, N, 3)``: u rows, v rows, w rows."""
    tracks = np.asarray(tracks, dtype=float)
    if tracks.ndim != 3 or tracks.shape[2] != 3:
        raise InputError(f"rigid-body tracks must have shape (frames, points, 3), got {tracks.shape}")
    return np.concatenate([tracks[:, :, 0], tracks[:, :, 1], tracks[:, :, 2]], axis=0)


def _sym_row(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Coefficients of ``a Q b^T`` in the 10 unique entries of a symmetric 4x4 ``Q``."""
    out = []
    for i in range(4):
        for j in range(i, 4):
            out.append(a[i] * b[j] + (a[j] * b[i] if i != j else 0.0))
    return np.array(out)


def _sym_from(vec: np.ndarray) -> np.ndarray:
    Q = np.zeros((4, 4))
    k = 0
    for i in range(4):
        for j in range(i, 4):
            Q[i, j] = Q[j, i] = vec[k]
            k += 1
    return Q


def factorize(tracks: np.ndarray, method: str = "auto") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rotations ``(F, 3, 3)``, translations ``(F, 3)`` and shape ``(N, 3)`` with ``x_fi = R_f s_i + t_f``.

    ``tracks``: ``(F, N, 3)`` with ``N >= 4`` points not all in one plane for a unique answer
    (with 3 points the fourth is added as the normal to their plane, which a rigid body carries
    along). The answer is unique up to the choice of the body frame (a rotation and an origin).
    ``method``: ``orthonormal`` (Eq. 4.7), ``anchor`` (first frame fixes the gauge) or ``auto``
    (Eq. 4.7 when its constraints determine ``Q``, else anchor).
    """
    if method not in METHODS:
        raise InputError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    tracks = float_array(tracks, "rigid-body tracks")
    if tracks.ndim != 3 or tracks.shape[2] != 3 or tracks.shape[1] < 3 or tracks.shape[0] < 2:
        raise InputError(f"need at least 3 points over 2 frames as (frames, points, 3), got {tracks.shape}")
    if not np.all(np.isfinite(tracks)):
        raise InputError("rigid-body tracks contain NaN")
    if float(np.abs(tracks).max()) > MAX_COORD:
        raise InputError(f"rigid-body tracks must be coordinates of magnitude at most {MAX_COORD:g}")
    first = tracks[0] - tracks[0].mean(axis=0)
    sv0 = np.linalg.svd(first, compute_uv=False)
    if not sv0[1] > max(1e-9 * float(sv0[0]), 1e-13 * float(np.abs(tracks[0]).max()), 1e-300):
        raise InputError("the body's points lie on one line (or are one point) in the first frame: "
                         "its rotation cannot be recovered; need 3 points not on one line")
    n_points = tracks.shape[1]
    if tracks.shape[1] == 3:  # a virtual fourth point off the plane of the three
        a, b, c = tracks[:, 0], tracks[:, 1], tracks[:, 2]
        n = np.cross(b - a, c - a)
        scale = np.linalg.norm(b - a, axis=1, keepdims=True)
        n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12) * scale
        tracks = np.concatenate([tracks, ((a + b + c) / 3 + n)[:, None, :]], axis=1)
    F = tracks.shape[0]
    W = stack_w(tracks)
    U, s, Vt = np.linalg.svd(W, full_matrices=False)
    Mh = U[:, :4] * np.sqrt(s[:4])
    Sh = np.sqrt(s[:4])[:, None] * Vt[:4]
    # last row of S must be ones: b S^ = 1
    b, *_ = np.linalg.lstsq(Sh.T, np.ones(Sh.shape[1]), rcond=None)
    # metric constraints on Q = A_R A_R^T (Eq. 4.7 in homogeneous form)
    rows, rhs = [], []
    for f in range(F):
        r = [Mh[f], Mh[F + f], Mh[2 * F + f]]
        for i in range(3):
            for j in range(i, 3):
                rows.append(_sym_row(r[i], r[j]))
                rhs.append(1.0 if i == j else 0.0)
    # b is orthogonal to A_R's columns: Q b = 0 (four more equations, weighted like the rest)
    for k in range(4):
        e = np.zeros(4)
        e[k] = 1.0
        rows.append(_sym_row(e, b) * 0.5)
        rhs.append(0.0)
    C = np.array(rows)
    sv = np.linalg.svd(C, compute_uv=False)
    well_posed = sv[-1] > 1e-3 * sv[0]
    if method == "orthonormal" or (method == "auto" and well_posed):
        q, *_ = np.linalg.lstsq(C, np.array(rhs), rcond=None)
        Q = _sym_from(q)
        w, V = np.linalg.eigh(Q)
        order = np.argsort(w)[::-1][:3]
        A_R = V[:, order] * np.sqrt(np.maximum(w[order], 1e-12))
        A_R = A_R - np.outer(b, b @ A_R) / (b @ b)  # enforce b A_R = 0
        a_t = b / (b @ b)
        A = np.column_stack([A_R, a_t])
    else:
        # Degenerate motion (no rotation, or rotation about one axis only): the orthonormality
        # constraints leave Q undetermined. 3-D tracks are metric already, so fix the gauge by
        # the first frame instead: M_0 A = [I | 0] and b A = e_4, i.e. A = [M^_0; b]^-1.
        try:
            A = np.linalg.inv(np.vstack([Mh[[0, F, 2 * F]], b]))
        except np.linalg.LinAlgError:  # a degenerate gauge: the first frame's points serve as shape
            A = None
    shape = None
    if A is not None and np.all(np.isfinite(A)):
        S = np.linalg.solve(A, Sh)
        shape = (S[:3] / S[3]).T
    if shape is None or not np.all(np.isfinite(shape)):
        shape = tracks[0].copy()
    # Every frame's motion from the factorised shape by orthogonal Procrustes (projects M's rows
    # onto SO(3)); if the factorisation was degenerate the first frame's points serve as shape.
    best = None
    for cand in (shape, tracks[0]):
        R, t = _procrustes(cand, tracks)
        rms = float(np.sqrt(np.mean((tracks - (np.einsum("fij,nj->fni", R, cand) + t[:, None, :])) ** 2)))
        if best is None or rms < best[3] - 1e-12:
            best = (R, t, cand, rms)
    assert best is not None  # set by the first candidate
    R, t, shape, _ = best
    return R, t, shape[:n_points]


def _procrustes(shape: np.ndarray, tracks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``R_f, t_f`` minimising ``sum_i |x_fi - R_f s_i - t_f|^2`` for every frame (Kabsch)."""
    mu_s = shape.mean(axis=0)
    mu_x = tracks.mean(axis=1)
    H = np.einsum("ni,fnj->fij", shape - mu_s, tracks - mu_x[:, None, :])
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.einsum("fij,fjk->fik", U, Vt)))
    D = np.zeros_like(H)
    D[:, 0, 0] = 1.0
    D[:, 1, 1] = 1.0
    D[:, 2, 2] = d
    R = np.einsum("fji,fjk,fkl->fil", Vt, D, np.transpose(U, (0, 2, 1)))
    t = mu_x - np.einsum("fij,j->fi", R, mu_s)
    return R, t


@dataclass
class RigidResult:
    model: str  # static | prismatic | revolute | planar | rigid
    configuration: dict
    motion: np.ndarray  # per frame motion variables of the model
    rotations: np.ndarray  # relative to the first frame
    translations: np.ndarray
    residuals: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"model": self.model, "configuration": self.configuration,
                "motion": [list(map(float, np.atleast_1d(m))) for m in self.motion],
                "residuals": self.residuals}


def classify_motion(R: np.ndarray, t: np.ndarray, noise: float = 0.005, size: float = 0.1, centre=None,
                    angular_noise: float | None = None) -> RigidResult:
    """Classify a sequence of rigid motions ``x_f = R_f x_0 + t_f`` (relative to frame 0).

    ``noise``: positional noise (length); ``size``: the body's radius (rms distance of its points
    from their centroid), turning ``noise`` into an angular noise ``noise / size``, unless
    ``angular_noise`` (radians) is given. Tolerances are 5 x those levels (the largest of a few
    hundred Gaussian deviations stays below 4 sigma). ``centre``: the body's centroid in the first
    frame (angular noise moves a point at distance ``d`` from it by ``d`` times the angular noise).
    ``R``: ``(F, 3, 3)`` rotation matrices, ``t``: ``(F, 3)`` translations, finite, ``F >= 1``;
    ``noise``, ``size`` and ``angular_noise``: positive.
    """
    _check_noise_size(noise, size)
    if angular_noise is not None:
        check_range("angular_noise", angular_noise, 0.0, math.inf, lo_open=True, hi_open=True)
    R = float_array(R, "R")
    t = float_array(t, "t")
    if R.ndim != 3 or R.shape[1:] != (3, 3):
        raise InputError(f"R must be an (F, 3, 3) array of rotation matrices, got shape {R.shape}")
    if len(R) < 1:
        raise InputError("R must hold at least one rotation, got none")
    R = check_rotations(R)     # (a scaled or sheared matrix was classified, e.g. 2 I as static)
    if t.shape != (len(R), 3):
        raise InputError(f"t must be an (F, 3) array, one translation per rotation (F = {len(R)}), got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise InputError("t contains NaN or infinite values")
    if centre is None:
        centre = np.zeros(3)
    else:
        centre = float_array(centre, "centre")
        if centre.shape != (3,) or not np.all(np.isfinite(centre)):
            raise InputError(f"centre must be 3 finite numbers (the body's centroid), got {centre.tolist()!r}")
    F = len(R)
    ang_tol = 5.0 * (noise / max(size, noise) if angular_noise is None else angular_noise)
    lin_tol = 5.0 * noise
    rv = Rotation.from_matrix(R).as_rotvec()
    angles = np.linalg.norm(rv, axis=1)
    tn = np.linalg.norm(t, axis=1)
    res = {"max_angle": float(angles.max()), "max_translation": float(tn.max())}
    if angles.max() < ang_tol:
        if tn.max() < lin_tol:
            return RigidResult("static", {}, np.zeros((F, 0)), R, t, res)
        _, sv, Vt = np.linalg.svd(t, full_matrices=False)
        d = Vt[0] if t[-1] @ Vt[0] >= 0 else -Vt[0]
        off = np.linalg.norm(t - np.outer(t @ d, d), axis=1).max()
        res["line_residual"] = float(off)
        if off < lin_tol:
            return RigidResult("prismatic", {"direction": d.tolist()}, (t @ d)[:, None], R, t, res)
        # translation in a plane, no rotation: plane constrained
        if len(Vt) < 3:  # fewer than 3 frames: the full basis has the plane's normal
            Vt = np.linalg.svd(t)[2]
        n = Vt[2]
        res["plane_residual"] = float(np.abs(t @ n).max())
        if res["plane_residual"] < lin_tol:
            return RigidResult("planar", {"normal": n.tolist()}, np.column_stack([t @ Vt[0], t @ Vt[1], np.zeros(F)]), R, t, res)
        return RigidResult("rigid", {}, np.column_stack([t, rv]), R, t, res)
    # a common rotation axis: the rotation vectors lie on one line
    _, sv, Vt = np.linalg.svd(rv, full_matrices=False)
    axis = Vt[0] if rv[np.argmax(angles)] @ Vt[0] >= 0 else -Vt[0]
    off_axis = float(np.linalg.norm(rv - np.outer(rv @ axis, axis), axis=1).max())
    res["off_axis_rotation"] = off_axis
    signed = rv @ axis
    if off_axis < ang_tol:
        # fixed points: (R_f - I) c + t_f = 0 for all f (least squares over frames)
        # c is defined up to the axis direction: regularise by adding axis . c = 0
        RmI = R - np.eye(3)
        Acat = np.vstack([RmI.reshape(3 * F, 3), axis[None, :]])
        bcat = np.concatenate([-t.reshape(3 * F), [0.0]])
        c, *_ = np.linalg.lstsq(Acat, bcat, rcond=None)
        fix = np.linalg.norm(np.einsum("fij,j->fi", RmI, c) + t, axis=1)
        res["fixed_point_residual"] = float(fix.max())
        if fix.max() < lin_tol + ang_tol * np.linalg.norm(c - centre):
            return RigidResult("revolute", {"axis": axis.tolist(), "point": c.tolist()}, signed[:, None], R, t, res)
        # rotation about the normal and translation in the plane: plane constrained (4.3.2.3)
        # the displacement of the axis point c, (R c + t - c), must stay perpendicular to n
        disp = np.einsum("fij,j->fi", R, centre) + t - centre
        res["plane_residual"] = float(np.abs(disp @ axis).max())
        if res["plane_residual"] < lin_tol:
            e1, e2 = _orthonormal_to(axis)
            return RigidResult("planar", {"normal": axis.tolist(), "point": centre.tolist()},
                               np.column_stack([disp @ e1, disp @ e2, signed]), R, t, res)
    return RigidResult("rigid", {}, np.column_stack([t, rv]), R, t, res)


def _relative(R: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Motions taking frame 0's points to frame f: ``R_f R_0^T``, ``t_f - R_f R_0^T t_0``."""
    Rr = np.einsum("fij,kj->fik", R, R[0])
    tr = t - np.einsum("fij,j->fi", Rr, t[0])
    return Rr, tr


def _check_noise_size(noise, size=None) -> None:
    check_range("noise", noise, 0.0, math.inf, lo_open=True, hi_open=True)
    if size is not None:
        check_range("size", size, 0.0, math.inf, lo_open=True, hi_open=True)


#: how far from 1 a unit quaternion's norm may be (as :func:`~artmotion.geometry.rotations.quat_to_matrix`)
QUAT_TOL = 1e-3


def check_poses(positions, quats, min_poses: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """``positions`` ``(F, 3)`` and unit quaternions ``(F, 4)`` as float arrays, checked (shapes,
    as many rows, at least ``min_poses``, finite positions of magnitude at most ``MAX_COORD``, unit
    quaternions); else an :class:`InputError` naming what is wrong."""
    t = float_array(positions, "positions")
    quats = float_array(quats, "quaternions")
    if t.ndim != 2 or t.shape[1] != 3:
        raise InputError(f"positions must be an (F, 3) array, got shape {t.shape}")
    if quats.ndim != 2 or quats.shape[1] != 4:
        raise InputError(f"quaternions must be an (F, 4) array (x, y, z, w), got shape {quats.shape}")
    if len(t) != len(quats):
        raise InputError(f"positions and quaternions must have as many rows, got {len(t)} and {len(quats)}")
    if len(t) < min_poses:
        raise InputError(f"a pose track needs at least {min_poses} poses, got {len(t)}")
    if not np.all(np.isfinite(t)):
        raise InputError("positions contain NaN or infinite values")
    if t.size and float(np.abs(t).max()) > MAX_COORD:
        raise InputError(f"positions must be coordinates of magnitude at most {MAX_COORD:g}")
    norms = np.linalg.norm(quats, axis=1)
    bad = np.flatnonzero(~(np.abs(norms - 1.0) <= QUAT_TOL))     # (NaN norms too)
    if bad.size:
        raise InputError(f"quaternions must be unit quaternions (x, y, z, w; norm 1 within {QUAT_TOL:g}): "
                         f"row {bad[0] + 1} has norm {norms[bad[0]]:.4g}")
    return t, quats


def classify_points(tracks: np.ndarray, noise: float = 0.005, method: str = "auto") -> RigidResult:
    """Factorise ``(F, N, 3)`` point tracks of one body and classify its motion."""
    _check_noise_size(noise)
    R, t, shape = factorize(tracks, method=method)
    Rr, tr = _relative(R, t)
    size = float(np.sqrt(((shape - shape.mean(axis=0)) ** 2).sum(axis=1).mean()))
    out = classify_motion(Rr, tr, noise=noise, size=size, centre=np.asarray(tracks)[0].mean(axis=0))
    rms = float(np.sqrt(np.mean((np.asarray(tracks) - (np.einsum("fij,nj->fni", R, shape) + t[:, None, :])) ** 2)))
    out.residuals["factorisation_rms"] = rms
    return out


def same_side(quats: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(F, 4)``, each turned to the side of the one before (``q`` and ``-q`` are
    one rotation; a log that flips the sign would read as the rounding of values 2 apart)."""
    if len(quats) < 2:
        return quats
    flips = np.concatenate([[False], np.einsum("ij,ij->i", quats[1:], quats[:-1]) < 0])
    return quats * np.where(np.cumsum(flips) % 2, -1.0, 1.0)[:, None]


def pose_noise(positions: np.ndarray, quats: np.ndarray) -> tuple[float, float]:
    """The noise of a pose track, estimated from the track: positional (length) and angular
    (radians) std, from the second differences of the positions and of the orientation (the step
    rotations' differences), whose spread is ``sqrt(6)`` times the noise's where the motion is
    smooth over three samples (a difference-based estimate, as Rice 1984), taken robustly (median
    absolute value / 0.6745) so that the motion's own turns count little. Floors: the rounding of
    values written with few decimals and the float precision of the positions
    (:func:`~artmotion.articulation.online.precision_floor`, as Algorithm 1's: a floor of 1e-9 of
    the positions' magnitude called a 2 cm slide with 0.2 mm noise static once 5e6 m were added to
    its positions). A fixed 5 mm called a drawer written in millimetres 'rigid' (its 1 mm noise
    1,000 times the tolerance's scale)."""
    from artmotion.articulation.online import precision_floor, rounding_std

    t = np.asarray(positions, dtype=float)
    q = same_side(np.asarray(quats, dtype=float))
    floors = (precision_floor(t), max(rounding_std(q), 1e-9))
    if len(t) < 3:
        return floors
    R = Rotation.from_quat(q)
    steps = (R[1:] * R[:-1].inv()).as_rotvec()
    mad = 1.0 / (0.6745 * math.sqrt(6.0))
    pos = float(np.median(np.abs(np.diff(t, n=2, axis=0)))) * mad
    ang = float(np.median(np.abs(np.diff(steps, axis=0)))) * mad
    return max(pos, floors[0]), max(ang, floors[1])


def classify_poses(positions: np.ndarray, quats: np.ndarray, noise: float | None = 0.005, size: float = 0.1,
                   angular_noise: float | None = None) -> RigidResult:
    """Classify a 6-D pose track: positions ``(F, 3)`` and unit quaternions ``(F, 4)`` (x, y, z, w).
    ``noise=None``: the positional and angular noise estimated from the track (:func:`pose_noise`),
    ``angular_noise`` (radians) taking the place of ``noise / size`` when given."""
    if noise is not None:
        _check_noise_size(noise)
    check_range("size", size, 0.0, math.inf, lo_open=True, hi_open=True)
    if angular_noise is not None:
        check_range("angular_noise", angular_noise, 0.0, math.inf, lo_open=True, hi_open=True)
    t, quats = check_poses(positions, quats)
    if noise is None:
        noise, angular_noise = pose_noise(t, quats)
    R = quat_to_matrix(quats)
    Rr, tr = _relative(R, t)
    return classify_motion(Rr, tr, noise=noise, size=size, centre=t[0], angular_noise=angular_noise)
