"""Finite-order (Taylor) motion models, Eq. 4.12-4.15, and their block-diagonal use per axis.

The state of one motion variable is ``[q, q', ..., q^(n-1)]``; the n-th derivative is white noise
``eta``. Discretised with step ``dt``: ``x(t+dt) = A x(t) + B eta`` (Eq. 4.13) where
``A = expm(A_c dt)`` has ``dt^k / k!`` on its k-th super-diagonal and
``B = [dt^n/n!, ..., dt^2/2!, dt]^T`` (Eq. 4.14). Order 2 is the constant-velocity model of
Eq. 2.10 and Eq. 3.6.
"""

from __future__ import annotations

import math

import numpy as np

from artmotion.errors import InputError


def taylor_transition(order: int, dt: float) -> np.ndarray:
    """``A`` of Eq. 4.14 for a state of ``order`` entries (``order >= 1``)."""
    if order < 1:
        raise ValueError("order must be >= 1")
    A = np.zeros((order, order))
    for k in range(order):
        A += np.eye(order, k=k) * (dt**k / math.factorial(k))
    return A


def white_noise_input(order: int, dt: float) -> np.ndarray:
    """``B`` of Eq. 4.14 (column of length ``order``): how the n-th derivative enters."""
    if order < 1:
        raise ValueError("order must be >= 1")
    return np.array([[dt ** (order - i) / math.factorial(order - i)] for i in range(order)])


def taylor_model(order: int, dt: float, noise_var: float = 1.0, dims: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``(F, Q)`` for ``dims`` independent axes each following an order-``order`` Taylor model.

    ``Q = B noise_var B^T`` per axis (the discrete white-noise model of Eq. 4.13); the state is
    ordered axis by axis: ``[q_1, q_1', ..., q_2, q_2', ...]`` (as Eq. 2.10).
    """
    if isinstance(dims, bool) or not isinstance(dims, (int, np.integer)) or dims < 1:
        raise InputError(f"dims must be a whole number of axes >= 1, got {dims!r}")
    q = np.atleast_1d(np.asarray(noise_var, dtype=float))
    if q.ndim != 1 or q.size not in (1, dims):
        raise InputError(f"noise variances must be one number or one per axis ({dims}), got {q.size}")
    A = taylor_transition(order, dt)
    B = white_noise_input(order, dt)
    if q.size == 1:
        q = np.repeat(q, dims)
    F = np.kron(np.eye(dims), A)
    Q = np.zeros_like(F)
    for d in range(dims):
        s = slice(d * order, (d + 1) * order)
        Q[s, s] = B @ B.T * q[d]
    return F, Q


def constant_velocity(dt: float, accel_var=1.0, dims: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(F, Q, H)`` of the constant-velocity model with white-noise acceleration (Eq. 2.10, 3.6).

    The state is ``[p_1, v_1, p_2, v_2, ...]``; ``H`` observes the positions.
    """
    F, Q = taylor_model(2, dt, accel_var, dims)
    H = np.kron(np.eye(dims), np.array([[1.0, 0.0]]))
    return F, Q, H
