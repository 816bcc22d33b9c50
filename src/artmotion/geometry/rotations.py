"""3-D rotations: quaternions (``x, y, z, w`` order, as SciPy), matrices and axis-angle."""

from __future__ import annotations

import numpy as np

from artmotion.errors import InputError, check_range, float_array


def _rotation():
    # scipy.spatial costs ~0.4 s to import: only when a rotation is asked for
    from scipy.spatial.transform import Rotation

    return Rotation


def quat_to_matrix(q, *, tol: float = 1e-3) -> np.ndarray:
    """Rotation matrix (``(..., 3, 3)``) from unit quaternions ``(..., 4)`` in ``x, y, z, w`` order.

    Raises :class:`InputError` if a quaternion's norm differs from 1 by more than ``tol``.
    """
    _check_tol(tol)
    q = float_array(q, "quaternions")
    if q.ndim < 1 or q.shape[-1] != 4:
        raise InputError(f"quaternions must be (..., 4) arrays (x, y, z, w), got shape {q.shape}")
    norms = np.linalg.norm(q, axis=-1)
    if np.any(~np.isfinite(norms)) or np.any(np.abs(norms - 1.0) > tol):
        bad = int(np.argmax(np.abs(np.nan_to_num(norms, nan=np.inf) - 1.0)))
        raise InputError(f"non-unit quaternion (norm {np.ravel(norms)[bad]:.4g} at row {bad + 1})")
    return _rotation().from_quat(q.reshape(-1, 4)).as_matrix().reshape(q.shape[:-1] + (3, 3))


def _check_tol(tol) -> None:
    """A tolerance must be a number in (0, 1]: NaN or infinity would accept any matrix."""
    check_range("tol", tol, 0.0, 1.0, lo_open=True)


def check_rotations(R, name: str = "R", tol: float = 1e-3) -> np.ndarray:
    """``R`` as a float array of rotation matrices ``(..., 3, 3)``, else an :class:`InputError`
    (another shape, NaN, a matrix that is not orthonormal to ``tol`` or is a reflection)."""
    return _rotations(R, name, tol)


def _rotations(R, name: str, tol: float, stack: bool = True) -> np.ndarray:
    """``R`` as a float array of rotation matrices, shape ``(3, 3)`` (or ``(..., 3, 3)`` with
    ``stack``), else an :class:`InputError`: another shape, NaN or infinite entries, a matrix that
    is not orthonormal (``R Rᵀ`` differs from the identity by more than ``tol`` in an entry, the
    style of :func:`quat_to_matrix`'s ``tol``) or is a reflection (determinant -1)."""
    _check_tol(tol)
    R = float_array(R, name)
    if not stack and R.ndim > 2:
        raise InputError(f"{name}: one 3x3 matrix, got a stack of shape {R.shape} "
                         "(matrix_to_quat and rotation_angle take stacks)")
    if R.ndim < 2 or R.shape[-2:] != (3, 3) or (not stack and R.ndim != 2):
        raise InputError(f"{name} must be a 3x3 rotation matrix{' or a stack of them (..., 3, 3)' if stack else ''}, "
                         f"got shape {R.shape}")
    if not np.isfinite(R).all():
        raise InputError(f"{name} contains NaN or infinite values")
    err = np.abs(R @ np.swapaxes(R, -1, -2) - np.eye(3)).max(axis=(-2, -1))
    det = np.linalg.det(R)
    bad = (err > tol) | (det <= 0.0)
    if np.any(bad):
        k = int(np.argmax(np.ravel(bad)))
        where = f" (matrix {k + 1})" if R.ndim > 2 else ""
        e, d = float(np.ravel(err)[k]), float(np.ravel(det)[k])
        why = (f"R Rᵀ differs from the identity by {e:.4g} (tolerance {tol:g})" if e > tol
               else f"its determinant is {d:.4g} (a reflection)")
        raise InputError(f"{name} is not a rotation matrix{where}: {why}")
    return R


def matrix_to_quat(R, *, tol: float = 1e-3) -> np.ndarray:
    """Unit quaternions ``(..., 4)`` (``x, y, z, w``) of rotation matrices ``(..., 3, 3)``.

    Raises :class:`InputError` for another shape, NaN, or a matrix that is not a rotation
    (orthonormal to ``tol``, determinant +1).
    """
    R = _rotations(R, "R", tol)
    return _rotation().from_matrix(R.reshape(-1, 3, 3)).as_quat().reshape(R.shape[:-2] + (4,))


