"""Simulated worlds for SLAM: point landmarks, static or moving, and a robot driving through them."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from artmotion.articulation.slam.ekf import MIN_RANGE, _control_noise, _motion_model, _wrap
from artmotion.errors import InputError, check_range, check_seed


@dataclass
class World:
    """Point landmarks: ``static`` (n, 2) plus moving ones ``(kind, params)``.

    prismatic params: ``origin, direction, amplitude, omega`` and optionally ``shift``:
    ``origin + A sin(omega t + shift) d``;
    revolute params: ``centre, radius, omega, phase``: ``centre + r (cos, sin)(a)`` with
    ``a = phase + omega t`` (turning round), or with ``swing`` (rad) and optionally ``shift``,
    ``a = phase + swing (1 - cos(omega t + shift)) / 2`` (a door opening and closing).
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
                s = math.sin(p["omega"] * t + p.get("shift", 0.0))
                out.append((np.asarray(p["origin"]) + p["amplitude"] * s * np.asarray(p["direction"]))[None])
            else:
                if "swing" in p:
                    a = p["phase"] + 0.5 * p["swing"] * (1.0 - math.cos(p["omega"] * t + p.get("shift", 0.0)))
                else:
                    a = p["phase"] + p["omega"] * t
                out.append((np.asarray(p["centre"]) + p["radius"] * np.array([math.cos(a), math.sin(a)]))[None])
        return np.concatenate(out, axis=0)


def make_world(n_landmarks: int = 42, n_prismatic: int = 1, n_revolute: int = 1, radius: float = 10.0,
               seed: int = 0) -> World:
    """Landmarks scattered in a ring around the robot's circular path (radius ``radius``); the moving
    ones sit close to the path so the robot sees them often."""
    counts = _check_counts(n_landmarks, n_prismatic, n_revolute)
    return _make_world(*counts, _check_radius(radius), np.random.default_rng(check_seed(seed, "seed")))


#: most landmarks a world may have
_MAX_LANDMARKS = 10**6


def _check_counts(n_landmarks, n_prismatic, n_revolute,
                  names=("n_landmarks", "n_prismatic", "n_revolute")) -> tuple[int, int, int]:
    """Landmark counts (all, prismatic, revolute) as whole numbers, the moving ones at most all of
    them; else an :class:`InputError` with the arguments' ``names``."""
    n, p, r = (check_range(name, v, 0, _MAX_LANDMARKS, integer=True)
               for name, v in zip(names, (n_landmarks, n_prismatic, n_revolute)))
    if p + r > n:
        raise InputError(f"{names[1]} ({p}) and {names[2]} ({r}) add up to more than {names[0]} ({n})")
    return n, p, r


def _check_radius(radius) -> float:
    return check_range("radius", radius, 0.0, math.inf, lo_open=True, hi_open=True)


def _make_world(n_landmarks: int, n_prismatic: int, n_revolute: int, radius: float, rng) -> World:
    """:func:`make_world` with checked arguments and a random generator ``rng``."""
    static = _ring(rng, n_landmarks - n_prismatic - n_revolute, radius, 1.5, 4.0)
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


def _ring(rng, n: int, radius: float, lo: float, hi: float, angles=(0.0, 2 * np.pi)) -> np.ndarray:
    """``n`` points at ``lo``-``hi`` m on either side of the circular path, at angles in ``angles``."""
    ang = rng.uniform(angles[0], angles[1], n)
    rad = radius + rng.choice([-1.0, 1.0], n) * rng.uniform(lo, hi, n)
    return np.column_stack([rad * np.cos(ang), rad * np.sin(ang)])


def _doors(rng, n: int, radius: float, angles=(0.0, 2 * np.pi)) -> list:
    """Doors in the walls of a ring corridor 2 m either side of the path: the handle (0.9-1.2 m from
    the hinge) swings 60-100 degrees into the corridor and back, each door at its own pace."""
    out = []
    for a in rng.uniform(angles[0], angles[1], n):
        side = rng.choice([-1.0, 1.0])
        hinge = (radius + 2.0 * side) * np.array([math.cos(a), math.sin(a)])
        tangent = np.array([-math.sin(a), math.cos(a)])
        closed = math.atan2(tangent[1], tangent[0])  # the leaf lies along the wall when closed
        turn = -side  # opening turns the handle towards the path
        out.append(("revolute", {"centre": hinge, "radius": float(rng.uniform(0.9, 1.2)), "omega": float(rng.uniform(0.2, 0.5)),
                                 "phase": closed, "swing": turn * math.radians(float(rng.uniform(60, 100))),
                                 "shift": float(rng.uniform(0, 2 * np.pi))}))
    return out


def _carts(rng, n: int, radius: float, angles=(0.0, 2 * np.pi)) -> list:
    """Carts on straight rails 1.5-4 m beside the path, along or across it, travelling +-1.5-3 m."""
    out = []
    for a in rng.uniform(angles[0], angles[1], n):
        r = radius + rng.choice([-1.0, 1.0]) * rng.uniform(1.5, 4.0)
        along = np.array([-math.sin(a), math.cos(a)])
        d = along if rng.random() < 0.5 else np.array([along[1], -along[0]])
        out.append(("prismatic", {"origin": r * np.array([math.cos(a), math.sin(a)]), "direction": d,
                                  "amplitude": float(rng.uniform(1.5, 3.0)), "omega": float(rng.uniform(0.2, 0.4)),
                                  "shift": float(rng.uniform(0, 2 * np.pi))}))
    return out


