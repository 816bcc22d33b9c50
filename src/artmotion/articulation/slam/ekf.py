"""EKF SLAM and Articulated EKF SLAM (Sections 4.6-4.7, Algorithm 2).

Robot state ``(x, y, theta)``; velocity motion model with control noise (Eq. 4.20-4.23) and its
Jacobians (Eq. 4.25-4.26); range-bearing observations of point landmarks (Eq. 4.24) with
Jacobians (Eq. 4.27-4.28). Data association is known (landmark ids).

* :class:`EKFSlam` (``articulated=False``): the standard algorithm; every landmark is a static
  ``(m_x, m_y)`` in the state from its first sighting.
* ``articulated=True`` (Algorithm 2): a landmark first goes through Algorithm 1
  (:class:`~artmotion.articulation.online.OnlineEstimator`) on its world positions as seen from the
  current robot estimate, without touching the SLAM state. Once a model passes ``tau`` the
  landmark joins the state as its *motion variables* — ``(m_x, m_y)`` if static, ``(q, q')``
  (Taylor order 2) along the fitted line or circle if prismatic or revolute — which the time update
  propagates (Eq. 4.18) and the observation Jacobian reaches through ``J_{m(t)}^{m_j}`` (Eq. 4.28).
"""

from __future__ import annotations

import math
import reprlib
import sys

import numpy as np

from artmotion.articulation.slam.landmarks import MIN_RADIUS, Decision, Joint, LandmarkModels
from artmotion.errors import InputError, check_bool, check_range, float_array

__all__ = ["motion_model", "control_noise", "observe", "inverse_observation", "gate_threshold", "EKFSlam"]


