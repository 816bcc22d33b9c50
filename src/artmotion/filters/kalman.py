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


#: a covariance may differ from its transpose by this much, relative to its largest entry
SYMMETRY_TOL = 1e-8
#: ... and have eigenvalues down to minus this much, relative to its largest entry (round-off)
PSD_TOL = 1e-8


def _check_covariance(name: str, a: np.ndarray) -> None:
    """An :class:`InputError` unless the square float array ``a`` is a covariance: finite,
    symmetric and positive semi-definite (to :data:`SYMMETRY_TOL` and :data:`PSD_TOL` of its
    size). Filters call it per step: a sound matrix costs a few float operations (1 x 1, 2 x 2)
    or one ``eigvalsh`` and one comparison with its transpose (its largest eigenvalue bounds
    its entries; a NaN or infinity fails a test); :func:`_covariance_problem` finds what is
    wrong only when a test fails."""
    n = a.shape[0]
    if n == 1:
        if 0.0 <= float(a[0, 0]) < math.inf:
            return
    elif n == 2:                       # (the Taylor models' 2 x 2: no LAPACK call)
        (p, q), (r, t) = a.tolist()
        scale = max(p, t)              # (for a covariance, |q| <= sqrt(p t) <= scale)
        if (0.0 <= p < math.inf and 0.0 <= t < math.inf and abs(q - r) <= SYMMETRY_TOL * scale
                and p * t - q * r >= -PSD_TOL * scale * scale):
            return
    else:
        try:
            w = np.linalg.eigvalsh(a)  # (reads the lower triangle)
        except np.linalg.LinAlgError:
            w = None                   # NaN or infinity
        if w is not None:
            hi = float(w[-1])
            if math.isfinite(hi) and w[0] >= -PSD_TOL * hi and (a - a.T).max() <= SYMMETRY_TOL * hi:
                return                 # (``a - a.T`` is antisymmetric: its max is its largest |entry|)
    _covariance_problem(name, a)


def _covariance_problem(name: str, a: np.ndarray) -> None:
    """Raise the :class:`InputError` that says why ``a`` is not a covariance, if it is not."""
    if not np.isfinite(a).all():
        raise InputError(f"Kalman filter: {name} contains NaN or infinite values")
    diag = np.diagonal(a)
    if np.any(diag < 0.0):
        raise InputError(f"Kalman filter: {name} has a negative variance on its diagonal ({float(diag.min()):g})")
    scale = float(np.abs(a).max())
    asym = float(np.abs(a - a.T).max())
    if asym > SYMMETRY_TOL * scale:
        raise InputError(f"Kalman filter: {name} must be symmetric (a covariance), but it differs from its "
                         f"transpose by up to {asym:.3g}")
    low = float(np.linalg.eigvalsh(a)[0])
    if low < -PSD_TOL * scale:
        raise InputError(f"Kalman filter: {name} must be positive semi-definite (a covariance), "
                         f"but its smallest eigenvalue is {low:.3g}")


def _covariance(name: str, value, n: int) -> np.ndarray:
    """An ``n x n`` covariance: finite, symmetric, positive semi-definite (:func:`_check_covariance`)."""
    a = _matrix(name, value, (n, n))
    _check_covariance(name, a)
    return a


def _override(name: str, value, shape: tuple[int, int], covariance: bool = False) -> np.ndarray:
    """A matrix given to one :meth:`KalmanFilter.predict` or :meth:`~KalmanFilter.update`: a float
    array of ``shape`` with finite entries (a covariance with ``covariance``: a number ``q`` stands
    for ``q`` times the identity, as in filterpy), else an :class:`InputError`. Not copied."""
    a = float_array(value, f"Kalman filter: {name}")
    if covariance and a.ndim == 0:
        q = float(a)
        if not math.isfinite(q):
            raise InputError(f"Kalman filter: {name} must be a finite variance, got {q:g}")
        if q < 0.0:
            raise InputError(f"Kalman filter: {name} must be a non-negative variance, got {q:g}")
        return q * np.eye(shape[0])
    if a.shape != shape:
        raise InputError(f"Kalman filter: {name} must have shape {shape}, got {a.shape}")
    if covariance:
        _check_covariance(name, a)
    elif not math.isfinite(a.sum()) and not np.isfinite(a).all():   # (one call when all is well)
        raise InputError(f"Kalman filter: {name} contains NaN or infinite values")
    return a


