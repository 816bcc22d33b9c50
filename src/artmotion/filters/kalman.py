"""A small, fast linear Kalman filter with filterpy's attribute names.

filterpy's ``KalmanFilter`` is general but slow for the thousands of tiny filters this project
runs (one per track, per angle, per articulation model); this one keeps the same names
(``x, P, F, Q, H, R``) and adds the innovation log-likelihood that model selection needs (Eq. 4.16).
"""

from __future__ import annotations

import math

import numpy as np

_LOG2PI = math.log(2.0 * math.pi)


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
        self.x = np.asarray(x, dtype=float).reshape(-1).copy()
        self.P = np.array(P, dtype=float)
        self.F = np.array(F, dtype=float)
        self.Q = np.array(Q, dtype=float)
        self.H = np.array(H, dtype=float)
        self.R = np.array(R, dtype=float)
        self.y = np.zeros(self.H.shape[0])
        self.S = np.eye(self.H.shape[0])
        self.log_likelihood = 0.0

    @property
    def dim_x(self) -> int:
        return self.x.shape[0]

    def predict(self, F=None, Q=None) -> np.ndarray:
        F = self.F if F is None else F
        Q = self.Q if Q is None else Q
        self.x = F @ self.x
        self.P = F @ self.P @ F.T + Q
        return self.x

    def update(self, z, R=None, H=None) -> float:
        """Fuse measurement ``z``; ``R`` may vary per call (e.g. a GP's predicted variance, Eq. 3.7).

        Returns the innovation log-likelihood.
        """
        H = self.H if H is None else H
        R = self.R if R is None else np.atleast_2d(R)
        z = np.atleast_1d(np.asarray(z, dtype=float))
        self.y = z - H @ self.x
        PHt = self.P @ H.T
        self.S = H @ PHt + R
        K = np.linalg.solve(self.S.T, PHt.T).T
        self.x = self.x + K @ self.y
        I_KH = np.eye(self.dim_x) - K @ H
        self.P = I_KH @ self.P @ I_KH.T + K @ R @ K.T  # Joseph form: stays symmetric positive
        self.log_likelihood = gaussian_loglik(self.y, self.S)
        return self.log_likelihood

    def innovation(self, z, R=None, H=None) -> tuple[np.ndarray, np.ndarray]:
        """Innovation and its covariance for ``z`` without changing the state (for gating)."""
        H = self.H if H is None else H
        R = self.R if R is None else np.atleast_2d(R)
        y = np.atleast_1d(np.asarray(z, dtype=float)) - H @ self.x
        return y, H @ self.P @ H.T + R