#: named worlds of ``slam simulate --world``: description and default number of steps (a lap of the
#: 10 m circle takes 628)
WORLDS = {
    "table4.2": ("42 landmarks, 1 prismatic and 1 revolute next to the path (Table 4.2)", 600),
    "corridor": ("ring corridor, 16 doors swinging open and shut among 40 landmarks", 600),
    "warehouse": ("15 carts sliding on rails among 40 landmarks", 600),
    "moving-only": ("static landmarks on one half of the loop only; 20 moving ones on the other; two laps", 1260),
}


def make_scenario(name: str, seed: int = 0, radius: float = 10.0) -> World:
    """The world called ``name`` (one of :data:`WORLDS`), laid out at random from ``seed``."""
    _check_world_name(name)
    return _make_scenario(name, np.random.default_rng(check_seed(seed, "seed")), _check_radius(radius))


def _check_world_name(name) -> str:
    if not isinstance(name, str) or name not in WORLDS:
        raise InputError(f"unknown world {name!r}; choose one of {', '.join(WORLDS)}")
    return name


def _make_scenario(name: str, rng, radius: float) -> World:
    """:func:`make_scenario` with checked arguments and a random generator ``rng``."""
    if name == "table4.2":
        return _make_world(42, 1, 1, radius, rng)
    if name == "corridor":
        return World(_ring(rng, 24, radius, 1.8, 2.2), _doors(rng, 16, radius))
    if name == "warehouse":
        return World(_ring(rng, 25, radius, 1.5, 4.0), _carts(rng, 15, radius))
    half = (np.pi, 2 * np.pi)
    return World(_ring(rng, 20, radius, 1.5, 4.0, angles=(-0.1, np.pi + 0.1)),
                 _carts(rng, 10, radius, half) + _doors(rng, 10, radius, half))


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
    max_seen: int | None = None  #: observe only the nearest this many landmarks in view

    def __post_init__(self) -> None:
        """Checked as made (NaN or a negative noise gave NaN poses with no error): a time step and
        noise levels that are positive finite numbers, speeds finite (turn rates at most 100
        rad/s), a field of view in (0, 2 pi]."""
        check_range("dt", self.dt, 0.0, 3600.0, lo_open=True)
        check_range("v", self.v, -1e3, 1e3)
        check_range("w", self.w, -100.0, 100.0)
        try:
            alphas = tuple(self.alphas)
        except TypeError:
            alphas = ()
        if len(alphas) != 4:
            raise InputError(f"alphas must be 4 numbers (the velocity motion model's noise, Eq. 4.22), got {self.alphas!r}")
        self.alphas = tuple(check_range(f"alphas[{i}]", a, 0.0, 1e3) for i, a in enumerate(alphas))
        check_range("range_std", self.range_std, 0.0, 1e3, lo_open=True)
        check_range("bearing_std", self.bearing_std, 0.0, math.pi, lo_open=True)
        check_range("max_range", self.max_range, 0.0, 1e6, lo_open=True)
        check_range("fov", self.fov, 0.0, 2 * math.pi, lo_open=True)
        if self.max_seen is not None:
            check_range("max_seen", self.max_seen, 1, 10**6, integer=True)


def simulate(world: World, steps: int, cfg: SimConfig | None = None, seed: int = 0, radius: float = 10.0) -> dict:
    """Drive the robot around a circle (commanded ``v, w``) with noisy execution; observe landmarks
    in range and field of view. Returns ``poses`` (steps+1, 3), ``controls`` (steps, 2),
    ``observations`` (list per step of ``(ids, z)``) and ``landmarks`` (steps+1, L, 2)."""
    if not isinstance(world, World):
        raise InputError(f"world must be a World (make_world, make_scenario), got {type(world).__name__}")
    steps = check_range("steps", steps, 1, 10**7, integer=True)
    if cfg is not None and not isinstance(cfg, SimConfig):
        raise InputError(f"cfg must be a SimConfig or None, got {type(cfg).__name__}")
    return _simulate(world, steps, cfg, np.random.default_rng(check_seed(seed, "seed")), _check_radius(radius))


def _simulate(world: World, steps: int, cfg: SimConfig | None, rng, radius: float) -> dict:
    """:func:`simulate` with checked arguments and a random generator ``rng``."""
    cfg = cfg or SimConfig()
    x = np.array([radius, 0.0, math.pi / 2])
    poses = [x.copy()]
    lms = [world.positions(0.0)]
    obs = []
    u = np.array([cfg.v, cfg.w])
    for k in range(steps):
        M = _control_noise(u, cfg.alphas)
        ut = u + rng.normal(0.0, np.sqrt(np.diag(M)))
        x, _, _ = _motion_model(x, ut, cfg.dt)
        x[2] = _wrap(x[2])
        t = (k + 1) * cfg.dt
        L = world.positions(t)
        d = L - x[:2]
        rng_ = np.hypot(d[:, 0], d[:, 1])
        brg = _wrap(np.arctan2(d[:, 1], d[:, 0]) - x[2])
        vis = np.flatnonzero((rng_ < cfg.max_range) & (np.abs(brg) < cfg.fov / 2))
        if cfg.max_seen is not None and len(vis) > cfg.max_seen:
            vis = np.sort(vis[np.argsort(rng_[vis], kind="stable")[: cfg.max_seen]])
        # a range is a distance: the noise of a landmark closer than it (a door swinging past the
        # robot) folds back to positive (the filters refuse a negative or zero range)
        z = np.column_stack([np.maximum(np.abs(rng_[vis] + rng.normal(0, cfg.range_std, len(vis))), MIN_RANGE),
                             _wrap(brg[vis] + rng.normal(0, cfg.bearing_std, len(vis)))])
        obs.append((vis, z))
        poses.append(x.copy())
        lms.append(L)
    return {"poses": np.array(poses), "controls": np.tile(u, (steps, 1)), "observations": obs,
            "landmarks": np.array(lms), "dt": cfg.dt, "config": cfg}


