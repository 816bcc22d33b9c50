"""Running SLAM back ends over simulated runs and scoring them: pose errors, Monte Carlo, figures."""

from __future__ import annotations

import inspect
import reprlib
import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from artmotion.articulation.slam.ekf import EKFSlam, _wrap
from artmotion.articulation.slam.world import (
    WORLDS,
    SimConfig,
    World,
    _check_counts,
    _check_world_name,
    _make_scenario,
    _make_world,
    _simulate,
)
from artmotion.errors import InputError, check_range, check_seed, float_array

#: the back ends compared by :func:`monte_carlo`: name -> (label, constructor keyword arguments);
#: "graph" is the factor graph of :mod:`~artmotion.articulation.slam.graph` (needs the ``slam`` extra)
BACKENDS: dict[str, tuple[str, dict]] = {
    "ekf": ("EKF SLAM", {"articulated": False, "gating": False}),
    "ekf_gated": ("EKF SLAM + chi2 gate", {"articulated": False, "gating": True}),
    "articulated": ("Articulated EKF SLAM", {"articulated": True}),
    "articulated_delayed": ("Articulated EKF SLAM, thesis (delayed)", {"articulated": True, "delayed": True}),
    "graph": ("Articulated factor graph (iSAM2)", {"articulated": True}),
}


def make_backend(name: str, sim: dict, **kwargs):
    """A fresh back end ``name`` (see :data:`BACKENDS`) set up for simulated run ``sim``."""
    _check_backend(name)
    _check_run(sim)
    cfg = sim["config"]
    args = (sim["poses"][0], sim["dt"], cfg.alphas, cfg.range_std, cfg.bearing_std, sim["landmarks"].shape[1])
    kw = {**BACKENDS[name][1], **kwargs}
    if name == "graph":
        from artmotion.articulation.slam.graph import GraphSlam

        return GraphSlam(*args, **kw)
    return EKFSlam(*args, **kw)


#: what :func:`~artmotion.articulation.slam.world.simulate` returns, and the back ends read
_RUN_KEYS = ("poses", "controls", "observations", "landmarks", "dt", "config")


def _check_run(sim) -> None:
    """``sim`` looks like a run of :func:`~artmotion.articulation.slam.world.simulate` (a mapping
    with its keys, a :class:`SimConfig` and one observation per control); else an :class:`InputError`."""
    if not isinstance(sim, Mapping) or any(k not in sim for k in _RUN_KEYS) or not isinstance(sim["config"], SimConfig) \
            or len(sim["observations"]) != len(sim["controls"]):
        raise InputError(f"sim must be a simulated run as simulate() returns it (a dict of {', '.join(_RUN_KEYS)}), "
                         f"got {reprlib.repr(sim)}")


def _check_backend(name, what: str = "back end") -> None:
    if not isinstance(name, str) or name not in BACKENDS:
        raise InputError(f"unknown {what} {name!r}; choose from {', '.join(BACKENDS)}")


#: the constructor's arguments that :func:`make_backend` takes from the simulated run
_POSITIONAL = {"x0", "dt", "alphas", "range_std", "bearing_std", "n_max"}


def _check_options(options) -> dict:
    """``options`` of :func:`monte_carlo`: back end name -> keyword arguments of its constructor
    (:class:`~artmotion.articulation.slam.ekf.EKFSlam`, or ``GraphSlam`` for "graph")."""
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise InputError(f"options must map back end names to dicts of keyword arguments, got {reprlib.repr(options)}")
    for name, kw in options.items():
        _check_backend(name, "back end in options:")
        if not isinstance(kw, Mapping) or not all(isinstance(k, str) for k in kw):
            raise InputError(f"options[{name!r}] must be a dict of keyword arguments, got {reprlib.repr(kw)}")
        cls: type = EKFSlam
        if name == "graph":
            from artmotion.articulation.slam.graph import GraphSlam

            cls = GraphSlam
        known = set(inspect.signature(cls).parameters) - _POSITIONAL  # (make_backend passes those from the run)
        unknown = [k for k in kw if k not in known]
        if unknown:
            raise InputError(f"options[{name!r}] names no keyword argument of {cls.__name__}: {', '.join(map(repr, unknown))}")
    return dict(options)


def run_slam(sim: dict, backend: str = "articulated", **kwargs) -> dict:
    """Run back end ``backend`` over a simulated run. Returns ``poses`` (steps+1, 3): the estimate
    at each step as it was made (a filter's); ``covs``: the robot's covariance at each step;
    ``smoothed``: a smoother's final estimate of the whole path (the same as ``poses`` for a
    filter); ``filter``: the back end; ``step_seconds`` (steps,) each step took and ``seconds`` in all."""
    f = make_backend(backend, sim, **kwargs)
    poses = [f.pose]
    covs = [f.pose_cov]
    stamps = [time.perf_counter()]
    for k, u in enumerate(sim["controls"]):
        f.predict(u)
        ids, z = sim["observations"][k]
        f.update(ids, z)
        poses.append(f.pose)
        covs.append(f.pose_cov)
        stamps.append(time.perf_counter())
    poses_arr = np.array(poses)
    smoothed = f.trajectory() if hasattr(f, "trajectory") else poses_arr
    return {"poses": poses_arr, "covs": np.array(covs), "smoothed": smoothed, "filter": f,
            "step_seconds": np.diff(stamps), "seconds": stamps[-1] - stamps[0]}