def gaussian_loglik(y: np.ndarray, S: np.ndarray) -> float:
    """``log N(y; 0, S)`` for an innovation ``y`` with covariance ``S``.

    Raises :class:`InputError` unless ``S`` is a finite positive variance (or a positive definite
    ``m x m`` matrix) and ``y`` holds ``m`` finite values.
    """
    y = np.atleast_1d(y)
    S = np.atleast_2d(S)
    if S.shape == (1, 1):
        s = float(S[0, 0])
        if y.shape != (1,) or not (0.0 < s < math.inf) or not math.isfinite(y[0]):
            _loglik_problem(y, S)
        return -0.5 * (_LOG2PI + math.log(s) + float(y[0]) ** 2 / s)
    try:
        L = np.linalg.cholesky(S)
        z = np.linalg.solve(L, y)
    except (ValueError, np.linalg.LinAlgError):
        _loglik_problem(y, S)
        raise InputError("gaussian_loglik: S must be positive definite (Cholesky failed: singular "
                         "to working precision)") from None
    zz = z @ z
    if math.isnan(zz):                     # NaN in y (S's would have stopped the Cholesky)
        _loglik_problem(y, S)
    return float(-0.5 * (len(y) * _LOG2PI + 2.0 * np.log(np.diag(L)).sum() + zz))


def _loglik_problem(y: np.ndarray, S: np.ndarray) -> None:
    """Raise the :class:`InputError` that says what is wrong with :func:`gaussian_loglik`'s ``y``
    and ``S``, if something is (a shape, a NaN, a variance that is not positive)."""
    if S.ndim != 2 or S.shape[0] != S.shape[1] or S.shape[0] == 0:
        raise InputError(f"gaussian_loglik: S must be a variance or a square covariance matrix, got shape {S.shape}")
    m = S.shape[0]
    if y.shape != (m,):
        raise InputError(f"gaussian_loglik: y must hold {m} value{'s' if m != 1 else ''} (the size of S), "
                         f"got shape {y.shape}")
    if not (np.isfinite(y).all() and np.isfinite(S).all()):
        raise InputError("gaussian_loglik: y and S must be finite, got NaN or infinite values")
    if m == 1:
        raise InputError(f"gaussian_loglik: the variance S must be positive, got {float(S[0, 0]):g}")
    low = float(np.linalg.eigvalsh(S)[0])
    if low <= 0.0 or np.abs(S - S.T).max() > SYMMETRY_TOL * np.abs(S).max():
        raise InputError(f"gaussian_loglik: S must be a symmetric positive definite covariance, "
                         f"but its smallest eigenvalue is {low:.3g}")


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
        H = np.atleast_2d(float_array(H, "Kalman filter: H"))
        if H.ndim != 2 or H.shape[1] != n or H.shape[0] == 0:
            raise InputError(f"Kalman filter: H must have shape (m, {n}) for a state of {n}, got {H.shape}")
        self.H = _matrix("H", H, H.shape)
        self.R = _covariance("R", np.atleast_2d(float_array(R, "Kalman filter: R")), H.shape[0])
        self.y = np.zeros(self.H.shape[0])
        self.S = np.eye(self.H.shape[0])
        self.log_likelihood = 0.0

    @property
    def dim_x(self) -> int:
        return self.x.shape[0]

    def predict(self, F=None, Q=None) -> np.ndarray:
        """``x = F x``, ``P = F P F^T + Q`` with the filter's ``F`` and ``Q`` or, for this step,
        the ones given (checked: ``F`` an ``n x n`` finite matrix, ``Q`` a covariance or a number
        ``q`` for ``q`` times the identity, as in filterpy)."""
        n = self.dim_x
        F = self.F if F is None else _override("F", F, (n, n))
        Q = self.Q if Q is None else _override("Q", Q, (n, n), covariance=True)
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
            raise InputError("Kalman filter: the innovation covariance is not positive definite "
                             f"({getattr(e, 'reason', e)})") from None
        self.y, self.S = y, S
        self.x = self.x + K @ self.y
        I_KH = np.eye(self.dim_x) - K @ H
        self.P = I_KH @ self.P @ I_KH.T + K @ R @ K.T  # Joseph form: stays symmetric positive
        self.log_likelihood = ll
        return self.log_likelihood

    def _measurement(self, z, R, H) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``H``, ``R`` and ``z`` of an update, checked against each other: ``z`` has one finite
        value per row of ``H``, ``R`` that square and a covariance (a number ``r``: ``r`` times
        the identity, as in filterpy), ``H`` finite."""
        if H is None:
            H = self.H
        else:
            H = np.atleast_2d(float_array(H, "Kalman filter: H"))
            if H.ndim != 2 or H.shape[1] != self.dim_x or H.shape[0] == 0:
                raise InputError(f"Kalman filter: H must have shape (m, {self.dim_x}) for a state of "
                                 f"{self.dim_x}, got {H.shape}")
            H = _override("H", H, H.shape)
        m = H.shape[0]
        if R is None:
            R = self.R
        else:
            R = float_array(R, "Kalman filter: R")
            if R.ndim == 1:
                R = R[None, :]       # [r] for one measured value
            R = _override("R", R, (m, m), covariance=True)
        z = np.atleast_1d(float_array(z, "Kalman filter: z"))
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
