"""EKF SLAM and Articulated EKF SLAM (Sections 4.6-4.7, Algorithm 2), with a simulator.

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
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from artmotion.articulation.online import OnlineEstimator
from artmotion.errors import InputError
from artmotion.filters import taylor_model

__all__ = [
    "motion_model",
    "control_noise",
    "observe",
    "World",
    "make_world",
    "simulate",
    "EKFSlam",
    "run_slam",
    "pose_errors",
    "monte_carlo",
    "plot_run",
]


def _wrap(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def motion_model(x: np.ndarray, u, dt: float):
    """Eq. 4.20 (4.21 when ``omega ~ 0``): next pose, ``J_x`` (Eq. 4.25) and ``J_u`` (Eq. 4.26)."""
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
    """``M_k`` of Eq. 4.23."""
    v, w = u
    a1, a2, a3, a4 = alphas
    return np.diag([a1 * v * v + a2 * w * w, a3 * v * v + a4 * w * w])


def observe(x: np.ndarray, m: np.ndarray):
    """Eq. 4.24 and its Jacobians: ``z = (range, bearing)``, ``J_x`` (Eq. 4.27), ``J_m`` (Eq. 4.28)."""
    dx, dy = m[0] - x[0], m[1] - x[1]
    q = dx * dx + dy * dy
    sq = math.sqrt(q)
    z = np.array([sq, _wrap(math.atan2(dy, dx) - x[2])])
    Hx = np.array([[-dx / sq, -dy / sq, 0.0], [dy / q, -dx / q, -1.0]])
    Hm = np.array([[dx / sq, dy / sq], [-dy / q, dx / q]])
    return z, Hx, Hm


# ---------------------------------------------------------------- world and simulator
@dataclass
class World:
    """Point landmarks: ``static`` (n, 2) plus moving ones ``(kind, params)``.

    prismatic params: ``origin, direction, amplitude, omega``: ``origin + A sin(omega t) d``;
    revolute params: ``centre, radius, omega, phase``: ``centre + r (cos, sin)(phase + omega t)``.
    """

    static: np.ndarray
    moving: list = field(default_factory=list)

    @property
    def kinds(self) -> list:
        return ["static"] * len(self.static) + [k for k, _ in self.moving]

    def positions(self, t: float) -> np.ndarray:
        out = [self.static]
        for kind, p in self.moving:
            if kind == "prismatic":
                out.append((np.asarray(p["origin"])
                            + p["amplitude"] * math.sin(p["omega"] * t) * np.asarray(p["direction"]))[None])
            else:
                a = p["phase"] + p["omega"] * t
                out.append((np.asarray(p["centre"]) + p["radius"] * np.array([math.cos(a), math.sin(a)]))[None])
        return np.concatenate(out, axis=0)


def make_world(n_landmarks: int = 42, n_prismatic: int = 1, n_revolute: int = 1, radius: float = 10.0,
               seed: int = 0) -> World:
    """Landmarks scattered in a ring around the robot's circular path (radius ``radius``); the moving
    ones sit close to the path so the robot sees them often."""
    n_static = n_landmarks - n_prismatic - n_revolute
    if n_static < 0 or min(n_prismatic, n_revolute) < 0:
        raise InputError("landmark counts must be non-negative and add up to at most --landmarks")
    rng = np.random.default_rng(seed)
    ang = rng.uniform(0, 2 * np.pi, n_static)
    rad = radius + rng.choice([-1.0, 1.0], n_static) * rng.uniform(1.5, 4.0, n_static)
    static = np.column_stack([rad * np.cos(ang), rad * np.sin(ang)])
    moving = []
    for i in range(n_prismatic):
        a = 2 * np.pi * (i + 0.25) / max(n_prismatic, 1)
        c = (radius + 3.0) * np.array([math.cos(a), math.sin(a)])
        d = np.array([-math.sin(a), math.cos(a)])
        moving.append(("prismatic", {"origin": c, "direction": d, "amplitude": 3.0, "omega": 0.3}))
    for i in range(n_revolute):
        a = 2 * np.pi * (i + 0.6) / max(n_revolute, 1)
        c = (radius + 3.0) * np.array([math.cos(a), math.sin(a)])
        moving.append(("revolute", {"centre": c, "radius": 2.0, "omega": 0.3, "phase": a}))
    return World(static, moving)


@dataclass
class SimConfig:
    dt: float = 0.1
    v: float = 1.0
    w: float = 0.1
    alphas: tuple = (0.05, 0.005, 0.005, 0.05)
    range_std: float = 0.1
    bearing_std: float = math.radians(1.0)
    max_range: float = 10.0
    fov: float = math.radians(120.0)


def simulate(world: World, steps: int, cfg: SimConfig | None = None, seed: int = 0, radius: float = 10.0) -> dict:
    """Drive the robot around a circle (commanded ``v, w``) with noisy execution; observe landmarks
    in range and field of view. Returns ``poses`` (steps+1, 3), ``controls`` (steps, 2),
    ``observations`` (list per step of ``(ids, z)``) and ``landmarks`` (steps+1, L, 2)."""
    cfg = cfg or SimConfig()
    rng = np.random.default_rng(seed)
    x = np.array([radius, 0.0, math.pi / 2])
    poses = [x.copy()]
    lms = [world.positions(0.0)]
    obs = []
    u = np.array([cfg.v, cfg.w])
    for k in range(steps):
        M = control_noise(u, cfg.alphas)
        ut = u + rng.normal(0.0, np.sqrt(np.diag(M)))
        x, _, _ = motion_model(x, ut, cfg.dt)
        x[2] = _wrap(x[2])
        t = (k + 1) * cfg.dt
        L = world.positions(t)
        d = L - x[:2]
        rng_ = np.hypot(d[:, 0], d[:, 1])
        brg = _wrap(np.arctan2(d[:, 1], d[:, 0]) - x[2])
        vis = np.flatnonzero((rng_ < cfg.max_range) & (np.abs(brg) < cfg.fov / 2))
        z = np.column_stack([rng_[vis] + rng.normal(0, cfg.range_std, len(vis)),
                             _wrap(brg[vis] + rng.normal(0, cfg.bearing_std, len(vis)))])
        obs.append((vis, z))
        poses.append(x.copy())
        lms.append(L)
    return {"poses": np.array(poses), "controls": np.tile(u, (steps, 1)), "observations": obs,
            "landmarks": np.array(lms), "dt": cfg.dt, "config": cfg}


# ---------------------------------------------------------------- the filters
class _Block:
    """A landmark's slice of the state and how it maps to a 2-D position."""

    __slots__ = ("kind", "start", "dim", "origin", "direction", "centre", "radius", "F", "Q")

    # set when the landmark is given a model (prismatic: origin, direction; revolute: centre, radius)
    origin: np.ndarray
    direction: np.ndarray
    centre: np.ndarray
    radius: float
    F: np.ndarray | None
    Q: np.ndarray | None

    def __init__(self, kind, start, dim):
        self.kind, self.start, self.dim = kind, start, dim
        self.F = self.Q = None

    def position(self, s: np.ndarray):
        """``m_j`` and ``J_{m(t)}^{m_j}`` (2 x dim) from the block's state ``s``."""
        if self.kind == "static":
            return s[:2], np.eye(2)
        q = s[0]
        J = np.zeros((2, self.dim))
        if self.kind == "prismatic":
            J[:, 0] = self.direction
            return self.origin + q * self.direction, J
        c, sn = math.cos(q), math.sin(q)
        J[:, 0] = self.radius * np.array([-sn, c])
        return self.centre + self.radius * np.array([c, sn]), J


