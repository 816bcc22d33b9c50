"""3-D rotations: quaternions (``x, y, z, w`` order, as SciPy), matrices and axis-angle."""

from __future__ import annotations

import numpy as np

from artmotion.errors import InputError


def _rotation():
    # scipy.spatial costs ~0.4 s to import: only when a rotation is asked for
    from scipy.spatial.transform import Rotation

    return Rotation


def quat_to_matrix(q, *, tol: float = 1e-3) -> np.ndarray:
    """Rotation matrix (``(..., 3, 3)``) from unit quaternions ``(..., 4)`` in ``x, y, z, w`` order.

    Raises :class:`InputError` if a quaternion's norm differs from 1 by more than ``tol``.
    """
    q = np.asarray(q, dtype=float)
    norms = np.linalg.norm(q, axis=-1)
    if np.any(~np.isfinite(norms)) or np.any(np.abs(norms - 1.0) > tol):
        bad = int(np.argmax(np.abs(np.nan_to_num(norms, nan=np.inf) - 1.0)))
        raise InputError(f"non-unit quaternion (norm {np.ravel(norms)[bad]:.4g} at row {bad + 1})")
    return _rotation().from_quat(q.reshape(-1, 4)).as_matrix().reshape(q.shape[:-1] + (3, 3))


def matrix_to_quat(R) -> np.ndarray:
    R = np.asarray(R, dtype=float)
    return _rotation().from_matrix(R.reshape(-1, 3, 3)).as_quat().reshape(R.shape[:-2] + (4,))


def axis_angle_to_matrix(axis, angle) -> np.ndarray:
    """Rodrigues' formula: rotation by ``angle`` (radians) about ``axis`` (any non-zero length)."""
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    angle = np.asarray(angle, dtype=float)
    return _rotation().from_rotvec(axis * angle[..., None]).as_matrix()


def matrix_to_axis_angle(R) -> tuple[np.ndarray, float]:
    """Unit axis and angle in ``[0, pi]`` of a rotation matrix (axis ``[0, 0, 1]`` for identity)."""
    rv = _rotation().from_matrix(np.asarray(R, dtype=float)).as_rotvec()
    angle = float(np.linalg.norm(rv))
    axis = rv / angle if angle > 1e-12 else np.array([0.0, 0.0, 1.0])
    return axis, angle


def rotation_angle(R) -> np.ndarray:
    """Angle of rotation(s) in radians, from the trace (robust to round-off)."""
    R = np.asarray(R, dtype=float)
    c = (np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0
    return np.arccos(np.clip(c, -1.0, 1.0))


def angle_between(u, v) -> np.ndarray:
    """Angle in radians between vectors ``u`` and ``v`` (broadcasting over leading axes)."""
    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    cos = np.sum(u * v, axis=-1) / (np.linalg.norm(u, axis=-1) * np.linalg.norm(v, axis=-1))
    return np.arccos(np.clip(cos, -1.0, 1.0))
