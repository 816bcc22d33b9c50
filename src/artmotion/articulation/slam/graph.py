"""Articulated SLAM as a factor graph, solved incrementally with iSAM2 (Sections 4.6-4.7).

The same models as :mod:`~artmotion.articulation.slam.ekf`, as factors of a graph that GTSAM's iSAM2
keeps solved as it grows (one update per step):

* robot poses ``X(k)`` (``Pose2``), a prior on ``X(0)`` and one odometry factor per step: the
  velocity motion model's pose increment (Eq. 4.20-4.21) with the control noise carried through
  ``J_u`` (Eq. 4.23, 4.26), in the body frame of ``X(k)``;
* a static landmark: one ``Point2`` and one range-bearing factor (Eq. 4.24) per sighting;
* a moving landmark (articulated mode, once Algorithm 1 has decided it moves): its motion variables
  ``(q, q')`` at every step it is seen, consecutive ones tied by the Taylor model (Eq. 4.18) over the
  gap between sightings, each sighting a range-bearing factor through the joint's ``m(q)`` (Eq. 4.24,
  Jacobians Eq. 4.27-4.28). The joint's place as Algorithm 1 fitted it (from points seen from the pose
  estimates of the time) gets an offset variable, so that a moving landmark is no absolute reference.
  Once a landmark is known to move, its static factors leave the graph; with ``history`` the sightings
  Algorithm 1 learnt it from are re-attached to motion variables at their own steps (the smoother
  re-reads its past, which the filter cannot).

Landmarks are handled as in :class:`~artmotion.articulation.slam.ekf.EKFSlam` (``articulated=True``): a
new one enters at once as static while Algorithm 1 learns its model in parallel; a chi^2 validation
gate takes a landmark out of the graph after three failed sightings in a row, and it re-enters as a
fresh variable (gtsam's keys are not re-used).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from artmotion.articulation.slam.ekf import (
    _check_arguments,
    _check_control,
    _check_sightings,
    _control_noise,
    _inverse_observation,
    _motion_model,
    _observe,
    _wrap,
    gate_threshold,
)
from artmotion.articulation.slam.landmarks import Decision, Joint, LandmarkModels
from artmotion.errors import InputError, check_bool, check_range

__all__ = ["GraphSlam", "moving_observation", "taylor_gap"]


#: regulariser of the odometry covariance, which has rank 2 (m^2, rad^2): 1 mm a step sideways
_ODOMETRY_REG = 1e-6
#: regulariser of the Taylor model's ``Q`` (rank 1 for one step), relative to its trace: about what a
#: continuous white-noise acceleration would add (``dt^2 / 12`` at ``dt = 0.1``)
_TAYLOR_REG = 1e-3
#: std of the prior on a moving landmark's first joint coordinate (rad on a circle, m on a line)
_Q_PRIOR_STD = math.pi
#: beyond this many steps since a landmark's last sighting the gate takes the pose's marginal
_DRIFT_STEPS = 100


def _gtsam():
    """The ``gtsam`` module, or an :class:`InputError` that says how to install it."""
    try:
        import gtsam
    except ImportError as e:
        raise InputError("the factor-graph back end needs GTSAM: pip install 'artmotion[slam]'") from e
    return gtsam


def _rot(th: float) -> np.ndarray:
    c, s = math.cos(th), math.sin(th)
    return np.array([[c, -s], [s, c]])


def _tangent_to_world(th: float) -> np.ndarray:
    """``d (x, y, theta)`` in world coordinates from a ``Pose2`` tangent (body-frame) perturbation."""
    J = np.eye(3)
    J[:2, :2] = _rot(th)
    return J


def moving_observation(pose: np.ndarray, s: np.ndarray, offset: np.ndarray, joint: Joint, z: np.ndarray):
    """Residual ``h(x, m) - z`` of a sighting ``z = (range, bearing)`` of a moving landmark at
    ``m = m_joint(q) + offset`` (motion variables ``s = (q, q')``; ``offset`` shifts the joint as fitted)
    (Eq. 4.24, bearing wrapped to [-pi, pi)), and its Jacobians w.r.t. the ``Pose2`` tangent of ``pose``
    (body frame, 2 x 3; Eq. 4.27), ``s`` (2 x 2; Eq. 4.28 through ``dm/dq``) and ``offset`` (2 x 2)."""
    m, dm = joint.position(float(s[0]))
    zh, Hx, Hm = _observe(pose, m + offset)
    e = np.array([zh[0] - z[0], _wrap(zh[1] - z[1])])
    Hp = Hx @ _tangent_to_world(pose[2])
    Hs = np.zeros((2, 2))
    Hs[:, 0] = Hm @ dm
    return e, Hp, Hs, Hm


def taylor_gap(F: np.ndarray, Q: np.ndarray, g: int) -> tuple[np.ndarray, np.ndarray]:
    """The Taylor model (Eq. 4.18) of one step, ``(F, Q)``, composed over ``g`` steps:
    ``F^g`` and ``sum_j F^j Q F^j^T``."""
    Fg, Qg = np.eye(len(F)), np.zeros_like(Q)
    for _ in range(g):
        Fg, Qg = F @ Fg, F @ Qg @ F.T + Q
    return Fg, Qg


def _inv2(S: np.ndarray) -> np.ndarray:
    """Inverse of a 2 x 2 matrix (``np.linalg`` is slow on tiny ones, called per sighting)."""
    a, b, c, d = S[0, 0], S[0, 1], S[1, 0], S[1, 1]
    return np.array([[d, -b], [-c, a]]) / (a * d - b * c)


def _pose_array(p) -> np.ndarray:
    return np.array([p.x(), p.y(), p.theta()])


class _Track:
    """A landmark's incarnation in the graph: a static ``Point2`` (``key``) or motion variables
    ``(q, q')`` at the steps it was seen (``steps``, ``keys``) along ``joint``; ``factors``: its
    factors' indices in iSAM2."""

    __slots__ = ("kind", "joint", "F", "Q", "key", "offset", "steps", "keys", "factors", "pending", "P", "last",
                 "_gaps")

    def __init__(self, kind: str, key: int | None = None, joint: Joint | None = None,
                 transition: tuple[np.ndarray, np.ndarray] | None = None):
        self.kind, self.key, self.joint = kind, key, joint
        self.offset: int | None = None  # a moving one's joint offset variable
        self.F: np.ndarray | None = transition[0] if transition is not None else None
        self.Q: np.ndarray | None = transition[1] if transition is not None else None
        self.steps: list[int] = []
        self.keys: list[int] = []
        self.factors: list[int] = []
        self.pending = 0  # factors waiting for the next iSAM2 update
        self.P: np.ndarray | None = None  # covariance given the robot's path (static: m; moving: (q, q'))
        self.last = -1  # step of its latest sighting in the graph
        self._gaps: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def gap(self, g: int) -> tuple[np.ndarray, np.ndarray]:
        """``(F^g, Q_g)`` of the Taylor model over ``g`` steps (cached)."""
        if g not in self._gaps:
            assert self.F is not None and self.Q is not None
            self._gaps[g] = taylor_gap(self.F, self.Q, g)
        return self._gaps[g]


class GraphSlam:
    """Articulated SLAM as a factor graph solved by iSAM2, with the interface of
    :class:`~artmotion.articulation.slam.ekf.EKFSlam` (``predict(u)``, ``update(ids, zs)``, ``pose``,
    ``pose_cov``, ``landmark_positions()``) plus ``trajectory()``, the smoothed path.

    ``articulated=False`` is plain graph SLAM: every landmark static. ``gating`` applies the chi^2
    (2 dof) validation gate of :meth:`_admit`, failed by a consistent sighting with probability
    ``gate`` (1 %: chosen by leave-one-world-out). ``history`` re-attaches the sightings Algorithm 1
    learnt a landmark from to motion variables at their own steps once it is decided moving (off by
    default: no better paths in the simulated worlds, and less consistent where only moving landmarks
    are in view, as those sightings also placed the joint).
    ``joint_noise`` (m, default ``point_noise``): how far a moving landmark may stray from its path as
    Algorithm 1 fitted it, added to its sightings' noise. ``relinearize_threshold`` and
    ``relinearize_skip`` are iSAM2's. ``kinds``: each landmark in the graph, static or moving;
    ``decided_at``: the step of each landmark's latest decision by Algorithm 1.
    """

    def __init__(self, x0, dt: float, alphas, range_std: float, bearing_std: float, n_max: int,
                 articulated: bool = True, threshold: float = 0.75, min_samples: int = 7,
                 point_noise: float = 0.15, max_radius: float = 5.0, motion_var: float = 0.01,
                 accel: float | None = 0.1, gating: bool = True, history: bool = False,
                 joint_noise: float | None = None, relinearize_threshold: float = 0.1, relinearize_skip: int = 10,
                 gate: float = 0.01):
        x0, alphas, n_max, min_samples = _check_arguments(
            x0, dt, alphas, range_std, bearing_std, n_max, articulated=articulated, threshold=threshold,
            min_samples=min_samples, point_noise=point_noise, max_radius=max_radius, motion_var=motion_var,
            accel=accel, gate=gate)
        check_bool("gating", gating)
        check_bool("history", history)
        if joint_noise is not None:
            check_range("joint_noise", joint_noise, 0.0, math.inf, hi_open=True)
        check_range("relinearize_threshold", relinearize_threshold, 0.0, math.inf, hi_open=True)
        # (0 divides by zero inside iSAM2: the process dies of SIGFPE)
        relinearize_skip = check_range("relinearize_skip", relinearize_skip, 1, 10**9, integer=True)
        gtsam = _gtsam()
        self._gtsam: Any = gtsam
        self.dt, self.alphas = dt, alphas
        self.R1 = np.diag([range_std**2, bearing_std**2])
        # BearingRangeFactor2D's error is (bearing, range); the moving landmarks' is (range, bearing)
        self._br_noise = gtsam.noiseModel.Diagonal.Sigmas(np.array([bearing_std, range_std]))
        self._unit2 = gtsam.noiseModel.Unit.Create(2)
        self.articulated = articulated
        self.gating = gating
        self.history = history
        self.joint_noise = point_noise if joint_noise is None else joint_noise
        self.gate = gate_threshold(gate)
        self.motion_var = motion_var
        self.models = LandmarkModels(dt, threshold, min_samples, point_noise, max_radius, accel)
        self.decided_at: dict[int, int] = {}  # step of each landmark's latest decision
        self.strikes: dict[int, int] = {}
        self.reverted: list = []
        self.tracks: dict[int, _Track] = {}
        self._seen: dict[int, list[tuple[int, np.ndarray]]] = {}  # sightings Algorithm 1 has of each landmark
        self._next_key = 0

        params = gtsam.ISAM2Params()
        params.setRelinearizeThreshold(relinearize_threshold)
        params.relinearizeSkip = relinearize_skip
        self.isam = gtsam.ISAM2(params)
        self._new = gtsam.NonlinearFactorGraph()
        self._values = gtsam.Values()
        self._owners: list[_Track | None] = []
        self._remove: list[int] = []

        self.k = 0
        self._pose_value = gtsam.Pose2(*x0)
        self._pose = x0.copy()
        self._cov = np.eye(3) * 1e-6
        self._odometry: list[tuple[np.ndarray, np.ndarray]] = []  # per step: J_x and the motion noise
        self._values.insert(self._x(0), self._pose_value)
        self._add(gtsam.PriorFactorPose2(self._x(0), self._pose_value, gtsam.noiseModel.Isotropic.Sigma(3, 1e-3)))

    # -- keys and bookkeeping
    def _x(self, k: int) -> int:
        return self._gtsam.symbol("x", k)

    def _key(self, c: str) -> int:
        """A fresh variable key: gtsam variables are not re-used once their factors are removed."""
        self._next_key += 1
        return self._gtsam.symbol(c, self._next_key)

    def _add(self, factor, owner: _Track | None = None) -> None:
        self._new.add(factor)
        self._owners.append(owner)
        if owner is not None:
            owner.pending += 1

    @property
    def pose(self) -> np.ndarray:
        return self._pose.copy()

    @property
    def pose_cov(self) -> np.ndarray:
        """The latest pose's marginal covariance in world ``(x, y, theta)``."""
        return self._cov.copy()

    @property
    def kinds(self) -> dict[int, str]:
        return {i: t.kind for i, t in self.tracks.items()}

    # -- odometry
    def predict(self, u) -> None:
        """Odometry factor ``X(k) -> X(k+1)``: the pose increment of Eq. 4.20-4.21 from the origin,
        covariance ``J_u M J_u^T`` (Eq. 4.23, 4.26) in the body frame of ``X(k)`` (rank 2: a small
        regulariser keeps it invertible)."""
        u = _check_control(u)
        gtsam = self._gtsam
        inc, _, Gu = _motion_model(np.zeros(3), u, self.dt)
        M = _control_noise(u, self.alphas)
        J = _tangent_to_world(inc[2]).T  # X(k)'s frame -> the tangent at the increment
        cov = J @ Gu @ M @ Gu.T @ J.T + _ODOMETRY_REG * np.eye(3)
        odo = gtsam.Pose2(*inc)
        self._add(gtsam.BetweenFactorPose2(self._x(self.k), self._x(self.k + 1), odo,
                                           gtsam.noiseModel.Gaussian.Covariance(cov)))
        self._pose_value = self._pose_value.compose(odo)
        self._values.insert(self._x(self.k + 1), self._pose_value)
        # the prediction the EKF would make: the gate's pose uncertainty until the update
        _, Gx, Gw = _motion_model(self._pose, u, self.dt)
        self._cov = Gx @ self._cov @ Gx.T + Gw @ M @ Gw.T
        self._odometry.append((Gx, Gw @ M @ Gw.T))
        self._pose = _pose_array(self._pose_value)
        self.k += 1

    # -- sightings
    def update(self, ids, zs) -> None:
        """The sightings of step ``k``, then one iSAM2 update."""
        for i, z in zip(*_check_sightings(ids, zs)):
            if self.articulated and i not in self.models.verdict:
                self._seen.setdefault(i, []).append((self.k, z))
                if self._learn(i, z):
                    continue
            t = self.tracks.get(i)
            if t is None:
                self._add_static(i, z)
            elif self._admit(i, t, z):
                self._sighting(t, z)
        self._solve()

    def _solve(self) -> None:
        # the variables of the new factors eliminated last (as iSAM2 does by default), the newest pose
        # the very last: in the root clique, its marginal is cheap
        # (CCOLAMD takes group numbers below the number of variables it orders: with the odometry
        # factor alone, as few as two)
        keys = self._new.keyVector()
        last = self._gtsam.KeyGroupMap()
        last.insert2(self._x(self.k), 2 if len(keys) > 2 else 1)
        for key in keys:
            last.insert2(key, 1)  # (insert2 keeps a key's first group)
        res = self.isam.update(self._new, self._values, self._remove, last)
        for idx, owner in zip(res.getNewFactorsIndices(), self._owners):
            if owner is not None:
                owner.factors.append(int(idx))
                owner.pending = 0
        gtsam = self._gtsam
        self._new, self._values = gtsam.NonlinearFactorGraph(), gtsam.Values()
        self._owners, self._remove = [], []
        key = self._x(self.k)
        self._pose_value = self.isam.calculateEstimatePose2(key)
        self._pose = _pose_array(self._pose_value)
        J = _tangent_to_world(self._pose[2])
        # its marginal as a conditional without parents (QR: 3x faster than iSAM2's marginalCovariance)
        P = J @ np.linalg.inv(self.isam.marginalFactor(key, self._gtsam.EliminateQR).information()) @ J.T
        self._cov = 0.5 * (P + P.T)

    def _learn(self, i: int, z: np.ndarray) -> bool:
        """Algorithm 1 on sighting ``z`` of undecided landmark ``i`` (as ``EKFSlam._learn``); True if
        the sighting is taken care of (the landmark entered the graph with it)."""
        m, _, Gz = _inverse_observation(self._pose, z)
        d = self.models.observe(i, m, Gz @ self.R1 @ Gz.T, self.k)
        if d is None:
            return False
        self.decided_at[i] = self.k
        if d.kind == "static":
            if i not in self.tracks:
                self._add_static(i, z)
                return True
            return False
        if i in self.tracks:
            self._drop(i, restart=False)
        self._add_moving(i, d, z)
        return True

    def _add_static(self, i: int, z: np.ndarray) -> None:
        """Landmark ``i`` enters the graph as static (a fresh ``Point2``) with sighting ``z``."""
        t = _Track("static", self._key("l"))
        self.tracks[i] = t
        self._values.insert(t.key, _inverse_observation(self._pose, z)[0])
        self._sighting(t, z)

    def _sighting(self, t: _Track, z: np.ndarray, k: int | None = None, init: np.ndarray | None = None) -> None:
        """Factors of sighting ``z`` at step ``k`` (default: now) of track ``t``; a moving one gets motion
        variables at ``k`` (initial value ``init``, default: the Taylor prediction from its last ones).
        Also refines the track's covariance given the path, ``t.P``, with the sighting (the gate's)."""
        gtsam = self._gtsam
        if k is None or k == self.k:
            k, pose = self.k, self._pose
        else:
            pose = _pose_array(self.isam.calculateEstimatePose2(self._x(k)))
        xk = self._x(k)
        t.last = max(t.last, k)
        if t.joint is None:
            self._add(gtsam.BearingRangeFactor2D(xk, t.key, gtsam.Rot2.fromAngle(float(z[1])), float(z[0]),
                                                 self._br_noise), t)
            _, _, H = _observe(pose, self._estimate(t.key, point=True))
            if t.P is None:  # the first sighting: the inverse observation's covariance
                Hi = _inv2(H)
                t.P = Hi @ self.R1 @ Hi.T
                return
            R = self.R1
        else:
            key = self._key("s")
            if t.keys:
                Fg, Qg = t.gap(k - t.steps[-1])
                if init is None:
                    init = Fg @ self._estimate(t.keys[-1])
                self._add(self._taylor_factor(t.keys[-1], key, Fg, Qg), t)
                t.P = Fg @ t.P @ Fg.T + Qg
            assert init is not None and t.P is not None
            self._values.insert(key, np.asarray(init, dtype=float))
            t.steps.append(k)
            t.keys.append(key)
            _, _, H, Hm = moving_observation(pose, init, self._estimate(t.offset, point=True), t.joint, z)
            R = self.R1 + self.joint_noise**2 * Hm @ Hm.T  # the path as fitted is known to joint_noise
            self._add(self._observation_factor(xk, key, t.offset, t.joint, z, R), t)
        PHt = t.P @ H.T
        P = t.P - PHt @ _inv2(H @ PHt + R) @ PHt.T
        t.P = 0.5 * (P + P.T)

    def _estimate(self, key: int | None, point: bool = False) -> np.ndarray:
        """Current estimate of a landmark variable (``Point2`` with ``point``, else ``(q, q')``), be it
        in the graph or waiting for the next update."""
        assert key is not None
        if self._values.exists(key):
            return self._values.atPoint2(key) if point else self._values.atVector(key)
        return self.isam.calculateEstimatePoint2(key) if point else self.isam.calculateEstimateVector(key)

    def _taylor_factor(self, ka: int, kb: int, Fg: np.ndarray, Qg: np.ndarray):
        """``s_b - F^g s_a ~ N(0, Q_g)`` (Eq. 4.18 over a gap of g steps): linear, so a whitened
        Jacobian factor (about the origin) in a linear container, exact wherever it is relinearised."""
        gtsam = self._gtsam
        Qg = Qg + _TAYLOR_REG * np.trace(Qg) * np.eye(2)
        W = np.linalg.inv(np.linalg.cholesky(Qg))
        jf = gtsam.JacobianFactor(ka, -W @ Fg, kb, W, np.zeros(2), self._unit2)
        lin = gtsam.Values()
        lin.insert(ka, np.zeros(2))
        lin.insert(kb, np.zeros(2))
        return gtsam.LinearContainerFactor(jf, lin)

    def _observation_factor(self, xk: int, sk: int, ok: int | None, joint: Joint, z: np.ndarray, R: np.ndarray):
        """A sighting of a moving landmark: Eq. 4.24 through ``m(q) + offset``, Jacobians Eq. 4.27-4.28."""
        assert ok is not None
        z = np.array(z, dtype=float)

        def error(this, values, H):
            e, Hp, Hs, Ho = moving_observation(_pose_array(values.atPose2(xk)), values.atVector(sk),
                                               values.atPoint2(ok), joint, z)
            if H is not None:
                H[0], H[1], H[2] = Hp, Hs, Ho
            return e

        return self._gtsam.CustomFactor(self._gtsam.noiseModel.Gaussian.Covariance(R), [xk, sk, ok], error)

    def _add_moving(self, i: int, d: Decision, z: np.ndarray) -> None:
        """Motion variables of landmark ``i``, decided moving now: its current sighting (initialised
        from the decision) and, with ``history``, its earlier sightings at their own steps."""
        assert d.joint is not None
        joint = d.joint
        t = _Track(d.kind, joint=joint, transition=joint.transition(self.dt, self.motion_var))
        t.P = np.diag([1e2, max(d.rate_var, 1e-6)])  # q: unknown until the first sighting
        self.tracks[i] = t
        # the joint's place, fitted to points seen from the pose estimates, is as uncertain as they
        # were: an offset variable (else the joint would be an absolute reference for the robot)
        t.offset = self._key("o")
        self._values.insert(t.offset, np.zeros(2))
        cov = self._cov[:2, :2] + self.models.point_noise**2 / max(len(self._seen.get(i, [])), 1) * np.eye(2)
        if joint.kind == "prismatic" and joint.direction is not None:
            # along its line a shift only renames q (a freedom the sightings cannot fix): held at 0
            # within the point noise, only the shift across the line left to the robot's uncertainty
            # (with the robot's whole covariance the pair was nearly indeterminate once the robot was
            # lost, and iSAM2 stopped)
            u = np.asarray(joint.direction, float) / np.linalg.norm(joint.direction)
            n = np.array([-u[1], u[0]])
            cov = self.models.point_noise**2 * np.outer(u, u) + float(n @ cov @ n) * np.outer(n, n)
        self._add(self._gtsam.PriorFactorPoint2(t.offset, np.zeros(2), self._gtsam.noiseModel.Gaussian.Covariance(cov)), t)
        past = self._seen.get(i, [])[:-1] if self.history else []
        if past:
            qs = [d.q]
            for k, zk in reversed(past):  # initial q from the sighting on the joint, unwrapped backwards
                m = _inverse_observation(_pose_array(self.isam.calculateEstimatePose2(self._x(k))), zk)[0]
                q = joint.coordinate(m)
                if joint.kind == "revolute":
                    q += 2 * np.pi * round((qs[-1] - q) / (2 * np.pi))
                qs.append(q)
            for (k, zk), q in zip(past, reversed(qs[1:])):
                self._sighting(t, zk, k, np.array([q, d.rate]))
        self._sighting(t, z, self.k, np.array([d.q, d.rate]))
        # the rate Algorithm 1 fitted: a prior on q' (q is left to the sightings: a prior of a half-turn,
        # or pi metres along a line, is nothing beside one sighting; 1e3 was, and with the Taylor
        # factors' regularised noise it left iSAM2 an indeterminate system in a moving-only run)
        sig = np.array([_Q_PRIOR_STD, math.sqrt(max(d.rate_var, 1e-6))])
        self._add(self._gtsam.PriorFactorVector(t.keys[-1], np.array([d.q, d.rate]),
                                                self._gtsam.noiseModel.Diagonal.Sigmas(sig)), t)

    # -- validation gate
    def _admit(self, i: int, t: _Track, z: np.ndarray) -> bool:
        """The chi^2 gate on sighting ``z`` of landmark ``i`` already in the graph (always True without
        ``gating``); a third failure in a row takes ``i`` out of the graph.

        Innovation covariance ``S = H_x P_x H_x^T + H_m P_m H_m^T + R`` (Eq. 4.27-4.28) of the
        landmark relative to the robot: ``P_m`` the landmark's covariance given the robot's path
        (``t.P``), ``P_x`` how far the robot may have drifted since it last saw the landmark
        (:meth:`_drift`). iSAM2's own marginals would be too slow (~10 ms a pose, up to 0.4 s a
        landmark at 1000 landmarks) and absolute: the pose's marginal, strongly correlated with the
        landmark's, lets sightings of a slowly moving landmark through."""
        if not self.gating:
            return True
        if t.joint is None:
            zh, Hx, H = _observe(self._pose, self._estimate(t.key, point=True))
            P = t.P
        else:
            Fg, Qg = t.gap(self.k - t.steps[-1])
            s = Fg @ self._estimate(t.keys[-1])
            m, dm = t.joint.position(float(s[0]))
            zh, Hx, Hm = _observe(self._pose, m + self._estimate(t.offset, point=True))
            H = np.column_stack([Hm @ dm, np.zeros(2)])
            P = Fg @ t.P @ Fg.T + Qg
        y = np.array([z[0] - zh[0], _wrap(z[1] - zh[1])])
        S = Hx @ self._drift(t.last) @ Hx.T + H @ P @ H.T + self.R1
        if y @ _inv2(S) @ y <= self.gate:
            self.strikes[i] = 0
            return True
        self.strikes[i] = self.strikes.get(i, 0) + 1
        if self.strikes[i] >= 3:
            # a decided landmark's model was wrong (or it started moving): learn it afresh; an
            # undecided one keeps its sightings, Algorithm 1 is still learning what it is
            self._drop(i, restart=i in self.models.verdict)
        return False

    def _drift(self, a: int) -> np.ndarray:
        """Covariance of the robot's motion from step ``a`` to now (the EKF prediction from a known pose
        at ``a``, Eq. 4.25-4.26; at most the pose's marginal, which it is after a long gap): how far the
        robot may have drifted from where it last saw a landmark."""
        if self.k - a > _DRIFT_STEPS:
            return self._cov
        P = np.zeros((3, 3))
        for Gx, Q in self._odometry[a:self.k]:
            P = Gx @ P @ Gx.T + Q
        return P if np.trace(P) < np.trace(self._cov) else self._cov

    def _drop(self, i: int, restart: bool = True) -> None:
        """Take landmark ``i``'s factors out of the graph (its variables go with them); with
        ``restart``, Algorithm 1 starts afresh on it."""
        t = self.tracks.pop(i)
        assert t.pending == 0, "a landmark leaves the graph only between updates"
        self._remove.extend(t.factors)
        # iSAM2 keeps a variable whose factors are all removed: a weak prior at its estimate keeps it
        # determined and tied to nothing else (without, an indeterminate system near it stopped a run)
        gtsam = self._gtsam
        weak = gtsam.noiseModel.Isotropic.Sigma(2, 1e3)
        points = [k for k in (t.key, t.offset) if k is not None]
        for key, point in [(k, True) for k in points] + [(k, False) for k in t.keys]:
            prior = gtsam.PriorFactorPoint2 if point else gtsam.PriorFactorVector
            self._new.add(prior(key, self._estimate(key, point=point), weak))
            self._owners.append(None)
        self.strikes.pop(i, None)
        if restart:
            self.models.reset(i)
            self._seen.pop(i, None)
            self.reverted.append((i, self.k, t.kind))

    # -- results
    def trajectory(self) -> np.ndarray:
        """The smoothed estimate of every pose ``X(0..k)``, (k+1, 3)."""
        est = self.isam.calculateEstimate()
        return np.array([_pose_array(est.atPose2(self._x(k))) for k in range(self.k + 1)])

    def landmark_positions(self) -> dict[int, np.ndarray]:
        """Current position of each landmark in the graph (a moving one's predicted to now)."""
        out = {}
        for i, t in self.tracks.items():
            if t.joint is None:
                out[i] = np.asarray(self.isam.calculateEstimatePoint2(t.key), dtype=float).copy()
            else:
                g = self.k - t.steps[-1]
                s = self._estimate(t.keys[-1])
                s = t.gap(g)[0] @ s if g > 0 else s
                out[i] = t.joint.position(float(s[0]))[0] + self._estimate(t.offset, point=True)
        return out