class EKFSlam:
    """EKF SLAM; ``articulated=True`` gives Articulated EKF SLAM (Algorithm 2)."""

    def __init__(self, x0, dt: float, alphas, range_std: float, bearing_std: float, n_max: int,
                 articulated: bool = False, threshold: float = 0.75, min_samples: int = 7,
                 point_noise: float = 0.15, max_radius: float = 5.0, motion_var: float = 0.01,
                 accel: float | None = 0.1, gating: bool | None = None):
        self.dt = dt
        self.alphas = alphas
        self.R1 = np.diag([range_std**2, bearing_std**2])
        self.articulated = articulated
        cap = 3 + 2 * n_max
        self.mu = np.zeros(cap)
        self.P = np.zeros((cap, cap))
        self.mu[:3] = x0
        self.P[:3, :3] = np.eye(3) * 1e-6
        self.n = 3
        self.blocks: dict = {}
        self.estimators: dict = {}
        self.decided_at: dict = {}
        self.first_seen: dict = {}
        self.threshold, self.min_samples = threshold, min_samples
        self.point_noise, self.max_radius, self.motion_var = point_noise, max_radius, motion_var
        self.accel = accel
        self.gating = articulated if gating is None else gating
        self.gate = 13.8  # chi^2, 2 degrees of freedom, 0.1 %
        self.strikes: dict = {}
        self.rejected: list = []
        self.reverted: list = []
        self.k = 0

    # -- time update (robot and moving landmarks)
    def predict(self, u):
        n = self.n
        mu, P = self.mu, self.P
        xn, Gx, Gu = motion_model(mu[:3], u, self.dt)
        mu[:3] = xn
        mu[2] = _wrap(mu[2])
        P[:3, :n] = Gx @ P[:3, :n]
        P[:n, :3] = P[:n, :3] @ Gx.T
        P[:3, :3] += Gu @ control_noise(u, self.alphas) @ Gu.T
        for b in self.blocks.values():
            if b.F is not None:
                sl = slice(b.start, b.start + b.dim)
                mu[sl] = b.F @ mu[sl]
                P[sl, :n] = b.F @ P[sl, :n]
                P[:n, sl] = P[:n, sl] @ b.F.T
                P[sl, sl] += b.Q
        self.k += 1

    # -- measurement update
    def update(self, ids, zs):
        ids = np.asarray(ids, dtype=int)
        if len(ids) == 0:
            return
        known = [(i, z) for i, z in zip(ids, zs) if i in self.blocks]
        new = [(i, z) for i, z in zip(ids, zs) if i not in self.blocks]
        if known:
            self._fuse(known)
        for i, z in new:
            if not self.articulated:
                self._add_static(i, z)
            else:
                self._algorithm1(i, z)

    def _fuse(self, known):
        n = self.n
        mu, P = self.mu, self.P
        rows = []
        for i, z in known:
            b = self.blocks[i]
            sl = slice(b.start, b.start + b.dim)
            pos, Jq = b.position(mu[sl])
            zh, Hx, Hm = observe(mu[:3], pos)
            Hi = np.zeros((2, n))
            Hi[:, :3] = Hx
            Hi[:, sl] = Hm @ Jq
            yi = np.array([z[0] - zh[0], _wrap(z[1] - zh[1])])
            if self.gating:
                # validation gate: a decided landmark whose observations keep failing it was
                # decided wrongly (or started moving); it goes back to Algorithm 1
                Si = Hi @ P[:n, :n] @ Hi.T + self.R1
                if yi @ np.linalg.solve(Si, yi) > self.gate:
                    self.strikes[i] = self.strikes.get(i, 0) + 1
                    if self.strikes[i] >= 3:
                        self.rejected.append(i)
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
        for i in self.rejected:
            self._remove(i)
        self.rejected = []

    def _remove(self, i):
        """Take landmark ``i`` out of the state; Algorithm 1 starts afresh on it."""
        b = self.blocks.pop(i)
        n, d, s0 = self.n, b.dim, b.start
        keep = np.r_[0:s0, s0 + d: n]
        self.mu[: n - d] = self.mu[keep]
        self.P[: n - d, : n - d] = self.P[np.ix_(keep, keep)]
        self.n = n - d
        for other in self.blocks.values():
            if other.start > s0:
                other.start -= d
        self.estimators.pop(i, None)
        self.strikes.pop(i, None)
        self.reverted.append((i, self.k, b.kind))

    def _inverse(self, z):
        """World point of observation ``z`` and its Jacobians w.r.t. robot and observation."""
        x = self.mu[:3]
        a = x[2] + z[1]
        c, s = math.cos(a), math.sin(a)
        m = np.array([x[0] + z[0] * c, x[1] + z[0] * s])
        Gx = np.array([[1.0, 0.0, -z[0] * s], [0.0, 1.0, z[0] * c]])
        Gz = np.array([[c, -z[0] * s], [s, z[0] * c]])
        return m, Gx, Gz

    def _append(self, i, kind, value, Gx_full, var_extra):
        """Add a block: ``value`` (dim,), ``Gx_full`` (dim x 3) maps robot uncertainty, ``var_extra``
        (dim x dim) its own uncertainty."""
        n = self.n
        d = len(value)
        sl = slice(n, n + d)
        self.mu[sl] = value
        cross = Gx_full @ self.P[:3, :n]
        self.P[sl, :n] = cross
        self.P[:n, sl] = cross.T
        self.P[sl, sl] = Gx_full @ self.P[:3, :3] @ Gx_full.T + var_extra
        b = _Block(kind, n, d)
        self.blocks[i] = b
        self.n = n + d
        self.decided_at[i] = self.k
        return b

    def _add_static(self, i, z):
        m, Gx, Gz = self._inverse(z)
        self._append(i, "static", m, Gx, Gz @ self.R1 @ Gz.T)

    def _algorithm1(self, i, z):
        m, Gx, Gz = self._inverse(z)
        est = self.estimators.get(i)
        if est is None:
            # hinges in this world are metres wide (the radius prior on its scale); landmarks are seen for
            # short stretches, so configurations are re-fitted every 10 % of samples
            est = OnlineEstimator(threshold=self.threshold, min_samples=self.min_samples, dim=2,
                                  noise=None, noise_floor=self.point_noise,
                                  radius_range=(0.2 * self.max_radius, self.max_radius), refit_growth=1.1,
                                  accel=self.accel)
            self.estimators[i] = est
            self.first_seen[i] = self.k
        # the point's noise: the observation noise carried to the world frame (the robot's own
        # uncertainty is common to all landmarks and mostly slow drift, not white noise)
        Pm = Gz @ self.R1 @ Gz.T
        est.noise = max(est.noise or 0.0, self.point_noise, math.sqrt(float(np.linalg.eigvalsh(Pm)[-1])))
        est.update(m, float(self.k))  # time in steps: the Taylor models work per sample
        probs = est.probabilities
        if not probs:
            return
        name = max(probs, key=probs.__getitem__)
        if probs[name] <= self.threshold:
            return
        if name == "static":
            self._add_static(i, z)
            return
        assert est.filters is not None  # a moving model leads only once the filters were fit
        f = est.filters[est.names.index(name)]
        model = f.model
        model.fit(np.asarray(est.X))
        # motion variable from the current sighting: q = G(m), dq/dm = J^+ (Eq. 4.28 inverted)
        q = float(model.motion(np.array([[m[0], m[1], 0.0]]))[0, 0])
        if name == "revolute":
            qs = model.motion(np.asarray(est.X))[:, 0]
            q = q + 2 * np.pi * round((qs[-1] - q) / (2 * np.pi))
        qdot, vdot = f.velocity(np.asarray(est.X), np.asarray(est.T))
        qdot, vdot = qdot / self.dt, vdot / self.dt**2  # per step -> per second
        if name == "revolute":
            # the circle lies in z = 0: express the angle in world x, y (world angle = atan2 of
            # (point - centre)), so the block's state is (phi, phi') with phi = phi0 + sgn q
            e1, e2 = model.u, model.v
            sgn = 1.0 if np.cross(e1, e2)[2] > 0 else -1.0
            q, qdot = math.atan2(e1[1], e1[0]) + sgn * q, sgn * qdot
            Jq = np.array([-math.sin(q), math.cos(q)]) * float(model.radius)
        else:
            Jq = model.jacobian(np.array([q]))[:2, 0]
        Gq = Jq / (Jq @ Jq)
        Gx_full = np.vstack([Gq @ Gx, np.zeros(3)])
        extra = np.diag([Gq @ Pm @ Gq, vdot])
        b = self._append(i, name, np.array([q, qdot]), Gx_full, extra)
        if name == "prismatic":
            b.origin, b.direction = model.origin[:2].copy(), model.direction[:2] / np.linalg.norm(model.direction[:2])
            scale = 1.0
        else:
            b.centre, b.radius = model.centre[:2].copy(), float(model.radius)
            scale = 1.0 / b.radius**2
        b.F, b.Q = taylor_model(2, self.dt, self.motion_var * scale, 1)

    def landmark_positions(self) -> dict:
        return {i: b.position(self.mu[b.start: b.start + b.dim])[0].copy() for i, b in self.blocks.items()}