def nees(est: np.ndarray, covs: np.ndarray, true: np.ndarray) -> np.ndarray:
    """Normalised estimation error squared of the robot pose at each step (chi^2 with 3 dof if the
    filter is consistent); step 0 (known start) left out."""
    e = np.asarray(est, dtype=float) - np.asarray(true, dtype=float)
    e[:, 2] = _wrap(e[:, 2])
    return np.einsum("ki,ki->k", e[1:], np.linalg.solve(covs[1:], e[1:, :, None])[..., 0])


def pose_errors(est: np.ndarray, true: np.ndarray, lag: int = 0, stride: int = 5) -> dict:
    """Errors of robot pose increments (the relative pose error of [91]) and absolute errors.

    An increment is the pose of step ``j`` seen from step ``i``; its error is the difference between
    the estimated and the true increment (translation: Euclidean norm; rotation: absolute angle).
    ``lag > 0`` averages over increments of ``lag`` steps; ``lag = 0`` over all pairs ``i < j``
    (every ``stride``-th pose; a run shorter than ``stride`` steps compares its first and last pose),
    which weighs local and global consistency alike. ``est`` and ``true``: ``(n, 3)`` poses
    ``(x, y, theta)``, finite, ``n >= 2``; ``lag < n``.
    """
    est, true = float_array(est, "est"), float_array(true, "true")
    for name, a in (("est", est), ("true", true)):
        if a.ndim != 2 or a.shape[1] != 3:
            raise InputError(f"{name} must be an (n, 3) array of poses (x, y, theta), got shape {a.shape}")
        if not np.isfinite(a).all():
            raise InputError(f"{name} holds NaN or infinite values")
    if len(est) != len(true):
        raise InputError(f"est and true must hold as many poses, got {len(est)} and {len(true)}")
    if len(est) < 2:
        raise InputError(f"est and true must hold at least 2 poses, got {len(est)}")
    lag = check_range("lag", lag, 0, len(est) - 1, integer=True)
    stride = check_range("stride", stride, 1, 10**9, integer=True)
    return _pose_errors(est, true, lag, stride)


def _pose_errors(est: np.ndarray, true: np.ndarray, lag: int, stride: int) -> dict:
    """:func:`pose_errors` of checked arrays (a back end that diverged gives NaN errors)."""
    if lag > 0:
        i = np.arange(0, len(est) - lag)
        j = i + lag
    else:
        idx = np.arange(0, len(est), max(1, min(stride, len(est) - 1)))
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


def _interval(values) -> dict:
    """Mean and its 95 % confidence interval (Student's t over runs; ``None`` from a single run),
    cut at 0 for values that cannot be negative (errors: the t interval of two runs went below 0)."""
    from scipy.stats import t as student

    v = np.asarray(values, dtype=float)
    m = float(v.mean())
    if len(v) < 2:
        return {"mean": m, "low": None, "high": None}
    h = float(student.ppf(0.975, len(v) - 1) * v.std(ddof=1) / np.sqrt(len(v)))
    return {"mean": m, "low": max(m - h, 0.0) if v.min() >= 0 else m - h, "high": m + h}


