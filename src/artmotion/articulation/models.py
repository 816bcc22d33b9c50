"""Configuration fits of point articulation models, Eq. 4.1: ``X(t) = f_M(C, q(t)) + nu``.

Each model separates the time-invariant configuration ``C`` (fitted from all samples at once,
Section 4.3.3 / 4.8.1) from the motion variable ``q(t)`` (recovered by ``G: (X, C) -> q``,
Section 4.8.2). Points are handled in 3-D; 2-D tracks are embedded in the plane ``z = 0`` and
the revolute model then keeps the axis ``(0, 0, 1)``.

=============  ============================================  =====================
model          configuration ``C``                           motion ``q``
=============  ============================================  =====================
static         ``centre``                                    (none)
prismatic      ``origin``, unit ``direction``                 signed length
revolute       ``centre``, unit ``axis``, ``radius``, ``u``   angle (rad, unwrapped)
planar         ``origin``, ``normal``, in-plane ``u``, ``v``  2-D coordinates
=============  ============================================  =====================
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from artmotion.errors import InputError, check_range, float_array

__all__ = [
    "PointModel",
    "StaticModel",
    "PrismaticModel",
    "RevoluteModel",
    "PlanarModel",
    "POINT_MODELS",
    "fit_circle_2d",
    "fit_circle_joint",
    "as_points3",
    "make_model",
]


#: largest coordinate magnitude the fits take (their squares and sums must stay finite floats)
MAX_COORD = 1e100


def as_points3(X) -> tuple[np.ndarray, int]:
    """``(n, 3)`` float array and the original dimension (2 or 3)."""
    X = float_array(X, "points")
    if X.ndim != 2 or X.shape[1] not in (2, 3):
        raise InputError(f"points must be an (n, 2) or (n, 3) array, got shape {X.shape}")
    if not np.all(np.isfinite(X)):
        raise InputError("points contain NaN or infinite values")
    if X.size and float(np.abs(X).max()) > MAX_COORD:
        raise InputError(f"points must be coordinates of magnitude at most {MAX_COORD:g}")
    dim = X.shape[1]
    if dim == 2:
        X = np.column_stack([X, np.zeros(len(X))])
    return X, dim


def _unit(v) -> np.ndarray:
    """``v`` scaled to unit length (a zero vector as it is), always a new array."""
    v = np.array(v, dtype=float)
    n = np.linalg.norm(v)
    return v / n if n > 0 else v


def _given(value, name: str, sizes: tuple[int, ...] = (3,)) -> np.ndarray | None:
    """An array given to a model's constructor as a float array of its own (a copy: the caller's
    array may change afterwards), or None: ``n`` finite numbers (``n`` in ``sizes``) of magnitude
    at most :data:`MAX_COORD` (as the points a fit takes), else an :class:`InputError` naming ``name``."""
    if value is None:
        return None
    v = float_array(value, name)
    if v.ndim != 1 or v.shape[0] not in sizes:
        want = " or ".join(map(str, sizes))
        raise InputError(f"{name} must be {want} numbers (an array of shape "
                         f"{' or '.join(f'({n},)' for n in sizes)}), got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise InputError(f"{name} must be finite numbers, got {v.tolist()}")
    if v.size and float(np.abs(v).max()) > MAX_COORD:
        raise InputError(f"{name} must be numbers of magnitude at most {MAX_COORD:g}")
    return v.copy()


def _given_direction(value, name: str, sizes: tuple[int, ...] = (3,)) -> np.ndarray:
    """A direction given to a model's constructor (:func:`_given`, as given: not scaled); a zero one
    (no direction: a line along it predicted its origin for every q) is an :class:`InputError`."""
    v = _given(value, name, sizes)
    assert v is not None
    if not np.linalg.norm(v) > 0:
        raise InputError(f"{name} must be a direction, not a zero vector (or one too short to scale to unit length)")
    return v


def _given_unit(value, name: str, sizes: tuple[int, ...] = (3,)) -> np.ndarray:
    """A direction given to a model's constructor, as a unit vector (see :func:`_given_direction`)."""
    return _unit(_given_direction(value, name, sizes))


