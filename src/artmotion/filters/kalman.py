"""A small, fast linear Kalman filter with filterpy's attribute names.

filterpy's ``KalmanFilter`` is general but slow for the thousands of tiny filters this project
runs (one per track, per angle, per articulation model); this one keeps the same names
(``x, P, F, Q, H, R``) and adds the innovation log-likelihood that model selection needs (Eq. 4.16).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from artmotion.errors import InputError, float_array

_LOG2PI = math.log(2.0 * math.pi)


def _size_note(name: str, n: int) -> str:
    """What sets the size of ``name``: the state's for ``P``, ``F``, ``Q``; the number of measured
    values (the rows of ``H``) for ``R``."""
    if name == "R":
        return f"one row and column per measured value: H has {n} row{'s' if n != 1 else ''}"
    return f"one row and column per entry of the state x, which holds {n}"


def _shape_error(name: str, shape: tuple[int, int], got: tuple[int, ...]) -> InputError:
    """The :class:`InputError` of a matrix ``name`` whose shape ``got`` is not ``shape``."""
    return InputError(f"Kalman filter: {name} must have shape {shape}, got {got} ({_size_note(name, shape[0])})")


def _flat(a: np.ndarray) -> np.ndarray | None:
    """``a`` as a vector if it is one: ``n`` values, a column ``(n, 1)`` (filterpy's convention) or
    a row ``(1, n)``; a number is one value. None if ``a`` is not a vector."""
    if a.ndim == 1:
        return a
    if a.ndim == 0 or (a.ndim == 2 and 1 in a.shape):
        return a.reshape(-1)
    return None


def _state(value) -> np.ndarray:
    """The state ``x`` (given to the constructor or assigned): a copy as a vector of finite floats
    (:func:`_flat`), else an :class:`InputError`."""
    a = float_array(value, "Kalman filter: x")
    x = _flat(a)
    if x is None:
        raise InputError(f"Kalman filter: x must be a vector (n values, or a column (n, 1) as in filterpy), "
                         f"got shape {a.shape}")
    if x.size == 0 or not np.all(np.isfinite(x)):
        raise InputError("Kalman filter: x must be a non-empty state of finite numbers")
    return x.copy()


def _matrix(name: str, value, n: int | None, copy: bool = False) -> np.ndarray:
    """``F`` (``n x n``) or ``H`` (``m x n``: a row per measured value; one row may be given as a
    vector) as a float matrix of finite entries, else an :class:`InputError`. ``n`` None (an
    assignment): any square ``F``, any ``H``; their sizes against the state's are checked at the
    next step (:meth:`KalmanFilter._check_state`)."""
    a = float_array(value, f"Kalman filter: {name}")
    if name == "H":
        if a.ndim < 2:
            a = np.atleast_2d(a)
        if a.ndim != 2 or 0 in a.shape or (n is not None and a.shape[1] != n):
            raise InputError(f"Kalman filter: H must have shape (m, {n}) for a state of {n}, got {a.shape}"
                             if n is not None else
                             f"Kalman filter: H must be a matrix (m, n) (a row of n numbers per measured value), "
                             f"got shape {a.shape}")
    elif n is not None:
        if a.shape != (n, n):
            raise _shape_error(name, (n, n), a.shape)
    elif a.ndim != 2 or a.shape[0] != a.shape[1] or a.shape[0] == 0:
        raise InputError(f"Kalman filter: {name} must be a square matrix, got shape {a.shape}")
    if not math.isfinite(a.sum()) and not np.isfinite(a).all():   # (one call when all is well)
        raise InputError(f"Kalman filter: {name} contains NaN or infinite values")
    return a.copy() if copy else a


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


def _covariance(name: str, value, n: int, any_size: bool = False, copy: bool = False) -> np.ndarray:
    """``P``, ``Q`` (``n``: the size of the state) or ``R`` (``n``: the number of measured values)
    as a covariance: an ``n x n`` float matrix, finite, symmetric and positive semi-definite
    (:func:`_check_covariance`), or a number ``q`` (alone or in a list) for ``q`` times the identity,
    as in filterpy; else an :class:`InputError`. With ``any_size`` (an assignment) a matrix may be
    of any size, checked against the others' at the next step (:meth:`KalmanFilter._check_state`).

    The one home of these rules: the constructor, the assignments and the matrices given to one
    :meth:`~KalmanFilter.predict` or :meth:`~KalmanFilter.update` (not copied) all come here."""
    a = float_array(value, f"Kalman filter: {name}")
    if a.ndim <= 1 and a.size == 1:
        q = float(a.reshape(-1)[0])
        if not math.isfinite(q):
            raise InputError(f"Kalman filter: {name} must be a finite variance, got {q:g}")
        if q < 0.0:
            raise InputError(f"Kalman filter: {name} must be a non-negative variance, got {q:g}")
        return q * np.eye(n)
    if not any_size:
        if a.shape != (n, n):
            raise _shape_error(name, (n, n), a.shape)
    elif a.ndim != 2 or a.shape[0] != a.shape[1] or a.shape[0] == 0:
        raise InputError(f"Kalman filter: {name} must be a square matrix (a covariance) or a number, got shape {a.shape}")
    _check_covariance(name, a)
    return a.copy() if copy else a


def gaussian_loglik(y: np.ndarray, S: np.ndarray) -> float:
    """``log N(y; 0, S)`` for an innovation ``y`` with covariance ``S``.

    Raises :class:`InputError` unless ``S`` is a finite positive variance (or a positive definite
    ``m x m`` matrix) and ``y`` holds ``m`` finite values.
    """
    y = np.atleast_1d(y)
    S = np.atleast_2d(S)
    if y.dtype.kind not in "fiu" or S.dtype.kind not in "fiu":
        raise InputError(f"gaussian_loglik: y and S must be real numbers, got {y.dtype} and {S.dtype}")
    if S.shape == (1, 1):
        s = float(S[0, 0])
        if y.shape != (1,) or not (0.0 < s < math.inf) or not math.isfinite(y[0]):
            _loglik_problem(y, S)
        try:
            out = -0.5 * (_LOG2PI + math.log(s) + float(y[0]) ** 2 / s)
        except OverflowError:
            out = -math.inf
        if not math.isfinite(out):      # (1e200 squared: beyond the floats, not a likelihood)
            raise InputError(f"gaussian_loglik: y = {float(y[0]):g} is too far out for variance {s:g} (its "
                             "log-likelihood is beyond the floats)")
        return out
    if (S.ndim != 2 or S.shape[0] != S.shape[1] or S.shape[0] == 0 or y.shape != S.shape[:1]
            or np.abs(S - S.T).max() > _symmetry_tol(S) * np.abs(S).max()):
        _loglik_problem(y, S)     # (Cholesky reads one triangle only: one not symmetric would pass as another)
    return _loglik(y, S)


def _symmetry_tol(S: np.ndarray) -> float:
    """How far from symmetric (relative) a covariance may be: :data:`SYMMETRY_TOL`, or a few
    dozen rounding units of a lower precision (float32: ``J P J^T`` rounds to ~4e-7)."""
    return max(SYMMETRY_TOL, 64.0 * float(np.finfo(S.dtype).eps)) if S.dtype.kind == "f" else SYMMETRY_TOL


def _loglik(y: np.ndarray, S: np.ndarray) -> float:
    """:func:`gaussian_loglik` of an ``m``-vector and an ``m x m`` matrix (``m`` >= 2) that are
    symmetric by construction (the Kalman update's ``H P H^T + R``): the checks of shape and
    symmetry are the public function's."""
    try:
        L = np.linalg.cholesky(S)
        z = np.linalg.solve(L, y)
    except (ValueError, np.linalg.LinAlgError):
        _loglik_problem(y, S)
        raise InputError("gaussian_loglik: S must be positive definite (Cholesky failed: singular "
                         "to working precision)") from None
    with np.errstate(over="ignore"):
        zz = z @ z
    if math.isnan(zz):                     # NaN in y (S's would have stopped the Cholesky)
        _loglik_problem(y, S)
    if math.isinf(zz):                     # (as for one dimension: beyond the floats, not a likelihood)
        raise InputError("gaussian_loglik: y is too far out for S (its log-likelihood is beyond the floats)")
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
    asym = float(np.abs(S - S.T).max())
    if asym > _symmetry_tol(S) * np.abs(S).max():
        raise InputError(f"gaussian_loglik: S must be a symmetric covariance, but S and its transpose differ by "
                         f"up to {asym:.3g}")
    low = float(np.linalg.eigvalsh(S)[0])
    if low <= 0.0:
        raise InputError(f"gaussian_loglik: S must be a symmetric positive definite covariance, "
                         f"but its smallest eigenvalue is {low:.3g}")


class _Checked:
    """An attribute of :class:`KalmanFilter` (``x, P, F, Q, H, R``) that an assignment checks and
    converts (:meth:`KalmanFilter._assigned`); read, it is the array itself (changed in place as
    in filterpy)."""

    def __init__(self, doc: str):
        self.__doc__ = doc

    def __set_name__(self, owner, name: str) -> None:
        self.name, self.slot = name, "_" + name

    def __get__(self, obj, objtype=None) -> Any:
        return self if obj is None else getattr(obj, self.slot)

    def __set__(self, obj, value) -> None:
        setattr(obj, self.slot, obj._assigned(self.name, value))


class KalmanFilter:
    """Linear Kalman filter ``x' = F x + w, w ~ N(0, Q)``; ``z = H x + v, v ~ N(0, R)``.

    After :meth:`update`, ``y`` is the innovation, ``S`` its covariance and ``log_likelihood``
    the log-density of the observation under the prediction.

    ``x, P, F, Q, H, R`` are attributes as in filterpy: read them, change them in place, or assign
    them. An assignment is checked and converted as the constructor checks and converts (a copy as
    a float array; a number for ``P``, ``Q`` or ``R`` is that variance times the identity; a column
    ``x`` is the state vector), else an :class:`InputError` naming the attribute. The sizes of the
    attributes against one another are checked at the next step, so that a state of another size
    can be assigned attribute by attribute (``x`` first: a number for ``P`` or ``Q`` takes its size).
    """

    def __init__(self, x, P, F, Q, H, R):
        self._x = _state(x)
        n = len(self._x)
        self._P = _covariance("P", P, n, copy=True)
        self._F = _matrix("F", F, n, copy=True)
        self._Q = _covariance("Q", Q, n, copy=True)
        self._H = _matrix("H", H, n, copy=True)
        m = self._H.shape[0]
        self._R = _covariance("R", R, m, copy=True)
        self._fits = True  # the attributes' sizes fit one another (False after an assignment, until checked)
        self.y = np.zeros(m)
        self.S = np.eye(m)
        self.log_likelihood = 0.0

    # -- filterpy's attributes: an assignment is checked and converted as the constructor does
    def _assigned(self, name: str, value) -> np.ndarray:
        """``value`` assigned to attribute ``name``, checked and converted (sizes: see the class doc)."""
        if name == "x":
            a = _state(value)
        elif name in ("F", "H"):
            a = _matrix(name, value, None, copy=True)
        else:
            a = _covariance(name, value, self._H.shape[0] if name == "R" else self._x.shape[0], any_size=True, copy=True)
        self._fits = False
        return a

    x = _Checked("The state, ``(n,)``.")
    P = _Checked("The state's covariance, ``(n, n)``.")
    F = _Checked("The transition, ``(n, n)``.")
    Q = _Checked("The process noise's covariance, ``(n, n)``.")
    H = _Checked("The measurement matrix, ``(m, n)``: a row per measured value.")
    R = _Checked("The measurement noise's covariance, ``(m, m)``.")

    @property
    def dim_x(self) -> int:
        return self._x.shape[0]

    def predict(self, F=None, Q=None) -> np.ndarray:
        """``x = F x``, ``P = F P F^T + Q`` with the filter's ``F`` and ``Q`` or, for this step,
        the ones given (checked: ``F`` an ``n x n`` finite matrix, ``Q`` a covariance or a number
        ``q`` for ``q`` times the identity, as in filterpy)."""
        if not self._fits:
            self._check_state()
        n = self._x.shape[0]
        F = self._F if F is None else _matrix("F", F, n)
        Q = self._Q if Q is None else _covariance("Q", Q, n)
        self._x = F @ self._x
        self._P = F @ self._P @ F.T + Q
        return self._x

    def update(self, z, R=None, H=None) -> float:
        """Fuse measurement ``z``; ``R`` may vary per call (e.g. a GP's predicted variance, Eq. 3.7).

        Returns the innovation log-likelihood.
        """
        H, R, z = self._measurement(z, R, H)
        try:
            y = z - H @ self._x
            PHt = self._P @ H.T
            S = H @ PHt + R
            K = np.linalg.solve(S.T, PHt.T).T
            ll = gaussian_loglik(y, S) if len(y) == 1 else _loglik(y, S)
        except InputError:      # (an innovation too far out for the floats: said as such)
            raise
        except (ValueError, np.linalg.LinAlgError) as e:
            raise InputError("Kalman filter: the innovation covariance is not positive definite "
                             f"({getattr(e, 'reason', e)})") from None
        self.y, self.S = y, S
        self._x = self._x + K @ self.y
        I_KH = np.eye(self.dim_x) - K @ H
        self._P = I_KH @ self._P @ I_KH.T + K @ R @ K.T  # Joseph form: stays symmetric positive
        self.log_likelihood = ll
        return self.log_likelihood

    def _measurement(self, z, R, H) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``H``, ``R`` and ``z`` of an update, checked against each other: ``z`` has one finite
        value per row of ``H`` (a column as in filterpy, or a vector), ``R`` that square and a
        covariance (a number ``r``: ``r`` times the identity, as in filterpy), ``H`` finite."""
        if not self._fits:
            self._check_state()
        H = self._H if H is None else _matrix("H", H, self._x.shape[0])
        m = H.shape[0]
        if R is not None:
            R = _covariance("R", R, m)
        elif self._R.shape[0] == m:
            R = self._R
        else:           # an H of other rows than the filter's R has
            raise InputError(f"{_shape_error('R', (m, m), self._R.shape)}: give R with H")
        za = float_array(z, "Kalman filter: z")
        zv = _flat(za)
        if zv is None or zv.shape != (m,):
            raise InputError(f"Kalman filter: z must hold {m} value{'s' if m != 1 else ''} (the rows of H), "
                             f"got shape {za.shape}")
        if not np.all(np.isfinite(zv)):
            raise InputError("Kalman filter: z contains NaN or infinite values")
        return H, R, zv

    def _check_state(self) -> None:
        """An :class:`InputError` naming ``P``, ``F``, ``Q``, ``H`` or ``R`` if its size does not fit
        the state's (or ``H``'s, for ``R``): an assignment changed one of them."""
        n = self._x.shape[0]
        for name, a in (("P", self._P), ("F", self._F), ("Q", self._Q)):
            if a.shape != (n, n):
                raise _shape_error(name, (n, n), a.shape)
        _matrix("H", self._H, n)      # (its shape against the state's, as the constructor checks it)
        m = self._H.shape[0]
        if self._R.shape != (m, m):
            raise _shape_error("R", (m, m), self._R.shape)
        self._fits = True

    def innovation(self, z, R=None, H=None) -> tuple[np.ndarray, np.ndarray]:
        """Innovation and its covariance for ``z`` without changing the state (for gating)."""
        H, R, z = self._measurement(z, R, H)
        return z - H @ self._x, H @ self._P @ H.T + R