def run_slam(sim: dict, articulated: bool, **kwargs) -> dict:
    """Run one filter over a simulated run; returns estimated ``poses`` (steps+1, 3), covariance
    traces, decisions and the filter."""
    cfg = sim["config"]
    n_max = sim["landmarks"].shape[1]
    f = EKFSlam(sim["poses"][0], sim["dt"], cfg.alphas, cfg.range_std, cfg.bearing_std, n_max,
                articulated=articulated, **kwargs)
    poses = [f.mu[:3].copy()]
    covs = [f.P[:3, :3].copy()]
    for k, u in enumerate(sim["controls"]):
        f.predict(u)
        ids, z = sim["observations"][k]
        f.update(ids, z)
        poses.append(f.mu[:3].copy())
        covs.append(f.P[:3, :3].copy())
    return {"poses": np.array(poses), "covs": np.array(covs), "filter": f}


def pose_errors(est: np.ndarray, true: np.ndarray, lag: int = 0, stride: int = 5) -> dict:
    """Errors of robot pose increments (the relative pose error of [91]) and absolute errors.

    An increment is the pose of step ``j`` seen from step ``i``; its error is the difference between
    the estimated and the true increment (translation: Euclidean norm; rotation: absolute angle).
    ``lag > 0`` averages over increments of ``lag`` steps; ``lag = 0`` over all pairs ``i < j``
    (every ``stride``-th pose), which weighs local and global consistency alike.
    """
    est = np.asarray(est, dtype=float)
    true = np.asarray(true, dtype=float)
    if lag > 0:
        i = np.arange(0, len(est) - lag)
        j = i + lag
    else:
        idx = np.arange(0, len(est), stride)
        i, j = np.triu_indices(len(idx), k=1)
        i, j = idx[i], idx[j]

    def inc(p):
        d = p[j, :2] - p[i, :2]
        c, s = np.cos(p[i, 2]), np.sin(p[i, 2])
        local = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
        return local, _wrap(p[j, 2] - p[i, 2])

    le, ae = inc(est)
    lt, at = inc(true)
    return {
        "translation_error": float(np.mean(np.linalg.norm(le - lt, axis=1))),
        "rotation_error": float(np.mean(np.abs(_wrap(ae - at)))),
        "absolute_translation_error": float(np.mean(np.linalg.norm(est[:, :2] - true[:, :2], axis=1))),
        "absolute_rotation_error": float(np.mean(np.abs(_wrap(est[:, 2] - true[:, 2])))),
    }


