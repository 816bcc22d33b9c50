"""What each landmark is: Algorithm 1 on its sightings, and the joint it decides (Sec. 4.7).

Both SLAM back ends use this: a landmark's world positions (seen from the current robot estimate)
go through :class:`~artmotion.articulation.online.OnlineEstimator`; once a model passes ``tau`` the
landmark gets a :class:`Joint` — the fitted line or circle its motion variable ``q`` moves along
(``q`` in metres along the line, or the world angle on the circle) — and the Taylor model of
``(q, q')`` that carries it from step to step (Eq. 4.18). With ``curve`` the decided line or circle
becomes a path of constant curvature (a :class:`Joint` of kind "curve", refined by Gauss-Newton on
the sightings), on which ``q`` is the arc length.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from artmotion.articulation.online import OnlineEstimator
from artmotion.filters import taylor_model

__all__ = ["Joint", "Decision", "LandmarkModels"]


@dataclass
class Joint:
    """A moving landmark's path: ``origin + q direction`` (prismatic), ``centre + radius (cos q,
    sin q)`` (revolute), or a path of constant ``curvature`` through ``origin`` with tangent
    ``direction`` there, ``q`` its arc length (curve, :meth:`position_shaped`); world coordinates."""

    kind: str
    origin: np.ndarray  # prismatic: a point of the line; revolute: the centre; curve: its anchor
    direction: np.ndarray | None = None  # prismatic: the line's; curve: the tangent at the anchor
    radius: float = 0.0
    curvature: float = 0.0  # curve: signed, > 0 turning left of ``direction``

    def position(self, q: float) -> tuple[np.ndarray, np.ndarray]:
        """``m(q)`` and ``dm/dq`` (the ``J_{m(t)}^{m_j}`` of Eq. 4.28)."""
        if self.kind == "curve":
            m, J = self.position_shaped(q, np.zeros(4))
            return m, J[:, 0]
        if self.kind == "prismatic":
            assert self.direction is not None
            return self.origin + q * self.direction, self.direction
        c, s = math.cos(q), math.sin(q)
        return self.origin + self.radius * np.array([c, s]), self.radius * np.array([-s, c])

    def position_shaped(self, q: float, e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``m(q)`` on the joint moved by ``e = (dx, dy, de)``: a shift of its line or centre, and
        ``de`` added to the radius (revolute) or turning the line about its origin (prismatic, rad);
        with ``dm/d(q, dx, dy, de)`` (2 x 4). A curve's ``e = (dx, dy, dphi, dkappa)`` shifts its
        anchor, turns its tangent there and changes its curvature (2 x 5)."""
        if self.kind == "curve":
            return self._curve(q, e)
        J = np.zeros((2, 4))
        J[:, 1:3] = np.eye(2)
        if self.kind == "prismatic":
            assert self.direction is not None
            c, s = math.cos(e[2]), math.sin(e[2])
            d0 = self.direction
            d = np.array([c * d0[0] - s * d0[1], s * d0[0] + c * d0[1]])
            J[:, 0] = d
            J[:, 3] = q * np.array([-d[1], d[0]])
            return self.origin + e[:2] + q * d, J
        c, s = math.cos(q), math.sin(q)
        r = self.radius + e[2]
        J[:, 0] = r * np.array([-s, c])
        J[:, 3] = [c, s]
        return self.origin + e[:2] + r * np.array([c, s]), J

    def _curve(self, s: float, e) -> tuple[np.ndarray, np.ndarray]:
        """A path of constant curvature through the anchor, a line and a circle alike:
        ``m(s) = a + R(phi) g(s, kappa)``, ``g = (sin(kappa s), 1 - cos(kappa s)) / kappa`` (its
        limit ``(s, 0)`` at ``kappa = 0``), ``s`` the arc length from the anchor."""
        assert self.direction is not None
        phi = math.atan2(self.direction[1], self.direction[0]) + float(e[2])
        k = self.curvature + float(e[3])
        u = k * s
        cu, su = math.cos(u), math.sin(u)
        if abs(u) < 1e-2:  # series: the closed forms lose their digits near the line
            u2 = u * u
            g = s * np.array([1.0 - u2 / 6.0 + u2 * u2 / 120.0, u / 2.0 - u * u2 / 24.0])
            dg_dk = s * s * np.array([-u / 3.0 + u * u2 / 30.0, 0.5 - u2 / 8.0 + u2 * u2 / 144.0])
        else:
            g = np.array([su, 1.0 - cu]) / k
            dg_dk = np.array([u * cu - su, u * su - 1.0 + cu]) / (k * k)
        c, sn = math.cos(phi), math.sin(phi)
        R = np.array([[c, -sn], [sn, c]])
        J = np.zeros((2, 5))
        J[:, 0] = R @ np.array([cu, su])
        J[:, 1:3] = np.eye(2)
        J[:, 3] = R @ np.array([-g[1], g[0]])
        J[:, 4] = R @ dg_dk
        return self.origin + np.asarray(e[:2], dtype=float) + R @ g, J

    def shape_covariance(self, points: np.ndarray, sigma: float, gauge: float) -> np.ndarray:
        """Covariance of ``(dx, dy, de)`` (see :meth:`position_shaped`) from a least-squares fit of
        the joint to ``points`` (n, 2) with noise ``sigma`` off the path: ``sigma^2 (J^T J)^-1`` of the
        residuals' Jacobian (Gauss-Newton). A revolute joint's residual is ``|p - c| - r`` in
        ``(c_x, c_y, r)``; a prismatic one's the distance to the line, in its shift along the normal
        and its angle; the shift along the line (which only renames ``q``) gets ``gauge^2``. A weak
        prior keeps a fit the points hardly constrain (a short arc) finite: std the radius for
        ``(c_x, c_y, r)``; the points' spread and 45 degrees for a line's shift and angle."""
        P = np.asarray(points, dtype=float)[:, :2]
        if self.kind == "curve":
            return self.fit_curve(P, sigma, gauge, steps=0)[1]
        if self.kind == "revolute":
            diff = P - self.origin
            u = diff / np.maximum(np.linalg.norm(diff, axis=1, keepdims=True), 1e-9)
            J = np.column_stack([-u, -np.ones(len(P))])
            prior = np.full(3, max(self.radius, gauge))
            return sigma**2 * np.linalg.inv(J.T @ J + np.diag((sigma / prior) ** 2))
        assert self.direction is not None
        d = self.direction
        n = np.array([-d[1], d[0]])
        q = (P - self.origin) @ d
        J = np.column_stack([-np.ones(len(P)), -q])
        prior = np.array([max(float(np.ptp(q)), gauge), math.pi / 4])
        C = sigma**2 * np.linalg.inv(J.T @ J + np.diag((sigma / prior) ** 2))
        T = np.array([[n[0], 0.0], [n[1], 0.0], [0.0, 1.0]])
        out = T @ C @ T.T
        out[:2, :2] += gauge**2 * np.outer(d, d)
        return out

    def fit_curve(self, P: np.ndarray, sigma: float, gauge: float, steps: int = 5) -> tuple[Joint, np.ndarray]:
        """Gauss-Newton on the points' distances to the curve in ``(shift along the anchor's
        normal, dphi, dkappa)`` with a weak prior (std the points' spread, 45 degrees, and a
        curvature of 1/m), ``steps`` iterations: the refined curve and the covariance of its
        ``(dx, dy, dphi, dkappa)``; the shift along the tangent (which only renames ``s``) gets
        ``gauge^2``."""
        curve = self
        prior = np.array([max(float(np.ptp(P, axis=0).max()), gauge), math.pi / 4, 1.0])
        L = np.diag((sigma / prior) ** 2)
        moved = np.zeros(3)  # the change from the first curve, which the prior holds back
        for it in range(steps + 1):
            assert curve.direction is not None
            t0 = curve.direction
            n0 = np.array([-t0[1], t0[0]])
            T = np.array([[n0[0], 0.0, 0.0], [n0[1], 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
            rows, res = [], []
            for p in P:
                s = curve.coordinate(p)
                m, J = curve.position_shaped(s, np.zeros(4))
                nrm = np.array([-J[1, 0], J[0, 0]])
                res.append(float(nrm @ (p - m)))
                rows.append(-(nrm @ J[:, 1:]) @ T)
            A, r = np.array(rows), np.array(res)
            H = A.T @ A + L
            if it == steps:
                C = T @ (sigma**2 * np.linalg.inv(H)) @ T.T
                C[:2, :2] += gauge**2 * np.outer(t0, t0)
                return curve, C
            d = -np.linalg.solve(H, A.T @ r + L @ moved)
            moved += d
            phi = math.atan2(t0[1], t0[0]) + d[1]
            curve = Joint("curve", curve.origin + d[0] * n0, np.array([math.cos(phi), math.sin(phi)]),
                          curvature=curve.curvature + float(d[2]))
        raise AssertionError("unreachable")

    def anchored(self, m: np.ndarray) -> Joint:
        """The same curve anchored at the point nearest to ``m`` (there ``s = 0``)."""
        assert self.kind == "curve" and self.direction is not None
        s = self.coordinate(m)
        a, J = self.position_shaped(s, np.zeros(4))
        return Joint("curve", a, J[:, 0] / np.linalg.norm(J[:, 0]), curvature=self.curvature)

    def coordinate(self, m: np.ndarray) -> float:
        """The motion variable ``q`` of the point of the path nearest to ``m`` (the angle in (-pi, pi];
        a curve's arc length from its anchor, within half a turn of it: ``|q| <= pi / |curvature|``,
        ample for a hinge's swing)."""
        if self.kind == "curve":
            assert self.direction is not None
            t0 = self.direction
            k = self.curvature
            d = np.asarray(m[:2], dtype=float) - self.origin
            if abs(k) < 1e-9:
                return float(d @ t0)
            n0 = np.array([-t0[1], t0[0]])
            ca = -n0 / k  # anchor - centre
            cp = d + ca  # point - centre
            alpha = math.atan2(ca[0] * cp[1] - ca[1] * cp[0], ca @ cp)
            return alpha / k
        if self.kind == "prismatic":
            assert self.direction is not None
            return float((m - self.origin) @ self.direction)
        return math.atan2(m[1] - self.origin[1], m[0] - self.origin[0])

    def transition(self, dt: float, accel_var: float) -> tuple[np.ndarray, np.ndarray]:
        """Taylor model (order 2) of ``(q, q')``: ``F`` and ``Q`` for a step of ``dt``; the
        acceleration noise is in m/s^2 along the path (radians scale by the radius)."""
        scale = 1.0 / self.radius**2 if self.kind == "revolute" else 1.0
        return taylor_model(2, dt, accel_var * scale, 1)


@dataclass
class Decision:
    """Algorithm 1's verdict on a landmark: ``kind``, and for a moving one its :class:`Joint`, the
    motion variable at the current sighting with ``dq/dm`` (2,), its rate and the rate's variance."""

    kind: str
    joint: Joint | None = None
    q: float = 0.0
    dq_dm: np.ndarray | None = None
    rate: float = 0.0
    rate_var: float = 0.0
    shape_cov: np.ndarray | None = None  #: covariance of the joint's ``(dx, dy, de)`` (3 x 3; a curve's 4 x 4)


#: the least hinge radius a priori (m): Algorithm 1's radius range starts here
MIN_RADIUS = 0.5


class LandmarkModels:
    """Algorithm 1 per landmark id: ``observe(i, m, Pm, k)`` feeds a world position (and its
    covariance) seen at step ``k`` and returns a :class:`Decision` once a model passes ``threshold``.

    ``min_radius``, ``max_radius``: the range of hinge radii a priori (log-uniform); re-fits every
    10 % of samples (landmarks are seen for short stretches); ``point_noise`` is a floor on the
    points' noise (the robot's own drift is not white noise)."""

    def __init__(self, dt: float, threshold: float = 0.75, min_samples: int = 7, point_noise: float = 0.15,
                 max_radius: float = 5.0, accel: float | None = 0.1, min_radius: float = MIN_RADIUS,
                 curve: bool = False):
        self.dt = dt
        self.curve = curve
        self.threshold, self.min_samples = threshold, min_samples
        self.point_noise, self.accel = point_noise, accel
        self.radius_range = (min_radius, max_radius)
        self.estimators: dict[int, OnlineEstimator] = {}
        self.verdict: dict[int, str] = {}  # the model that passed tau (Algorithm 1 has decided)

    def reset(self, i: int) -> None:
        """Forget landmark ``i``'s sightings (it was decided wrongly, or started moving)."""
        self.estimators.pop(i, None)
        self.verdict.pop(i, None)

    def observe(self, i: int, m: np.ndarray, Pm: np.ndarray, k: int) -> Decision | None:
        """Sighting ``m`` (world position, covariance ``Pm``) of landmark ``i`` at step ``k``; the
        :class:`Decision` once a model passes ``threshold`` (kept in :attr:`verdict`)."""
        est = self.estimators.get(i)
        if est is None:
            est = OnlineEstimator(threshold=self.threshold, min_samples=self.min_samples, dim=2, noise=None,
                                  noise_floor=self.point_noise,
                                  radius_range=self.radius_range, refit_growth=1.1,
                                  accel=self.accel)
            self.estimators[i] = est
        # the point's noise: the observation noise carried to the world frame
        est.noise = max(est.noise or 0.0, self.point_noise, math.sqrt(float(np.linalg.eigvalsh(Pm)[-1])))
        est.update(m, float(k))  # time in steps: the Taylor models work per sample
        probs = est.probabilities
        if not probs:
            return None
        name = max(probs, key=probs.__getitem__)
        if probs[name] <= self.threshold:
            return None
        self.verdict[i] = name
        if name == "static":
            return Decision("static")
        f = est.fitted(name)  # robust, as Algorithm 1 fits it: one glitch does not drag the joint
        model = f.model
        X = np.asarray(est.X)
        # motion variable from the current sighting: q = G(m), dq/dm = J^+ (Eq. 4.28 inverted)
        if name == "revolute":  # (a line's q is the joint's coordinate of m, below)
            q = float(model.motion(np.array([[m[0], m[1], 0.0]]))[0, 0])
            q = q + 2 * np.pi * round((model.motion(X)[-1, 0] - q) / (2 * np.pi))
        rate, rate_var = f.velocity(X, np.asarray(est.T))
        rate, rate_var = rate / self.dt, rate_var / self.dt**2  # per step -> per second
        if name == "revolute":
            # the circle lies in z = 0: the motion variable becomes the world angle of (point - centre)
            e1, e2 = model.u, model.v
            sgn = 1.0 if np.cross(e1, e2)[2] > 0 else -1.0
            q, rate = math.atan2(e1[1], e1[0]) + sgn * q, sgn * rate
            joint = Joint("revolute", model.centre[:2].copy(), radius=float(model.radius))
        else:
            d = model.direction[:2]
            joint = Joint("prismatic", model.origin[:2].copy(), d / np.linalg.norm(d))
            q = joint.coordinate(m)
        sigma = max(float(f.sigma), self.point_noise)
        if self.curve:
            # the decision keeps Algorithm 1's name; its path may bend or straighten in the filter
            joint, q, rate, rate_var = self._as_curve(joint, q, rate, rate_var, X, m, sigma)
        _, Jq = joint.position(q)
        shape = joint.shape_covariance(X, sigma, self.point_noise)
        return Decision(name, joint, q, Jq / (Jq @ Jq), rate, rate_var, shape)

    def _as_curve(self, joint: Joint, q: float, rate: float, rate_var: float, X: np.ndarray, m: np.ndarray,
                  sigma: float) -> tuple[Joint, float, float, float]:
        """The fitted line or circle as a :class:`Joint` of kind "curve" refined on the points ``X``
        (Gauss-Newton) and anchored at the current sighting ``m`` (``s = 0``), with the rate in
        metres along it."""
        if joint.kind == "revolute":
            c, sn = math.cos(q), math.sin(q)
            curve = Joint("curve", joint.origin + joint.radius * np.array([c, sn]), np.array([-sn, c]),
                          curvature=1.0 / joint.radius)
            rate, rate_var = rate * joint.radius, rate_var * joint.radius**2
        else:
            assert joint.direction is not None
            curve = Joint("curve", joint.origin + q * joint.direction, joint.direction.copy())
        curve, _ = curve.fit_curve(np.asarray(X, dtype=float)[:, :2], sigma, self.point_noise)
        return curve.anchored(m), 0.0, rate, rate_var