def monte_carlo(runs: int = 20, steps: int | None = None, world: str = "table4.2", seed: int = 0, lag: int = 0,
                backends=("articulated", "ekf", "ekf_gated"), keep_last: bool = False,
                landmarks: tuple[int, int, int] | None = None, options: dict | None = None,
                on_run: Callable[[int, int], None] | None = None) -> dict:
    """Errors of the ``backends`` over ``runs`` simulated runs of ``world`` (Table 4.2 and the other
    scenarios of :data:`~artmotion.articulation.slam.world.WORLDS`), each back end on the same runs.

    Per back end and error: the mean over runs with its 95 % interval (``{"mean", "low", "high"}``);
    ``nees``: the robot pose's NEES averaged over steps and runs (3 if consistent); ``seconds_per_step``.
    A smoother is scored on its final path (``smoothed``). ``landmarks = (all, prismatic, revolute)``
    replaces the world by :func:`make_world` with those counts; ``options``: back end name -> keyword
    arguments for it. ``on_run(done, total)`` is called after each back end's run (``total`` = runs
    times back ends), e.g. to show progress: a large world runs for minutes per run.
    """
    runs = check_range("runs", runs, 1, 10**6, integer=True)
    if steps is not None:
        steps = check_range("steps", steps, 2, 10**7, integer=True)
    seed = check_seed(seed, "seed")
    _check_world_name(world)
    if landmarks is not None and (not isinstance(landmarks, (tuple, list)) or len(landmarks) not in (0, 3)):
        raise InputError(f"landmarks must be three counts (all, prismatic, revolute), got {reprlib.repr(landmarks)}")
    if landmarks:
        landmarks = _check_counts(*landmarks, names=("landmarks[0] (all)", "landmarks[1] (prismatic)",
                                                     "landmarks[2] (revolute)"))
    try:
        names = list(backends) if not isinstance(backends, str) else []
    except TypeError:
        names = []
    if not names:
        raise InputError(f"backends must be a list of back end names ({', '.join(BACKENDS)}), got {reprlib.repr(backends)}")
    for name in names:
        _check_backend(name)
    backends = names
    options = _check_options(options)
    if on_run is not None and not callable(on_run):
        raise InputError(f"on_run must be a function of (done, total), got {reprlib.repr(on_run)}")
    steps = steps or WORLDS[world][1]
    if isinstance(lag, bool) or not isinstance(lag, (int, np.integer)) or not 0 <= lag <= steps:
        raise InputError(f"lag must be a whole number of steps in [0, {steps}] (the run's length; 0: all pairs), got {lag!r}")
    acc: dict[str, list[dict[str, float]]] = {name: [] for name in backends}
    last = None
    done = 0
    for r in range(runs):
        s = seed + 1000 * r
        # (the seeds of later runs may pass 2**32 - 1: NumPy's generators take them)
        rng = np.random.default_rng(s)
        w = _make_world(*landmarks, 10.0, rng) if landmarks else _make_scenario(world, rng, 10.0)
        sim = _simulate(w, steps, None, np.random.default_rng(s + 1), 10.0)
        res = {}
        for name in backends:
            out = run_slam(sim, name, **options.get(name, {}))
            e = _pose_errors(out["smoothed"], sim["poses"], lag, 5)
            e1 = _pose_errors(out["smoothed"], sim["poses"], 1, 5)
            e["step_translation_error"], e["step_rotation_error"] = e1["translation_error"], e1["rotation_error"]
            e["nees"] = float(nees(out["poses"], out["covs"], sim["poses"]).mean())
            e["seconds_per_step"] = out["seconds"] / steps
            acc[name].append(e)
            res[name] = out
            done += 1
            if on_run is not None:
                on_run(done, runs * len(backends))
        if keep_last:
            last = (w, sim, res)
    summary: dict[str, Any] = {name: {k: _interval([e[k] for e in errs]) for k in errs[0]} for name, errs in acc.items()}
    summary.update(runs=runs, steps=steps, lag=lag, world=world if not landmarks else "custom")
    if keep_last:
        summary["_last"] = last
    return summary


def plot_run(world: World, sim: dict, results: dict, path, frames=(0.1, 0.5, 1.0)) -> None:
    """Figures 4.6/4.7: the true robot path and each back end's estimate as it was made (3-sigma
    ellipse at the last pose shown; at the end, a smoother's final path dotted) at fractions
    ``frames`` of the run; landmarks coloured by the model an
    articulated back end gave them (grey: none yet), the moving landmarks' true paths dotted."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from artmotion.io import save_figure

    colours = {"static": "tab:blue", "prismatic": "tab:orange", "revolute": "tab:green"}
    styles = {"ekf": "r--", "ekf_gated": "m-.", "articulated": "g-", "articulated_delayed": "y-", "graph": "c-"}
    judge = next((results[n]["filter"] for n in ("graph", "articulated", "articulated_delayed") if n in results), None)
    steps = len(sim["poses"]) - 1
    fig, axes = plt.subplots(1, len(frames), figsize=(5 * len(frames), 5))
    for ax, fr in zip(np.atleast_1d(axes), frames):
        k = max(1, round(fr * steps))
        true = sim["poses"][: k + 1]
        ax.plot(true[:, 0], true[:, 1], "k-", lw=1, label="true path")
        for name, out in results.items():
            style = styles.get(name, "b-")
            p = out["poses"][: k + 1]
            ax.plot(p[:, 0], p[:, 1], style, lw=1, label=name)
            w, V = np.linalg.eigh(out["covs"][k][:2, :2])
            a = np.linspace(0, 2 * np.pi, 50)
            ell = (V @ (np.sqrt(np.maximum(w, 0))[:, None] * 3 * np.vstack([np.cos(a), np.sin(a)]))).T + p[-1, :2]
            ax.plot(ell[:, 0], ell[:, 1], style[0] + "-", lw=0.8)
            if k == steps and out["smoothed"] is not out["poses"]:  # a smoother's final path
                ax.plot(out["smoothed"][:, 0], out["smoothed"][:, 1], style[0] + ":", lw=1.2, label=f"{name} smoothed")
        kinds = world.kinds
        decided = judge.kinds if judge is not None else {}
        for j, (lx, ly) in enumerate(sim["landmarks"][k]):
            known = judge is not None and j in decided and judge.decided_at.get(j, 1e9) <= k
            ax.plot(lx, ly, "o" if kinds[j] == "static" else "s", color=colours[decided[j]] if known else "0.7", ms=4)
        for j, (kind, _) in enumerate(world.moving):
            path_j = sim["landmarks"][:, len(world.static) + j]
            ax.plot(path_j[:, 0], path_j[:, 1], ":", color=colours[kind], lw=0.8)
        ax.set_title(f"step {k}")
        ax.set_aspect("equal")
    np.atleast_1d(axes)[-1].legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    save_figure(fig, path, dpi=80)