def monte_carlo(runs: int = 20, steps: int = 600, landmarks: int = 42, prismatic: int = 1, revolute: int = 1,
                seed: int = 0, lag: int = 0, keep_last: bool = False) -> dict:
    """Average errors of Articulated EKF SLAM and EKF SLAM over ``runs`` simulated runs (Table 4.2)."""
    if runs < 1 or steps < 2:
        raise InputError("need at least one run of at least two steps")
    acc: dict[str, list[dict[str, float]]] = {"articulated": [], "ekf": [], "ekf_gated": []}
    last = None
    for r in range(runs):
        world = make_world(landmarks, prismatic, revolute, seed=seed + 1000 * r)
        sim = simulate(world, steps, seed=seed + 1000 * r + 1)
        res = {}
        for name, art, gate in (("articulated", True, True), ("ekf", False, False), ("ekf_gated", False, True)):
            out = run_slam(sim, art, gating=gate)
            e = pose_errors(out["poses"], sim["poses"], lag=lag)
            e1 = pose_errors(out["poses"], sim["poses"], lag=1)
            e["step_translation_error"], e["step_rotation_error"] = e1["translation_error"], e1["rotation_error"]
            acc[name].append(e)
            res[name] = out
        if keep_last:
            last = (world, sim, res)
    summary: dict[str, Any] = {name: {k: float(np.mean([e[k] for e in errs])) for k in errs[0]} for name, errs in acc.items()}
    summary["runs"], summary["steps"], summary["lag"] = runs, steps, lag
    if keep_last:
        summary["_last"] = last
    return summary


