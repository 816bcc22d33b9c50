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

from artmotion.errors import InputError, check_range, float_array

#: highest Taylor order, and most state entries a model is made for (its ``F`` and ``Q`` are
#: dense: 4096 entries take 128 MB each; order 2**63 or 10**9 axes ended in a MemoryError, order
#: 200 overflowed the factorials)
MAX_ORDER = 20
MAX_STATE = 4096


def _check_order_dt(order, dt) -> int:
    """``order`` as an int (a whole number >= 1) after checking ``dt`` (a finite step >= 0),
    else an :class:`InputError`. ``dt`` itself is used as given (its type keeps the results
    bit for bit)."""
    order = check_range("order (of the Taylor model)", order, 1, MAX_ORDER, integer=True)
    check_range("dt (the time step)", dt.item() if isinstance(dt, np.ndarray) and dt.ndim == 0 else dt,
                0.0, math.inf, hi_open=True)
    return order


def taylor_transition(order: int, dt: float) -> np.ndarray:
    """``A`` of Eq. 4.14 for a state of ``order`` entries (``order >= 1``, ``dt >= 0``)."""
    order = _check_order_dt(order, dt)
    A = np.zeros((order, order))
    for k in range(order):
        A += np.eye(order, k=k) * (dt**k / math.factorial(k))
    return A


def white_noise_input(order: int, dt: float) -> np.ndarray:
    """``B`` of Eq. 4.14 (column of length ``order``): how the n-th derivative enters."""
    order = _check_order_dt(order, dt)
    return np.array([[dt ** (order - i) / math.factorial(order - i)] for i in range(order)])


def taylor_model(order: int, dt: float, noise_var: float = 1.0, dims: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``(F, Q)`` for ``dims`` independent axes each following an order-``order`` Taylor model.

    ``Q = B noise_var B^T`` per axis (the discrete white-noise model of Eq. 4.13); the state is
    ordered axis by axis: ``[q_1, q_1', ..., q_2, q_2', ...]`` (as Eq. 2.10). ``order`` is a whole
    number >= 1, ``dt`` a finite step >= 0, the variances finite and >= 0 (else :class:`InputError`).
    """
    if isinstance(dims, bool) or not isinstance(dims, (int, np.integer)) or dims < 1:
        raise InputError(f"dims must be a whole number of axes >= 1, got {dims!r}")
    order = _check_order_dt(order, dt)
    if dims * order > MAX_STATE:
        raise InputError(f"dims x order must be at most {MAX_STATE} state entries, got {dims} x {order}")
    q = np.atleast_1d(float_array(noise_var, "noise variances"))
    if q.ndim != 1 or q.size not in (1, dims):
        raise InputError(f"noise variances must be one number or one per axis ({dims}), got {q.size}")
    if not (np.isfinite(q).all() and (q >= 0.0).all()):
        bad = q[~(np.isfinite(q) & (q >= 0.0))][0]
        raise InputError(f"noise variances must be finite and >= 0, got {bad:g}")
    try:
        A = taylor_transition(order, dt)
        B = white_noise_input(order, dt)
    except OverflowError:       # (dt**k of a Python float beyond the floats)
        A = B = np.full((order, 1), np.inf)
    if q.size == 1:
        q = np.repeat(q, dims)
    with np.errstate(over="ignore", invalid="ignore"):
        BB = B @ B.T
        if not (np.isfinite(A).all() and np.isfinite(BB * q.max()).all()):     # (dt**k / k! beyond the floats)
            raise InputError(f"the Taylor model of order {order} over dt = {float(dt):g} with these variances does "
                             "not fit in floating point (F or Q overflows): take a smaller step or order")
    F = np.kron(np.eye(dims), A)
    Q = np.zeros_like(F)
    for d in range(dims):
        s = slice(d * order, (d + 1) * order)
        Q[s, s] = BB * q[d]
    return F, Q


def constant_velocity(dt: float, accel_var=1.0, dims: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(F, Q, H)`` of the constant-velocity model with white-noise acceleration (Eq. 2.10, 3.6).

    The state is ``[p_1, v_1, p_2, v_2, ...]``; ``H`` observes the positions.
    """
    F, Q = taylor_model(2, dt, accel_var, dims)
    H = np.kron(np.eye(dims), np.array([[1.0, 0.0]]))
    return F, Q, H
