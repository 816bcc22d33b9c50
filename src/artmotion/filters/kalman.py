"""A small, fast linear Kalman filter with filterpy's attribute names.

filterpy's ``KalmanFilter`` is general but slow for the thousands of tiny filters this project
runs (one per track, per angle, per articulation model); this one keeps the same names
(``x, P, F, Q, H, R``) and adds the innovation log-likelihood that model selection needs (Eq. 4.16).
"""

from __future__ import annotations

import math

import numpy as np

from artmotion.errors import InputError, float_array

_LOG2PI = math.log(2.0 * math.pi)


def _matrix(name: str, value, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a float array of ``shape`` with finite entries, else an :class:`InputError`."""
    a = float_array(value, f"Kalman filter: {name}").copy()
    if a.shape != shape:
        raise InputError(f"Kalman filter: {name} must have shape {shape}"
                         f"{' for a state of ' + str(shape[1]) if len(shape) == 2 else ''}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError(f"Kalman filter: {name} contains NaN or infinite values")
    return a


def _covariance(name: str, value, n: int) -> np.ndarray:
    """An ``n x n`` covariance: finite, with a non-negative diagonal (variances)."""
    a = _matrix(name, value, (n, n))
    if np.any(np.diagonal(a) < 0.0):
        raise InputError(f"Kalman filter: {name} has a negative variance on its diagonal")
    return a


def gaussian_loglik(y: np.ndarray, S: np.ndarray) -> float:
    """``log N(y; 0, S)`` for an innovation ``y`` with covariance ``S``."""
    y = np.atleast_1d(y)
    S = np.atleast_2d(S)
    if S.shape == (1, 1):
        s = float(S[0, 0])
        return -0.5 * (_LOG2PI + math.log(s) + float(y[0]) ** 2 / s)
    L = np.linalg.cholesky(S)
    z = np.linalg.solve(L, y)
    return float(-0.5 * (len(y) * _LOG2PI + 2.0 * np.log(np.diag(L)).sum() + z @ z))


class KalmanFilter:
    """Linear Kalman filter ``x' = F x + w, w ~ N(0, Q)``; ``z = H x + v, v ~ N(0, R)``.

    After :meth:`update`, ``y`` is the innovation, ``S`` its covariance and ``log_likelihood``
    the log-density of the observation under the prediction.
    """

    def __init__(self, x, P, F, Q, H, R):
        self.x = float_array(x, "Kalman filter: x").reshape(-1).copy()
        n = len(self.x)
        if n == 0 or not np.all(np.isfinite(self.x)):
            raise InputError("Kalman filter: x must be a non-empty state of finite numbers")
        self.P = _covariance("P", P, n)
        self.F = _matrix("F", F, (n, n))
        self.Q = _covariance("Q", Q, n)
        H = np.atleast_2d(np.asarray(H, dtype=float))
        if H.ndim != 2 or H.shape[1] != n or H.shape[0] == 0:
            raise InputError(f"Kalman filter: H must have shape (m, {n}) for a state of {n}, got {H.shape}")
        self.H = _matrix("H", H, H.shape)
        self.R = _covariance("R", np.atleast_2d(np.asarray(R, dtype=float)), H.shape[0])
        self.y = np.zeros(self.H.shape[0])
        self.S = np.eye(self.H.shape[0])
        self.log_likelihood = 0.0

    @property
    def dim_x(self) -> int:
        return self.x.shape[0]

    def predict(self, F=None, Q=None) -> np.ndarray:
        F = self.F if F is None else F
        Q = self.Q if Q is None else Q
        try:
            x = F @ self.x
            P = F @ self.P @ F.T + Q
            if P.shape != self.P.shape:
                raise ValueError("shape")
        except ValueError:
            self._check_state()
            n = self.dim_x
            raise InputError(f"Kalman filter: F and Q must have shape {(n, n)} for a state of {n}, "
                             f"got {np.shape(F)} and {np.shape(Q)}") from None
        self.x, self.P = x, P
        return self.x

    def update(self, z, R=None, H=None) -> float:
        """Fuse measurement ``z``; ``R`` may vary per call (e.g. a GP's predicted variance, Eq. 3.7).

        Returns the innovation log-likelihood.
        """
        H, R, z = self._measurement(z, R, H)
        try:
            y = z - H @ self.x
            PHt = self.P @ H.T
            S = H @ PHt + R
            K = np.linalg.solve(S.T, PHt.T).T
            ll = gaussian_loglik(y, S)
        except (ValueError, np.linalg.LinAlgError) as e:
            self._check_state()
            raise InputError(f"Kalman filter: the innovation covariance is not positive definite ({e})") from None
        self.y, self.S = y, S
        self.x = self.x + K @ self.y
        I_KH = np.eye(self.dim_x) - K @ H
        self.P = I_KH @ self.P @ I_KH.T + K @ R @ K.T  # Joseph form: stays symmetric positive
        self.log_likelihood = ll
        return self.log_likelihood

    def _measurement(self, z, R, H) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``H``, ``R`` and ``z`` of an update, checked against each other: ``z`` has one finite
        value per row of ``H``, ``R`` is that square with non-negative variances."""
        if H is None:
            H = self.H
        else:
            H = np.atleast_2d(np.asarray(H, dtype=float))
            if H.ndim != 2 or H.shape[1] != self.dim_x:
                raise InputError(f"Kalman filter: H must have shape (m, {self.dim_x}) for a state of "
                                 f"{self.dim_x}, got {H.shape}")
        m = H.shape[0]
        if R is None:
            R = self.R
        else:
            R = np.atleast_2d(np.asarray(R, dtype=float))
            if R.shape != (m, m):
                raise InputError(f"Kalman filter: R must have shape {(m, m)} for {m} measured value(s), got {R.shape}")
            if m == 1:
                if not R[0, 0] >= 0.0:
                    raise InputError(f"Kalman filter: R must be a non-negative variance, got {R[0, 0]:g}")
            elif not np.all(np.diagonal(R) >= 0.0):
                raise InputError("Kalman filter: R has a negative or NaN variance on its diagonal")
        z = np.atleast_1d(np.asarray(z, dtype=float))
        if z.shape != (m,):
            raise InputError(f"Kalman filter: z must hold {m} value{'s' if m != 1 else ''} (the rows of H), "
                             f"got shape {z.shape}")
        if not np.all(np.isfinite(z)):
            raise InputError("Kalman filter: z contains NaN or infinite values")
        return H, R, z

    def _check_state(self) -> None:
        """An :class:`InputError` naming ``x``, ``P`` or ``R`` if one of them has a shape that does
        not fit the others (they are attributes: a caller may have replaced them)."""
        n = self.dim_x if self.x.ndim == 1 else -1
        if n < 1:
            raise InputError(f"Kalman filter: x must be a vector, got shape {self.x.shape}")
        for name in ("P", "F", "Q"):
            if np.shape(getattr(self, name)) != (n, n):
                raise InputError(f"Kalman filter: {name} must have shape {(n, n)} for a state of {n}, "
                                 f"got {np.shape(getattr(self, name))}")
        if self.H.ndim != 2 or self.H.shape[1] != n:
            raise InputError(f"Kalman filter: H must have shape (m, {n}) for a state of {n}, got {self.H.shape}")
        m = self.H.shape[0]
        if np.shape(self.R) != (m, m):
            raise InputError(f"Kalman filter: R must have shape {(m, m)} for {m} measured value(s), got {np.shape(self.R)}")

    def innovation(self, z, R=None, H=None) -> tuple[np.ndarray, np.ndarray]:
        """Innovation and its covariance for ``z`` without changing the state (for gating)."""
        H, R, z = self._measurement(z, R, H)
        try:
            y = z - H @ self.x
            return y, H @ self.P @ H.T + R
        except ValueError:
            self._check_state()
            raise