def _cross3(a, b) -> np.ndarray:
    """Cross product of two 3-vectors (np.cross costs ~20x more for one pair)."""
    a0, a1, a2 = float(a[0]), float(a[1]), float(a[2])
    b0, b1, b2 = float(b[0]), float(b[1]), float(b[2])
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _orthonormal_to(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = _unit(_cross3(n, a))
    return u, _cross3(n, u)


def _points_2d(P, name: str = "P") -> np.ndarray:
    """``P`` as an ``(n, 2)`` float array of finite coordinates (at most :data:`MAX_COORD`), else an
    :class:`InputError` naming ``name``."""
    P = float_array(P, name)
    if P.ndim != 2 or P.shape[1] != 2:
        hint = " (project 3-D points onto the circle's plane first)" if P.ndim == 2 and P.shape[1] == 3 else ""
        raise InputError(f"{name} must be an (n, 2) array of 2-D points, got shape {P.shape}{hint}")
    if not np.all(np.isfinite(P)):
        raise InputError(f"{name} contains NaN or infinite values")
    if P.size and float(np.abs(P).max()) > MAX_COORD:
        raise InputError(f"{name} must be coordinates of magnitude at most {MAX_COORD:g}")
    return P


def _on_one_line(P: np.ndarray, scale: float = 0.0) -> bool:
    """True if the 2-D points ``P`` (at least 3) lie on one line or are one point, to the rounding
    of coordinates of magnitude ``scale`` (and of their own): no circle passes through them, or
    every one does (its centre and radius are then anything the arithmetic makes up)."""
    sv = np.linalg.svd(P - P.mean(axis=0), compute_uv=False)
    return not sv[1] > 1e-12 * max(float(sv[0]), float(np.abs(P).max()), scale)


def _check_circle_points(P: np.ndarray, name: str, weights=None) -> None:
    """At least 3 points (of positive weight) not all on one line or one point, else an :class:`InputError`."""
    used = P if weights is None else P[weights > 0]
    which = "" if weights is None else " of positive weight"
    if len(used) < 3:
        noun = "point" if len(used) == 1 else "points"
        raise InputError(f"a circle needs at least 3 points, got {len(used)} {noun}{which} in {name}")
    if _on_one_line(used):
        raise InputError(f"the points{which} in {name} lie on one line or are one point: they do not span a circle")


def fit_circle_2d(P: np.ndarray, init: tuple | None = None, weights=None) -> tuple[np.ndarray, float]:
    """Circle through 2-D points: algebraic (Kasa) fit, refined by Gauss-Newton on the geometric
    distance. Linear in ``(cx, cy, r^2 - |c|^2)`` — the "separate" estimate of Table 4.1.

    ``P``: an ``(n, 2)`` array of at least 3 points not all on one line (nor one point).
    ``init``: a previous circle ``(centre, radius)``; Gauss-Newton starts from it instead of the
    algebraic fit when its geometric cost is lower (re-fits as samples arrive converge in fewer steps;
    a non-finite or out-of-scale one is not used).
    ``weights``: per-point weights (robust re-weighting; finite, non-negative), or None for all ones.
    """
    P = _points_2d(P, "P")
    if weights is not None:
        weights = float_array(weights, "weights")
        if weights.shape != (len(P),):
            raise InputError(f"weights must hold one weight per point ({len(P)}), got shape {weights.shape}")
        if not (np.all(np.isfinite(weights)) and np.all(weights >= 0.0)):
            raise InputError("weights must be finite and non-negative")
    _check_circle_points(P, "P", weights)
    if init is not None:
        try:
            centre, radius = init
        except (TypeError, ValueError):
            raise InputError(f"init must be a circle (centre, radius), got {init!r}") from None
        centre = float_array(centre, "init's centre")
        if centre.shape != (2,) or isinstance(radius, bool) or not isinstance(radius, numbers.Real):
            raise InputError(f"init must be a circle (centre: 2 numbers, radius: a number), got {init!r}")
        init = (centre, float(radius))
    return _circle_2d(P, init, weights)


def _circle_2d(P: np.ndarray, init: tuple | None = None, weights=None) -> tuple[np.ndarray, float]:
    """:func:`fit_circle_2d` on points already checked (or, for Algorithm 1's own revolute model,
    points on a line or at one point, whose circle is scored and loses)."""
    w = np.ones(len(P)) if weights is None else np.asarray(weights, dtype=float)
    mu = (w @ P) / w.sum()
    Q = P - mu
    scale = max(float(np.sqrt(w @ (Q**2).sum(axis=1) / w.sum())), 1e-12)
    Q = Q / scale
    sw = np.sqrt(w)
    A = np.column_stack([2 * Q, np.ones(len(Q))]) * sw[:, None]
    b = (Q**2).sum(axis=1) * sw
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    c = sol[:2]
    r = math.sqrt(max(sol[2] + c @ c, 1e-24))
    if init is not None and np.all(np.isfinite(init[0])) and 0.0 < init[1] < 1e6 * scale:
        ci = (np.asarray(init[0], dtype=float) - mu) / scale
        ri = float(init[1]) / scale

        def cost(cc, rr):
            return float(w @ (np.sqrt(((Q - cc) ** 2).sum(axis=1)) - rr) ** 2)

        if cost(ci, ri) < cost(c, r):
            c, r = ci, ri
    # geometric refinement (a few Gauss-Newton steps; stop if the radius explodes = a line);
    # J^T J and J^T res from sums over the points (J rows: -(d / rho), -1)
    qx, qy = np.ascontiguousarray(Q[:, 0]), np.ascontiguousarray(Q[:, 1])
    n = float(w.sum())
    cx, cy = float(c[0]), float(c[1])
    for _ in range(10):
        dx = qx - cx
        dy = qy - cy
        rho = np.sqrt(dx * dx + dy * dy)
        if rho.min() < 1e-12 or r > 1e6:
            break
        ux = dx / rho
        uy = dy / rho
        res = rho - r
        wx, wy, wr = w * ux, w * uy, w * res
        # weighted normal equations (J^T W J) step = -J^T W res with J = -[u, 1]: a symmetric 3x3 system
        a11, a12, a13 = float(wx @ ux), float(wx @ uy), float(wx.sum())
        a22, a23, a33 = float(wy @ uy), float(wy.sum()), n
        b1, b2, b3 = float(ux @ wr), float(uy @ wr), float(wr.sum())
        c11 = a22 * a33 - a23 * a23
        c12 = a13 * a23 - a12 * a33
        c13 = a12 * a23 - a13 * a22
        det = a11 * c11 + a12 * c12 + a13 * c13
        if not abs(det) > 1e-300:
            break
        c22 = a11 * a33 - a13 * a13
        c23 = a12 * a13 - a11 * a23
        c33 = a11 * a22 - a12 * a12
        s0 = (c11 * b1 + c12 * b2 + c13 * b3) / det
        s1 = (c12 * b1 + c22 * b2 + c23 * b3) / det
        s2 = (c13 * b1 + c23 * b2 + c33 * b3) / det
        cx += s0
        cy += s1
        r = abs(r + s2)
        if max(abs(s0), abs(s1), abs(s2)) < 1e-7:
            break
    c = np.array([cx, cy])
    return mu + c * scale, r * scale


def fit_circle_joint(t: np.ndarray, P: np.ndarray, theta0: float | None = None, omega: float | None = None):
    """Joint estimate of Eq. 4.29: ``X(t) = c + r [cos(theta0 + t w), sin(theta0 + t w)]``.

    Non-linear least squares in ``(cx, cy, r, theta0, w)``; needs a starting guess, taken from the
    chord (mean of the points as centre, unit radius, angle of the first point, small velocity)
    unless given. ``t``: one time per point; ``P``: ``(n, 2)``, at least 3 points not all on one
    line. Returns ``(centre, radius, theta0, omega)``.
    """
    from scipy.optimize import least_squares

    P = _points_2d(P, "P")
    t = float_array(t, "t")
    if t.shape != (len(P),):
        raise InputError(f"t must hold one time per point ({len(P)}), got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise InputError("t contains NaN or infinite values")
    _check_circle_points(P, "P")
    if not np.ptp(t) > 0:      # (the angle's rate needs two times: LAPACK failed on one, printing to stderr)
        raise InputError("t must hold at least two different times (the angle turns at a rate w over time)")
    if theta0 is not None:
        theta0 = check_range("theta0", theta0, -math.inf, math.inf, lo_open=True, hi_open=True)
    if omega is not None:
        omega = check_range("omega", omega, -math.inf, math.inf, lo_open=True, hi_open=True)
    c0 = P.mean(axis=0)
    d0 = P[0] - c0
    r0 = float(np.sqrt(((P - c0) ** 2).sum(axis=1)).mean())
    th0 = math.atan2(d0[1], d0[0]) if theta0 is None else theta0
    if omega is None:
        a = np.unwrap(np.arctan2(P[:, 1] - c0[1], P[:, 0] - c0[0]))
        omega = float(np.polyfit(t, a, 1)[0]) if len(t) > 1 else 0.0

    def res(p):
        cx, cy, r, th, w = p
        ang = th + t * w
        return np.concatenate([P[:, 0] - cx - r * np.cos(ang), P[:, 1] - cy - r * np.sin(ang)])

    sol = least_squares(res, [c0[0], c0[1], r0, th0, omega], method="lm")
    cx, cy, r, th, w = sol.x
    return np.array([cx, cy]), abs(float(r)), float(th), float(w)


class PointModel:
    """Base class: ``fit`` sets the configuration from an ``(n, 3)`` array of points, or the
    constructor takes it as given (copies of the arrays: the caller's may change afterwards)."""

    name = "base"
    dof = 0
    #: fewest points a fit needs, and the point dimensions it takes
    min_points = 1
    dims: tuple[int, ...] = (3,)

    def _check_points(self, X: np.ndarray, dims: tuple[int, ...], min_points: int = 0, fitted: bool = False) -> None:
        """An :class:`InputError` unless ``X`` is an ``(n, d)`` array (``d`` in ``dims``) of at least
        ``min_points`` finite points of magnitude at most :data:`MAX_COORD`."""
        if X.ndim != 2 or X.shape[1] not in dims:
            want = " or ".join(f"(n, {d})" for d in dims)
            like = " like the points it was fitted to" if fitted else ""
            raise InputError(f"{self.name} model: points must be an {want} array{like}, got shape {X.shape}")
        if len(X) < min_points:
            raise InputError(f"{self.name} model: needs at least {min_points} "
                             f"point{'s' if min_points > 1 else ''}, got {len(X)}")
        if not np.all(np.isfinite(X)):
            raise InputError(f"{self.name} model: points contain NaN or infinite values")
        if X.size and float(np.abs(X).max()) > MAX_COORD:
            raise InputError(f"{self.name} model: points must be coordinates of magnitude at most {MAX_COORD:g}")

    def _points_input(self, X, dim: int | None) -> np.ndarray:
        """Points given to a fitted model (``motion``, ``residuals``): an ``(n, dim)`` float array
        (``dim``: its configuration's dimension; None: any the model takes) of finite coordinates,
        checked as :meth:`fit` checks them (``n`` may be 0); else an :class:`InputError`."""
        X = float_array(X, "points")
        self._check_points(X, self.dims if dim is None else (dim,), fitted=dim is not None)
        return X

    def _fit_input(self, X, weights) -> tuple[np.ndarray, np.ndarray | None]:
        """``X`` and ``weights`` as float arrays, checked: finite points of a dimension the model
        takes, at least :attr:`min_points` of them, and one finite, non-negative weight per point
        with a positive sum; else an :class:`InputError`."""
        X = float_array(X, "points")
        self._check_points(X, self.dims, self.min_points)
        if weights is not None:
            weights = float_array(weights, "weights")
            if weights.shape != (len(X),):
                raise InputError(f"{self.name} model: needs one weight per point ({len(X)}), got shape {weights.shape}")
            if not (np.all(np.isfinite(weights)) and np.all(weights >= 0.0) and weights.sum() > 0.0):
                raise InputError(f"{self.name} model: weights must be finite, non-negative and not all zero")
        return X, weights

    def _not_fitted(self) -> InputError:
        return InputError(f"{self.name} model is not fitted: call fit(points) first (or give its configuration)")

    def _motion_input(self, q) -> np.ndarray:
        """Motion variables as an ``(n, dof)`` float array (finite), else an :class:`InputError`.
        With one motion variable ``n`` values (or one number) are taken as a column; with more,
        a 1-D array of ``dof`` values is one point's."""
        q = float_array(q, "motion variables")
        dof = self.dof
        if q.ndim == 2 and q.shape[1] == dof:
            pass
        elif dof == 1 and q.ndim <= 1:
            q = q.reshape(-1, 1)
        elif dof > 1 and q.shape == (dof,):
            q = q.reshape(1, dof)
        else:
            also = " (or n values)" if dof == 1 else f" (or one point's {dof} values)" if dof > 1 else ""
            raise InputError(f"{self.name} model: motion variables must be an (n, {dof}) array{also}, got shape {q.shape}")
        if not np.all(np.isfinite(q)):
            raise InputError(f"{self.name} model: motion variables must be finite numbers, got NaN or infinite values")
        return q

    def _one_motion(self, q) -> np.ndarray:
        """One point's motion variables (for :meth:`jacobian`): ``dof`` finite numbers, else an :class:`InputError`."""
        q = float_array(q, "motion variables").reshape(-1)
        if q.size != self.dof or not np.all(np.isfinite(q)):
            got = "NaN or infinite values" if q.size == self.dof else f"{q.size} value{'s' if q.size != 1 else ''}"
            raise InputError(f"{self.name} model: jacobian takes one point's motion variables, {self.dof} finite "
                             f"number{'s' if self.dof != 1 else ''}, got {got}")
        return q

    def _scalar_motion(self, q) -> float:
        """One motion variable as a finite number (``predict1``, ``jacobian1``), else an :class:`InputError`."""
        return check_range(f"{self.name} model: the motion variable", q, -math.inf, math.inf, lo_open=True, hi_open=True)

    #: configuration parameters of the model for 3-D and for 2-D points (its charge in the BIC score)
    n_params = {3: 0, 2: 0}

    def fit(self, X: np.ndarray, weights=None) -> PointModel:  # pragma: no cover - interface
        """Configuration from points ``X`` (``(n, 3)``), each weighted by ``weights`` (None: all 1)."""
        raise NotImplementedError

    def motion(self, X: np.ndarray) -> np.ndarray:
        """``G(X, C)``: motion variables ``(n, dof)`` of points ``(n, 3)``."""
        raise NotImplementedError

    def predict(self, q: np.ndarray) -> np.ndarray:
        """``f_M(C, q)``: points ``(n, 3)`` for motion variables ``(n, dof)``."""
        raise NotImplementedError

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """``d f_M / d q`` at one ``q`` (``(3, dof)``)."""
        raise NotImplementedError

    def residuals(self, X: np.ndarray) -> np.ndarray:
        """Distance of each point to the model's manifold."""
        X = float_array(X, "points")
        return np.linalg.norm(X - self.predict(self.motion(X)), axis=1)

    def configuration(self, dim: int = 3) -> dict:
        raise NotImplementedError


def _weighted_mean(X: np.ndarray, weights) -> np.ndarray:
    return X.mean(axis=0) if weights is None else (weights @ X) / weights.sum()


def _principal_axes(X: np.ndarray, mu: np.ndarray, weights) -> np.ndarray:
    """Rows: principal directions of the (weighted) points about ``mu``, largest spread first."""
    D = X - mu
    if weights is not None:
        D = D * np.sqrt(weights)[:, None]
    return np.linalg.svd(D, full_matrices=False)[2]


class StaticModel(PointModel):
    name = "static"
    dof = 0
    n_params = {3: 3, 2: 2}  # the centre
    min_points = 1
    dims = (2, 3)

    def __init__(self, centre=None):
        self.centre = _given(centre, "centre", (2, 3))  # (2-D points: a 2-D centre, as fit gives)

    def fit(self, X, weights=None):
        X, weights = self._fit_input(X, weights)
        self.centre = _weighted_mean(X, weights)
        return self

    def motion(self, X):
        X = self._points_input(X, None if self.centre is None else len(self.centre))
        return np.zeros((len(X), 0))

    def predict(self, q):
        if self.centre is None:
            raise self._not_fitted()
        return np.repeat(self.centre[None, :], len(self._motion_input(q)), axis=0)

    def jacobian(self, q):
        self._one_motion(q)
        return np.zeros((3, 0))

    def configuration(self, dim=3):
        if self.centre is None:
            raise self._not_fitted()
        return {"centre": self.centre[:dim].tolist()}


class PrismaticModel(PointModel):
    name = "prismatic"
    dof = 1
    n_params = {3: 4, 2: 2}  # a line
    min_points = 2
    dims = (2, 3)

    def __init__(self, origin=None, direction=None):
        self.origin = _given(origin, "origin", (2, 3))
        self.direction = None if direction is None else _given_unit(direction, "direction", (2, 3))
        if self.origin is not None and self.direction is not None and len(self.direction) != len(self.origin):
            raise InputError(f"direction must have as many numbers as origin ({len(self.origin)}), "
                             f"got {len(self.direction)}")

    def fit(self, X, weights=None):
        X, weights = self._fit_input(X, weights)
        mu = _weighted_mean(X, weights)
        d = _principal_axes(X, mu, weights)[0]
        if (X[-1] - X[0]) @ d < 0:  # q grows along the track
            d = -d
        # origin: the first sample's projection on the line, so q(0) ~ 0
        self.origin = mu + ((X[0] - mu) @ d) * d
        self.direction = d
        return self

    def motion(self, X):
        if self.origin is None or self.direction is None:
            raise self._not_fitted()
        return ((self._points_input(X, len(self.origin)) - self.origin) @ self.direction)[:, None]

    def predict(self, q):
        if self.origin is None or self.direction is None:
            raise self._not_fitted()
        return self.origin + self._motion_input(q) * self.direction

    def jacobian(self, q):
        if self.direction is None:
            raise self._not_fitted()
        self._one_motion(q)
        return self.direction.reshape(-1, 1)

    def predict1(self, q: float) -> np.ndarray:
        if self.origin is None or self.direction is None:
            raise self._not_fitted()
        return self.origin + self._scalar_motion(q) * self.direction

    def jacobian1(self, q: float) -> np.ndarray:
        if self.direction is None:
            raise self._not_fitted()
        self._scalar_motion(q)
        return self.direction

    def configuration(self, dim=3):
        if self.origin is None or self.direction is None:
            raise self._not_fitted()
        return {"origin": self.origin[:dim].tolist(), "direction": self.direction[:dim].tolist()}


class RevoluteModel(PointModel):
    """Point on a circle: ``f(C, q) = c + r (cos q u + sin q v)``, ``v = axis x u``.

    ``fit`` refuses points that do not span a circle (all on one line, or one point), whose centre
    and radius would be made up by the arithmetic, unless :attr:`require_circle` is False: Algorithm 1
    (online.py) fits every candidate to every track and lets the evidence reject such a circle."""

    name = "revolute"
    dof = 1
    n_params = {3: 6, 2: 3}  # the circle's plane (3-D only), its centre in the plane and radius
    min_points = 3
    #: refuse points on one line or at one point (see the class doc)
    require_circle = True

    def __init__(self, centre=None, axis=None, radius=None, u=None, planar_axis=None):
        self.centre = _given(centre, "centre")
        self.axis = None if axis is None else _given_unit(axis, "axis")
        self.radius = None if radius is None else float(
            check_range("radius", radius, 0.0, MAX_COORD, lo_open=True))
        self.u = None if u is None else _given_unit(u, "u")
        if self.u is not None and self.axis is not None:
            # u spans the circle's plane with v = axis x u: its part along the axis is dropped (as fit
            # does), else the points predicted lay on an ellipse; along the axis it spans nothing
            along = float(self.u @ self.axis)
            if along != 0.0:
                perp = self.u - along * self.axis
                if not np.linalg.norm(perp) > 1e-6:  # (nearly) parallel: no direction in the plane
                    raise InputError("u must not be parallel to the axis: it gives the direction of angle 0 "
                                     "in the circle's plane, perpendicular to the axis")
                self.u = _unit(perp)
        # fixed plane normal (2-D data), or None to estimate
        self.planar_axis = None if planar_axis is None else _given_direction(planar_axis, "planar_axis")

    @property
    def v(self):
        if getattr(self, "_v", None) is None:
            if self.axis is None or self.u is None:
                raise self._not_fitted()
            self._v = _cross3(self.axis, self.u)
        return self._v

    def fit(self, X, weights=None):
        X, weights = self._fit_input(X, weights)
        mu = _weighted_mean(X, weights)
        n = _unit(self.planar_axis) if self.planar_axis is not None else _principal_axes(X, mu, weights)[2]
        e1, e2 = _orthonormal_to(n)
        P = np.column_stack([(X - mu) @ e1, (X - mu) @ e2])
        if self.require_circle:
            used = P if weights is None else P[weights > 0]
            if len(used) < 3 or _on_one_line(used, float(np.abs(X).max())):
                which = "" if weights is None else ", counting those of positive weight"
                raise InputError(f"{self.name} model: the points do not span a circle (they lie on one line or "
                                 f"are one point{which})")
        init = None
        if getattr(self, "warm", False) and self.centre is not None and self.radius is not None:
            d = self.centre - mu
            init = (np.array([d @ e1, d @ e2]), self.radius)
        c2, r = _circle_2d(P, init, weights)
        centre = mu + c2[0] * e1 + c2[1] * e2
        # orient the axis so that the angle grows along the track (right-hand rule)
        a0 = X[0] - centre
        a1 = X[-1] - centre
        if _cross3(a0, a1) @ n < 0:
            n = -n
        u = a0 - (a0 @ n) * n
        if np.linalg.norm(u) < 1e-12:
            u = _orthonormal_to(n)[0]
        self.centre, self.axis, self.radius, self.u = centre, n, float(r), _unit(u)
        self._v = _cross3(self.axis, self.u)
        return self

    def _fitted(self) -> bool:
        return self.centre is not None and self.axis is not None and self.radius is not None and self.u is not None

    def motion(self, X):
        if not self._fitted():
            raise self._not_fitted()
        assert self.centre is not None  # fitted
        d = self._points_input(X, len(self.centre)) - self.centre
        ang = np.arctan2(d @ self.v, d @ self.u)
        return np.unwrap(ang)[:, None]

    def predict(self, q):
        if not self._fitted():
            raise self._not_fitted()
        q = self._motion_input(q)
        return self.centre + self.radius * (np.cos(q) * self.u + np.sin(q) * self.v)

    def jacobian(self, q):
        if not self._fitted():
            raise self._not_fitted()
        q = float(self._one_motion(q)[0])
        assert self.u is not None  # fitted
        return (self.radius * (-math.sin(q) * self.u + math.cos(q) * self.v)).reshape(3, 1)

    def predict1(self, q: float) -> np.ndarray:
        if not self._fitted():
            raise self._not_fitted()
        assert self.u is not None and self.centre is not None and self.radius is not None  # fitted
        q = self._scalar_motion(q)
        return self.centre + (self.radius * math.cos(q)) * self.u + (self.radius * math.sin(q)) * self.v

    def jacobian1(self, q: float) -> np.ndarray:
        if self.u is None or self.axis is None or self.radius is None:
            raise self._not_fitted()
        q = self._scalar_motion(q)
        return (-self.radius * math.sin(q)) * self.u + (self.radius * math.cos(q)) * self.v

    def configuration(self, dim=3):
        if not self._fitted():
            raise self._not_fitted()
        assert self.centre is not None and self.axis is not None and self.radius is not None
        out = {"centre": self.centre[:dim].tolist(), "radius": float(self.radius)}
        out["axis"] = self.axis.tolist()
        return out


class PlanarModel(PointModel):
    """Point moving freely in a plane (2 DOF): ``f(C, q) = origin + q1 u + q2 v``."""

    name = "planar"
    dof = 2
    n_params = {3: 3, 2: 0}  # the plane
    min_points = 3

    def __init__(self, origin=None, normal=None, planar_axis=None):
        self.origin = _given(origin, "origin")
        self.normal = None if normal is None else _given_unit(normal, "normal")
        self.planar_axis = None if planar_axis is None else _given_direction(planar_axis, "planar_axis")
        if self.normal is not None:
            self.u, self.v = _orthonormal_to(self.normal)

    def fit(self, X, weights=None):
        X, weights = self._fit_input(X, weights)
        mu = _weighted_mean(X, weights)
        if self.planar_axis is not None:
            n = _unit(self.planar_axis)
            self.u, self.v = _orthonormal_to(n)
        else:
            Vt = _principal_axes(X, mu, weights)
            n, self.u = Vt[2], Vt[0]
            self.v = _cross3(n, self.u)
        self.origin = mu + ((X[0] - mu) @ self.u) * self.u + ((X[0] - mu) @ self.v) * self.v
        self.normal = n
        return self

    def motion(self, X):
        if self.origin is None or self.normal is None:
            raise self._not_fitted()
        d = self._points_input(X, len(self.origin)) - self.origin
        return np.column_stack([d @ self.u, d @ self.v])

    def predict(self, q):
        if self.origin is None or self.normal is None:
            raise self._not_fitted()
        q = self._motion_input(q)
        return self.origin + q[:, :1] * self.u + q[:, 1:] * self.v

    def jacobian(self, q):
        if self.origin is None or self.normal is None:
            raise self._not_fitted()
        self._one_motion(q)
        return np.column_stack([self.u, self.v])

    def configuration(self, dim=3):
        if self.origin is None or self.normal is None:
            raise self._not_fitted()
        return {"origin": self.origin[:dim].tolist(), "normal": self.normal.tolist()}


POINT_MODELS = {"static": StaticModel, "prismatic": PrismaticModel, "revolute": RevoluteModel, "planar": PlanarModel}


def make_model(name: str, dim: int = 3) -> PointModel:
    """A fresh model by name; for 2-D data the revolute/planar plane is fixed to ``z = 0``."""
    if not isinstance(name, str) or name not in POINT_MODELS:
        raise InputError(f"unknown point model {name!r}: expected one of {', '.join(POINT_MODELS)}")
    if dim not in (2, 3):
        raise InputError(f"point models work on 2-D or 3-D points, got dim={dim!r}")
    cls = POINT_MODELS[name]
    if name in ("revolute", "planar") and dim == 2:
        return cls(planar_axis=np.array([0.0, 0.0, 1.0]))
    return cls()