def _no_direction(name: str, x: np.ndarray, norm: float, got) -> InputError:
    """The error for a vector ``x`` (of length ``norm``) that cannot be normalised."""
    return InputError(f"{name} must be a non-zero vector (a zero vector has no direction), got {got}" if not np.any(x)
                      else f"{name} is too {'short' if norm == 0.0 else 'long'} to normalise, got {got}")


def _unit_axis(axis) -> np.ndarray:
    """``axis`` (a finite, non-zero 3-vector) divided by its length, else an :class:`InputError`."""
    axis = float_array(axis, "axis")
    if axis.shape != (3,):
        raise InputError(f"axis must be a 3-vector, got shape {axis.shape}")
    if not np.isfinite(axis).all():
        raise InputError(f"axis contains NaN or infinite values, got {axis.tolist()}")
    norm = np.linalg.norm(axis)
    if not 0.0 < norm < np.inf:
        raise _no_direction("axis", axis, float(norm), axis.tolist())
    return axis / norm


def axis_angle_to_matrix(axis, angle) -> np.ndarray:
    """Rodrigues' formula: rotation by ``angle`` (radians) about ``axis`` (a 3-vector of any
    non-zero length). ``angle`` may be an array: one matrix per angle, shape ``angle.shape + (3, 3)``.
    Raises :class:`InputError` for a zero or non-finite axis or a non-finite angle."""
    axis = _unit_axis(axis)
    angle = float_array(angle, "angle")
    if not np.isfinite(angle).all():
        raise InputError("angle contains NaN or infinite values")
    return _rotation().from_rotvec(axis * angle[..., None]).as_matrix()


def matrix_to_axis_angle(R, *, tol: float = 1e-3) -> tuple[np.ndarray, float]:
    """Unit axis and angle in ``[0, pi]`` of one rotation matrix ``(3, 3)`` (axis ``[0, 0, 1]`` for
    identity). Raises :class:`InputError` for another shape (a stack too: use :func:`matrix_to_quat`
    or :func:`rotation_angle` for those), NaN, or a matrix that is not a rotation (to ``tol``)."""
    R = _rotations(R, "R", tol, stack=False)
    rv = _rotation().from_matrix(R).as_rotvec()
    angle = float(np.linalg.norm(rv))
    axis = rv / angle if angle > 1e-12 else np.array([0.0, 0.0, 1.0])
    return axis, angle


def rotation_angle(R, *, tol: float = 1e-3) -> np.ndarray:
    """Angle of rotation(s) ``(..., 3, 3)`` in radians, from the trace (robust to round-off).
    Raises :class:`InputError` for another shape, NaN, or a matrix that is not a rotation (to ``tol``)."""
    R = _rotations(R, "R", tol)
    c = (np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0
    return np.arccos(np.clip(c, -1.0, 1.0))


def angle_between(u, v) -> np.ndarray:
    """Angle in radians between vectors ``u`` and ``v`` (broadcasting over leading axes).
    Raises :class:`InputError` for vectors of different lengths, NaN, or a zero vector (it has
    no direction)."""
    u = float_array(u, "u")
    v = float_array(v, "v")
    if u.ndim == 0 or v.ndim == 0 or u.shape[-1] != v.shape[-1] or u.shape[-1] == 0:
        raise InputError(f"u and v must be vectors of the same length, got shapes {u.shape} and {v.shape}")
    nu = np.linalg.norm(u, axis=-1)
    nv = np.linalg.norm(v, axis=-1)
    for name, x, n in (("u", u, nu), ("v", v, nv)):
        if not np.isfinite(x).all():
            raise InputError(f"{name} contains NaN or infinite values")
        bad = ~((n > 0.0) & (n < np.inf))          # zero, or too short or too long for its length
        if np.any(bad):
            k = int(np.argmax(np.ravel(bad)))
            row = x.reshape(-1, x.shape[-1])[k]
            got = x.tolist() if x.ndim == 1 else f"row {k + 1}: {row.tolist()}"
            raise _no_direction(name, row, float(np.ravel(n)[k]), got)
    cos = np.sum(u * v, axis=-1) / (nu * nv)
    return np.arccos(np.clip(cos, -1.0, 1.0))
