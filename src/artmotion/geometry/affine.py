"""2x3 affine maps of the image plane (``x' = A[:, :2] x + A[:, 2]``), one or a stack ``(..., 2, 3)``."""

from __future__ import annotations

import numpy as np

__all__ = ["IDENTITY", "apply", "compose", "invert"]

IDENTITY = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
IDENTITY.setflags(write=False)


def apply(A: np.ndarray, X: np.ndarray) -> np.ndarray:
    """``A`` applied to points ``X`` (``(..., 2)``; stacks broadcast)."""
    return np.einsum("...ij,...j->...i", A[..., :2], X) + A[..., 2]


def compose(D: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``D`` after ``A``."""
    L = D[..., :2]
    return np.concatenate([L @ A[..., :2], (L @ A[..., 2:]) + D[..., 2:]], axis=-1)


def invert(A: np.ndarray) -> np.ndarray:
    """The inverse map(s) of ``A``."""
    Li = np.linalg.inv(A[..., :2])
    return np.concatenate([Li, -(Li @ A[..., 2:])], axis=-1)