def plot_run(world: World, sim: dict, results: dict, path, frames=(10, 100, -1)) -> None:
    """Figures 4.6/4.7: true and estimated robot paths with covariance ellipses, landmarks coloured
    by their decided model, predicted landmark paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from artmotion.io import save_figure

    colours = {"static": "tab:blue", "prismatic": "tab:orange", "revolute": "tab:green"}
    fig, axes = plt.subplots(1, len(frames), figsize=(5 * len(frames), 5))
    for ax, fr in zip(np.atleast_1d(axes), frames):
        k = fr if fr >= 0 else len(sim["poses"]) - 1
        true = sim["poses"][: k + 1]
        ax.plot(true[:, 0], true[:, 1], "k-", lw=1, label="true path")
        for name, style in (("articulated", "g-"), ("ekf", "r--")):
            p = results[name]["poses"][: k + 1]
            ax.plot(p[:, 0], p[:, 1], style, lw=1, label=f"{name} estimate")
            C = results[name]["covs"][k][:2, :2]
            w, V = np.linalg.eigh(C)
            a = np.linspace(0, 2 * np.pi, 50)
            ell = (V @ (np.sqrt(np.maximum(w, 0))[:, None] * 3 * np.vstack([np.cos(a), np.sin(a)]))).T + p[-1, :2]
            ax.plot(ell[:, 0], ell[:, 1], style[0] + "-", lw=0.8)
        L = sim["landmarks"][k]
        kinds = world.kinds
        f = results["articulated"]["filter"]
        for j, (lx, ly) in enumerate(L):
            b = f.blocks.get(j)
            col = colours[b.kind] if (b is not None and f.decided_at.get(j, 1e9) <= k) else "0.7"
            ax.plot(lx, ly, "o" if kinds[j] == "static" else "s", color=col, ms=4)
        for kind, p in world.moving:
            tt = np.linspace(0, 2 * np.pi / p["omega"], 100)
            if kind == "prismatic":
                e = np.asarray(p["origin"]) + np.outer(np.array([-1, 1]) * p["amplitude"], p["direction"])
                ax.plot(e[:, 0], e[:, 1], ":", color=colours[kind])
            else:
                ax.plot(p["centre"][0] + p["radius"] * np.cos(tt * p["omega"]),
                        p["centre"][1] + p["radius"] * np.sin(tt * p["omega"]), ":", color=colours[kind])
        ax.set_title(f"step {k}")
        ax.set_aspect("equal")
    np.atleast_1d(axes)[0].legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    save_figure(fig, path, dpi=80)