def _wrap(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


#: largest magnitude of a number the public helpers below take (a pose's, a control's, a time
#: step's, a noise coefficient's): their products then stay finite floats
MAX_VALUE = 1e100


def _vector(value, name: str, size: int, what: str, nonneg: bool = False) -> np.ndarray:
    """``value`` as a float array of ``size`` finite numbers of magnitude at most :data:`MAX_VALUE`
    (``nonneg``: and >= 0; ``what`` says what they are), else an :class:`InputError` naming ``name``
    and the shape wanted. The public helpers' check (the filter's per-step path calls the unchecked
    ones)."""
    try:
        a = float_array(value, name)
    except InputError:
        raise InputError(f"{name} must be {what}, got {reprlib.repr(value)}") from None
    if a.shape != (size,):
        raise InputError(f"{name} must be {what}: an array of shape ({size},), got shape {a.shape}")
    if not np.all((a >= (0.0 if nonneg else -MAX_VALUE)) & (a <= MAX_VALUE)):   # (False for NaN)
        raise InputError(f"{name} must be {what}, finite and of magnitude at most {MAX_VALUE:g}, "
                         f"got {reprlib.repr(value)}")
    return a


def _pose(x):
    return _vector(x, "x", 3, "a pose, 3 numbers (x, y, theta)")


def _control(u):
    return _vector(u, "u", 2, "a control, 2 numbers (v, omega)")


def motion_model(x: np.ndarray, u, dt: float):
    """Eq. 4.20 (4.21 when ``omega ~ 0``): next pose, ``J_x`` (Eq. 4.25) and ``J_u`` (Eq. 4.26) from
    pose ``x = (x, y, theta)``, control ``u = (v, omega)`` and time step ``dt > 0`` (numbers of
    magnitude at most :data:`MAX_VALUE`; else an :class:`InputError`)."""
    return _motion_model(_pose(x), _control(u), check_range("dt", dt, 0.0, MAX_VALUE, lo_open=True))


def _motion_model(x, u, dt: float):
    """:func:`motion_model` of checked arguments (the filter's per-step path)."""
    px, py, th = x
    v, w = u
    if abs(w) < 1e-9:
        c, s = math.cos(th), math.sin(th)
        xn = np.array([px + v * dt * c, py + v * dt * s, th])
        Gx = np.array([[1.0, 0.0, -v * dt * s], [0.0, 1.0, v * dt * c], [0.0, 0.0, 1.0]])
        Gu = np.array([[dt * c, -0.5 * v * dt * dt * s], [dt * s, 0.5 * v * dt * dt * c], [0.0, dt]])
        return xn, Gx, Gu
    r = v / w
    s0, c0 = math.sin(th), math.cos(th)
    th1 = th + w * dt
    s1, c1 = math.sin(th1), math.cos(th1)
    xn = np.array([px - r * s0 + r * s1, py + r * c0 - r * c1, th1])
    Gx = np.array([[1.0, 0.0, -r * c0 + r * c1], [0.0, 1.0, -r * s0 + r * s1], [0.0, 0.0, 1.0]])
    Gu = np.array([
        [(-s0 + s1) / w, v * (s0 - s1) / w**2 + v * c1 * dt / w],
        [(c0 - c1) / w, -v * (c0 - c1) / w**2 + v * s1 * dt / w],
        [0.0, dt],
    ])
    return xn, Gx, Gu


def control_noise(u, alphas) -> np.ndarray:
    """``M_k`` of Eq. 4.23 for control ``u = (v, omega)`` and noise coefficients ``alphas`` (4 numbers
    >= 0); an :class:`InputError` unless they are finite numbers of magnitude at most :data:`MAX_VALUE`."""
    u = _control(u)
    alphas = _vector(alphas, "alphas", 4, "4 numbers >= 0 (the control noise of Eq. 4.23)", nonneg=True)
    return _control_noise(u, alphas)


def _control_noise(u, alphas) -> np.ndarray:
    """:func:`control_noise` of checked arguments (the filter's per-step path)."""
    v, w = u
    a1, a2, a3, a4 = alphas
    return np.diag([a1 * v * v + a2 * w * w, a3 * v * v + a4 * w * w])


def observe(x: np.ndarray, m: np.ndarray):
    """Eq. 4.24 and its Jacobians: ``z = (range, bearing)``, ``J_x`` (Eq. 4.27), ``J_m`` (Eq. 4.28) of
    landmark ``m = (m_x, m_y)`` seen from pose ``x = (x, y, theta)``; an :class:`InputError` unless
    they are finite numbers of magnitude at most :data:`MAX_VALUE` and ``m`` lies away from the
    pose (at range 0 the bearing and the Jacobians are undefined)."""
    x = _pose(x)
    m = _vector(m, "m", 2, "a landmark position, 2 numbers (m_x, m_y)")
    dx, dy = float(m[0] - x[0]), float(m[1] - x[1])
    if not dx * dx + dy * dy > 0.0:
        raise InputError(f"m must lie away from the pose x, got range {math.hypot(dx, dy):g}: at range 0 (or one "
                         "whose square is 0 in floats) the bearing and the Jacobians are undefined")
    return _observe(x, m)


def _observe(x: np.ndarray, m: np.ndarray):
    """:func:`observe` of checked arguments (the filter's per-step path)."""
    dx, dy = m[0] - x[0], m[1] - x[1]
    q = dx * dx + dy * dy
    sq = math.sqrt(q)
    z = np.array([sq, _wrap(math.atan2(dy, dx) - x[2])])
    Hx = np.array([[-dx / sq, -dy / sq, 0.0], [dy / q, -dx / q, -1.0]])
    Hm = np.array([[dx / sq, dy / sq], [-dy / q, dx / q]])
    return z, Hx, Hm


def inverse_observation(x: np.ndarray, z) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. 4.24 inverted: the world point ``m`` that sighting ``z = (range, bearing)`` from pose ``x``
    sees, and its Jacobians w.r.t. the pose (2 x 3) and the sighting (2 x 2). An :class:`InputError`
    unless they are finite numbers of magnitude at most :data:`MAX_VALUE` and the range is >= 0."""
    x = _pose(x)
    z = _vector(z, "z", 2, "a sighting, 2 numbers (range, bearing)")
    if not z[0] >= 0.0:
        raise InputError(f"z's range must be >= 0 (a distance), got {float(z[0]):g}")
    return _inverse_observation(x, z)


def _inverse_observation(x: np.ndarray, z) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`inverse_observation` of checked arguments (the filter's per-step path)."""
    a = x[2] + z[1]
    c, s = math.cos(a), math.sin(a)
    m = np.array([x[0] + z[0] * c, x[1] + z[0] * s])
    Gx = np.array([[1.0, 0.0, -z[0] * s], [0.0, 1.0, z[0] * c]])
    Gz = np.array([[c, -z[0] * s], [s, z[0] * c]])
    return m, Gx, Gz


def gate_threshold(p: float) -> float:
    """The chi^2 (2 degrees of freedom) value that a consistent sighting exceeds with probability
    ``p``: ``-2 ln p`` (13.8 for 0.1 %). An :class:`InputError` unless ``p`` lies in (0, 1)."""
    p = check_range("p", p, 0.0, 1.0, lo_open=True, hi_open=True)
    return -2.0 * math.log(p)


def _numeric(a) -> bool:
    """Whether ``a`` makes a NumPy array of real numbers (not text, objects or ragged lists)."""
    try:
        return np.asarray(a).dtype.kind in "biuf"
    except ValueError:  # a ragged list
        return False


def _check_control(u) -> tuple[float, float]:
    """``u`` as two finite floats ``(v, omega)``, else an :class:`InputError` (before the state is touched)."""
    U = np.asarray(u, dtype=float) if _numeric(u) else None
    if U is None or U.shape != (2,) or not np.isfinite(U).all():
        raise InputError(f"a control must be two finite numbers (v, omega), got {reprlib.repr(u)}")
    return float(U[0]), float(U[1])


#: the ranges a sighting may have (m): a range of 0 (or so small that the landmark lands on the
#: robot's estimate) has no bearing and divides by zero (Eq. 4.27-4.28); one beyond 1000 km
#: overflows the covariances (``range^2 bearing_std^2``); either turned the whole state to NaN
MIN_RANGE, MAX_RANGE = 1e-6, 1e6
#: least and greatest (range, bearing): a finite bearing lies within the largest floats
_Z_LOW, _Z_HIGH = np.array([MIN_RANGE, -sys.float_info.max]), np.array([MAX_RANGE, sys.float_info.max])


def _check_sightings(ids, zs) -> tuple[list[int], np.ndarray]:
    """``ids`` as whole numbers and ``zs`` as a ``(k, 2)`` array of (range, bearing) pairs, one per
    id, ranges in ``[MIN_RANGE, MAX_RANGE]`` and bearings finite; else an :class:`InputError`
    (before the filter's state is touched)."""
    idx = np.asarray(ids) if _numeric(ids) else None
    if idx is None or idx.ndim != 1 or (idx.size and not (np.isfinite(idx).all() and (idx == np.round(idx)).all())):
        raise InputError(f"landmark ids must be a list of whole numbers, got {reprlib.repr(ids)}")
    Z = np.asarray(zs, dtype=float) if _numeric(zs) else None
    if Z is not None and Z.size == 0:
        Z = Z.reshape(0, 2)
    if Z is None or Z.ndim != 2 or Z.shape[1] != 2:
        raise InputError(f"sightings zs must be (range, bearing) pairs, one row each, got {reprlib.repr(zs)}")
    if len(Z) != len(idx):
        raise InputError(f"{len(idx)} landmark ids but {len(Z)} sightings zs")
    ok = (Z >= _Z_LOW) & (Z <= _Z_HIGH)  # (False for NaN)
    if not ok.all():
        j, c = np.argwhere(~ok)[0]
        what = (f"has range {Z[j, 0]:g}: ranges must lie in [{MIN_RANGE:g}, {MAX_RANGE:g}] m" if c == 0
                else f"has bearing {Z[j, 1]:g}: bearings must be finite")
        raise InputError(f"sighting zs[{j}] of landmark {int(idx[j])} {what}")
    return idx.astype(int).tolist(), Z


#: most landmarks a filter is made for: the EKF's covariance is allocated for them at once, (3 +
#: 2 n)^2 numbers (800 MB at 5000; 10^6 asked for 29 TiB and ended in a MemoryError)
MAX_LANDMARKS = 5000


def _check_arguments(x0, dt, alphas, range_std, bearing_std, n_max, *, articulated, threshold, min_samples,
                     point_noise, max_radius, motion_var, accel, gate, undecided_var=0.0) -> tuple[np.ndarray, tuple, int, int]:
    """The arguments :class:`EKFSlam` and :class:`~artmotion.articulation.slam.graph.GraphSlam`
    share, checked before anything is built: ``x0`` as a float array ``(3,)``, ``alphas`` as 4
    floats, ``n_max`` and ``min_samples`` as ints (a whole float such as ``5.0`` is the count it
    is); else an :class:`InputError` that names the argument. With ``articulated``, also those
    of Algorithm 1 (:class:`~artmotion.articulation.online.OnlineEstimator` checked them only at a
    landmark's first sighting, under its own names; without, ``min_samples`` is passed on as given)."""
    x = float_array(x0, "x0")
    if x.shape != (3,) or not np.isfinite(x).all():
        raise InputError(f"x0 must be 3 finite numbers (x, y, theta), got {reprlib.repr(x0)}")
    check_range("dt", dt, 0.0, math.inf, lo_open=True, hi_open=True)
    a = float_array(alphas, "alphas")
    if a.shape != (4,) or not (np.isfinite(a).all() and (a >= 0).all()):
        raise InputError(f"alphas must be 4 finite numbers >= 0 (the control noise of Eq. 4.23), got {reprlib.repr(alphas)}")
    check_range("range_std", range_std, 0.0, math.inf, lo_open=True, hi_open=True)
    check_range("bearing_std", bearing_std, 0.0, math.inf, lo_open=True, hi_open=True)
    n_max = check_range("n_max", n_max, 0, MAX_LANDMARKS, integer=True)
    check_range("motion_var", motion_var, 0.0, math.inf, hi_open=True)
    check_range("undecided_var", undecided_var, 0.0, math.inf, hi_open=True)
    check_range("gate", gate, 0.0, 1.0, lo_open=True, hi_open=True)
    if check_bool("articulated", articulated):
        # as OnlineEstimator (Algorithm 1) requires them
        check_range("threshold", threshold, 0.0, 1.0, lo_open=True, hi_open=True)
        min_samples = check_range("min_samples", min_samples, 3, 10**9, integer=True)
        check_range("point_noise", point_noise, 0.0, math.inf, hi_open=True)
        check_range("max_radius", max_radius, MIN_RADIUS, math.inf, lo_open=True, hi_open=True)
        if accel is not None:
            check_range("accel", accel, 0.0, math.inf, hi_open=True)
    return x, tuple(float(v) for v in a), n_max, min_samples


# ---------------------------------------------------------------- the filter
class _Block:
    """A landmark's slice of the state: ``(m_x, m_y)`` if static, ``(q, q')`` along a :class:`Joint`."""

    __slots__ = ("kind", "start", "dim", "joint", "F", "Q")

    def __init__(self, kind: str, start: int, dim: int, joint: Joint | None = None):
        self.kind, self.start, self.dim, self.joint = kind, start, dim, joint
        self.F: np.ndarray | None = None
        self.Q: np.ndarray | None = None

    def position(self, s: np.ndarray):
        """``m_j`` and ``J_{m(t)}^{m_j}`` (2 x dim) from the block's state ``s``: ``(m_x, m_y)``, or
        ``(q, q')`` and, if ``dim`` is 4, a shift ``(dx, dy)`` of the joint's line or centre, and if
        ``dim`` is 5 also a change of its radius or direction, if 6 (a curve) the turn of its tangent
        and the change of its curvature (:meth:`Joint.position_shaped`)."""
        if self.joint is None:
            return s[:2], np.eye(2)
        J = np.zeros((2, self.dim))
        if self.dim >= 5:
            m, Js = self.joint.position_shaped(float(s[0]), s[2:self.dim])
            J[:, 0], J[:, 2:] = Js[:, 0], Js[:, 1:]
            return m, J
        m, Jq = self.joint.position(float(s[0]))
        J[:, 0] = Jq
        if self.dim == 4:
            m = m + s[2:4]
            J[:, 2:4] = np.eye(2)
        return m, J


class EKFSlam:
    """EKF SLAM; ``articulated=True`` gives Articulated EKF SLAM.

    Articulated, a new landmark enters the state at once as static (the most likely model a priori)
    while Algorithm 1 learns its model from its sightings in parallel; once a moving model passes
    ``threshold`` the landmark's static block is replaced by its motion variables ``(q, q')``
    (re-initialised from the current sighting). ``delayed=True`` is the thesis's Algorithm 2: a
    landmark stays out of the state until Algorithm 1 has decided. ``undecided_var`` (m^2 per step)
    lets an undecided static landmark drift as a random walk, weighted by Algorithm 1's probability
    that it moves (an interacting-multiple-model view of "static or moving"; 0 turns it off).
    ``joint_shift``: a moving landmark's state also holds a shift ``(dx, dy)`` of its fitted line or
    circle, which starts with the robot's uncertainty (the joint was fitted to points seen from the
    robot's estimates) plus ``point_noise``; without it the joint is taken as exact. ``joint_shape``
    (with ``joint_shift``) also puts the joint's radius (revolute) or direction (prismatic) in the
    state: shift and shape then start with the fit's own covariance (Gauss-Newton on the sightings
    Algorithm 1 fitted, :meth:`~artmotion.articulation.slam.landmarks.Joint.shape_covariance`)
    instead of ``point_noise``, and every sighting refines them. ``joint_curve`` (with both, the
    default; chosen by leave-one-world-out) puts the decided line or circle in the state as a path
    of constant curvature anchored at the current sighting — ``(s, s', dx, dy, dphi, dkappa)``, arc
    length, its rate, the anchor's shift, the tangent's turn and the curvature's change — so a
    line may bend and an arc straighten as sightings come (Algorithm 1 often cannot tell a line
    from an arc over the stretch it saw).

    ``gating`` (default: on when articulated) applies a chi^2 (2 dof) validation gate that a
    consistent sighting fails with probability ``gate`` (1 %: chosen by leave-one-world-out); a
    landmark whose sightings fail it three times in a row leaves the state until its next sighting
    (and if Algorithm 1 had decided its model, it learns it afresh). With ``drift_window`` ``W``
    (default 3; 0 or 1: off) a sighting also fails the gate when the sum of the landmark's last
    ``W`` innovations (this one and the ``W - 1`` before it that passed) fails the same test
    against the sum of their covariances: a consistent filter's innovations are white, so their
    sum has that covariance, while a landmark that drifts slowly (a cart or a door fused as static
    while each sighting still passes) adds up innovations of one sign. Chosen by
    leave-one-world-out (docs/articulation.md).
    """

    def __init__(self, x0, dt: float, alphas, range_std: float, bearing_std: float, n_max: int,
                 articulated: bool = False, threshold: float = 0.75, min_samples: int = 7,
                 point_noise: float = 0.15, max_radius: float = 5.0, motion_var: float = 0.01,
                 accel: float | None = 0.1, gating: bool | None = None, delayed: bool = False,
                 undecided_var: float = 0.0, joint_shift: bool = True, gate: float = 0.01,
                 joint_shape: bool = True, joint_curve: bool = True, drift_window: int = 3):
        x0, alphas, n_max, min_samples = _check_arguments(
            x0, dt, alphas, range_std, bearing_std, n_max, articulated=articulated, threshold=threshold,
            min_samples=min_samples, point_noise=point_noise, max_radius=max_radius, motion_var=motion_var,
            accel=accel, gate=gate, undecided_var=undecided_var)
        check_bool("gating", gating, none=True)
        for name, flag in (("delayed", delayed), ("joint_shift", joint_shift), ("joint_shape", joint_shape),
                           ("joint_curve", joint_curve)):
            check_bool(name, flag)
        self.dt = dt
        self.alphas = alphas
        self.R1 = np.diag([range_std**2, bearing_std**2])
        self.articulated = articulated
        self.delayed = delayed
        self.undecided_var = undecided_var
        self.joint_shift = joint_shift
        self.joint_shape = joint_shape
        cap = 3 + 2 * n_max  # grows if moving landmarks need more (see _append)
        self.mu = np.zeros(cap)
        self.P = np.zeros((cap, cap))
        self.mu[:3] = x0
        self.P[:3, :3] = np.eye(3) * 1e-6
        self.n = 3
        self.blocks: dict[int, _Block] = {}
        self.models = LandmarkModels(dt, threshold, min_samples, point_noise, max_radius, accel,
                                     curve=joint_curve and joint_shift and joint_shape)
        self.decided_at: dict[int, int] = {}
        self.motion_var = motion_var
        self.gating = articulated if gating is None else gating
        self.gate = gate_threshold(gate)
        self.strikes: dict[int, int] = {}
        self.drift_window = check_range("drift_window", drift_window, 0, 1000, integer=True)
        self.innovations: dict[int, list] = {}
        self.reverted: list = []
        self.k = 0

    @property
    def pose(self) -> np.ndarray:
        return self.mu[:3].copy()

    @property
    def pose_cov(self) -> np.ndarray:
        return self.P[:3, :3].copy()

    # -- time update (robot and moving landmarks)
    def predict(self, u):
        """The time update with control ``u = (v, omega)``."""
        u = _check_control(u)
        n = self.n
        mu, P = self.mu, self.P
        xn, Gx, Gu = _motion_model(mu[:3], u, self.dt)
        mu[:3] = xn
        mu[2] = _wrap(mu[2])
        P[:3, :n] = Gx @ P[:3, :n]
        P[:n, :3] = P[:n, :3] @ Gx.T
        P[:3, :3] += Gu @ _control_noise(u, self.alphas) @ Gu.T
        for i, b in self.blocks.items():
            sl = slice(b.start, b.start + b.dim)
            if b.F is not None and b.Q is not None:
                mu[sl] = b.F @ mu[sl]
                P[sl, :n] = b.F @ P[sl, :n]
                P[:n, sl] = P[:n, sl] @ b.F.T
                P[sl, sl] += b.Q
            elif self.undecided_var > 0:
                P[sl, sl] += self.undecided_var * self._moving_probability(i) * np.eye(2)
        self.k += 1

    def _moving_probability(self, i: int) -> float:
        """1 - Algorithm 1's probability that ``i`` is static (1/2 before it has a say)."""
        est = self.models.estimators.get(i)
        probs = est.probabilities if est is not None else {}
        return 1.0 - probs["static"] if probs else 0.5

    # -- measurement update
    def update(self, ids, zs):
        """The measurement update with sightings ``zs`` ``(k, 2)`` (range, bearing) of landmarks ``ids`` ``(k,)``:
        ranges in ``[MIN_RANGE, MAX_RANGE]`` m, bearings finite (else an :class:`InputError`, the state untouched)."""
        ids, zs = _check_sightings(ids, zs)
        known = []
        for i, z in zip(ids, zs):
            if self.articulated and i not in self.models.verdict and self._learn(i, z):
                continue  # the sighting initialised the landmark in the state with its model
            if i in self.blocks:
                known.append((i, z))
            elif not self.articulated or not self.delayed:
                self._add_static(i, z)
        if known:
            self._fuse(known)

    def _learn(self, i: int, z) -> bool:
        """Algorithm 1 on sighting ``z`` of undecided landmark ``i``; once it decides a model other
        than the one ``i`` has in the state, ``i`` is re-initialised from ``z`` with it and True is
        returned."""
        m, Gx, Gz = _inverse_observation(self.mu[:3], z)
        Pm = Gz @ self.R1 @ Gz.T
        d = self.models.observe(i, m, Pm, self.k)
        b = self.blocks.get(i)
        if d is None or (b is not None and b.kind == d.kind):
            return False
        if b is not None:
            self._remove(i)
        if d.kind == "static":
            self._append(i, _Block("static", self.n, 2), m, Gx, Pm)
        else:
            self._add_moving(i, d, Gx, Pm)
        return True

    def _fuse(self, known):
        n = self.n
        mu, P = self.mu, self.P
        rows = []
        rejected = []
        for i, z in known:
            b = self.blocks[i]
            sl = slice(b.start, b.start + b.dim)
            pos, Jq = b.position(mu[sl])
            zh, Hx, Hm = _observe(mu[:3], pos)
            Hi = np.zeros((2, n))
            Hi[:, :3] = Hx
            Hi[:, sl] = Hm @ Jq
            yi = np.array([z[0] - zh[0], _wrap(z[1] - zh[1])])
            if self.gating:
                # validation gate: a landmark whose sightings keep failing it has the wrong model
                # (or started moving); it leaves the state
                idx = np.r_[0:3, b.start:b.start + b.dim]  # H is zero elsewhere
                Si = Hi[:, idx] @ P[np.ix_(idx, idx)] @ Hi[:, idx].T + self.R1
                fail = yi @ np.linalg.solve(Si, yi) > self.gate
                if not fail and self.drift_window > 1:
                    # the innovations of a consistent filter are white: their sum over the last
                    # sightings has the sum of their covariances; a landmark that drifts (a slow
                    # cart fused as static) adds up innovations of one sign
                    past = self.innovations.setdefault(i, [])
                    if len(past) >= self.drift_window - 1:
                        ys = yi + sum(y for y, _ in past)
                        Ss = Si + sum(S for _, S in past)
                        fail = ys @ np.linalg.solve(Ss, ys) > self.gate
                    if not fail:
                        past.append((yi, Si))
                        del past[:-(self.drift_window - 1)]
                if fail:
                    self.strikes[i] = self.strikes.get(i, 0) + 1
                    if self.strikes[i] >= 3:
                        rejected.append(i)
                    continue
                self.strikes[i] = 0
            rows.append((Hi, yi))
        if rows:
            m = len(rows)
            H = np.vstack([h for h, _ in rows])
            y = np.concatenate([v for _, v in rows])
            Pn = P[:n, :n]
            PHt = Pn @ H.T
            S = H @ PHt + np.kron(np.eye(m), self.R1)
            K = np.linalg.solve(S, PHt.T).T
            mu[:n] += K @ y
            mu[2] = _wrap(mu[2])
            Pn -= K @ PHt.T
            Pn[:] = 0.5 * (Pn + Pn.T)
        for i in rejected:
            self.reverted.append((i, self.k, self.blocks[i].kind))
            self._remove(i)
            # its model was wrong (or it started moving): Algorithm 1 learns it afresh; an
            # undecided one keeps its sightings, Algorithm 1 is still learning what it is
            if i in self.models.verdict:
                self.models.reset(i)

    def _remove(self, i: int):
        """Take landmark ``i`` out of the state (it re-enters at its next sighting, as Algorithm 1
        then says, or as static)."""
        b = self.blocks.pop(i)
        n, d, s0 = self.n, b.dim, b.start
        keep = np.r_[0:s0, s0 + d: n]
        self.mu[: n - d] = self.mu[keep]
        self.P[: n - d, : n - d] = self.P[np.ix_(keep, keep)]
        self.n = n - d
        for other in self.blocks.values():
            if other.start > s0:
                other.start -= d
        self.strikes.pop(i, None)
        self.innovations.pop(i, None)

    def _append(self, i, block: _Block, value, Gx_full, var_extra):
        """Add ``block`` at the end of the state: ``value`` (dim,), ``Gx_full`` (dim x 3) maps the
        robot's uncertainty, ``var_extra`` (dim x dim) is the block's own."""
        n = self.n
        d = len(value)
        if n + d > len(self.mu):  # (a row of P as long as needed: long rows slow every update)
            cap = max(n + d, len(self.mu) + len(self.mu) // 4)
            mu, P = np.zeros(cap), np.zeros((cap, cap))
            mu[:n], P[:n, :n] = self.mu[:n], self.P[:n, :n]
            self.mu, self.P = mu, P
        sl = slice(n, n + d)
        self.mu[sl] = value
        cross = Gx_full @ self.P[:3, :n]
        self.P[sl, :n] = cross
        self.P[:n, sl] = cross.T
        self.P[sl, sl] = Gx_full @ self.P[:3, :3] @ Gx_full.T + var_extra
        self.blocks[i] = block
        self.n = n + d
        self.decided_at[i] = self.k

    def _add_static(self, i, z):
        m, Gx, Gz = _inverse_observation(self.mu[:3], z)
        self._append(i, _Block("static", self.n, 2), m, Gx, Gz @ self.R1 @ Gz.T)

    def _add_moving(self, i, d: Decision, Gx, Pm):
        """Motion variables ``(q, q')`` of a decided moving landmark, from the current sighting."""
        assert d.joint is not None and d.dq_dm is not None
        Gq = d.dq_dm
        F, Q = d.joint.transition(self.dt, self.motion_var)
        if not self.joint_shift:
            b = _Block(d.kind, self.n, 2, d.joint)
            b.F, b.Q = F, Q
            self._append(i, b, np.array([d.q, d.rate]), np.vstack([Gq @ Gx, np.zeros(3)]),
                         np.diag([Gq @ Pm @ Gq, d.rate_var]))
            return
        # the joint was fitted to points seen from the robot's estimates: its place shares the
        # robot's uncertainty (like a static landmark's) plus the fit's own; with ``joint_shape``
        # its radius or direction is a state too, starting with the fit's covariance
        dim = 2 + len(d.shape_cov) if self.joint_shape and d.shape_cov is not None else 4
        b = _Block(d.kind, self.n, dim, d.joint)
        b.F, b.Q = np.eye(dim), np.zeros((dim, dim))
        b.F[:2, :2], b.Q[:2, :2] = F, Q
        extra = np.zeros((dim, dim))
        extra[0, 0], extra[1, 1] = Gq @ Pm @ Gq, d.rate_var
        if dim >= 5:
            extra[2:, 2:] = d.shape_cov
        else:
            extra[2:, 2:] = self.models.point_noise**2 * np.eye(2)
        Gfull = np.zeros((dim, 3))
        Gfull[2:4] = Gx
        self._append(i, b, np.r_[d.q, d.rate, np.zeros(dim - 2)], Gfull, extra)

    @property
    def kinds(self) -> dict[int, str]:
        """The model of each landmark in the state."""
        return {i: b.kind for i, b in self.blocks.items()}

    def landmark_positions(self) -> dict:
        return {i: b.position(self.mu[b.start: b.start + b.dim])[0].copy() for i, b in self.blocks.items()}
