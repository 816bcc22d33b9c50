"""Speed of articulation estimation (not a test; numbers go into docs/articulation.md).

    .venv/bin/python benchmarks/articulation.py [--quick]
    .venv/bin/python benchmarks/articulation.py --report   # regenerate docs/articulation*.png and numbers

* online update: microseconds per observation per model (Algorithm 1's filter step alone, and
  amortised over a whole track including the configuration re-fits: a 2000-sample synthetic arc
  and the 30 real logs of Sturm et al., min and median of repeats);
SLAM has its own benchmark, benchmarks/slam.py.
"""

from __future__ import annotations

import os

# single-threaded BLAS: on a shared 2-core machine threaded BLAS on ~100x100 matrices loses to contention
for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import json
import sys
import time

import numpy as np

from artmotion.articulation.online import OnlineEstimator


def bench_online(n: int = 2000, seed: int = 0, repeats: int = 5) -> dict:
    """Algorithm 1 over an ``n``-sample arc, ``repeats`` times (the machine is shared: min and median)."""
    rng = np.random.default_rng(seed)
    th = np.linspace(0, 1.5, n)
    X = np.column_stack([0.4 * np.cos(th), 0.4 * np.sin(th), np.zeros(n)]) + rng.normal(0, 0.002, (n, 3))
    amort, amort_norefit = [], []
    for rep in range(repeats):
        for refit, out_list in ((True, amort), (False, amort_norefit)):
            est = OnlineEstimator(refit=refit)
            t0 = time.perf_counter()
            for k in range(n):
                est.update(X[k])
            out_list.append(1e6 * (time.perf_counter() - t0) / n / len(est.names))
    est = OnlineEstimator()
    for k in range(n):
        est.update(X[k])
    # one sample's step alone (residual off the model, along-track filter where it runs), per model
    out = {}
    z = X[-1].tolist()
    for f in est.filters:
        reps = 20000
        t0 = time.perf_counter()
        for _ in range(reps):
            f.step(z, 1.0)
        out[f.model.name] = 1e6 * (time.perf_counter() - t0) / reps
    return {"step_us_per_model": out,
            "amortised_us_per_observation_per_model": {"min": min(amort), "median": float(np.median(amort))},
            "without_refits_us_per_observation_per_model": {"min": min(amort_norefit),
                                                            "median": float(np.median(amort_norefit))},
            "samples": n, "repeats": repeats}


def bench_online_sturm(sturm: str = "../shared/data/articulation/sturm2010", repeats: int = 3) -> dict | None:
    """Algorithm 1 over the 30 real logs (240-770 samples each: the re-fits weigh more than on a
    long track), amortised per observation per model; None when the data are absent."""
    import glob

    logs = [np.loadtxt(p) for p in sorted(glob.glob(os.path.join(sturm, "*", "*.log")))]
    if not logs:
        return None
    n = sum(len(X) for X in logs)
    models = len(OnlineEstimator().names)
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        for X in logs:
            est = OnlineEstimator()
            for k in range(len(X)):
                est.update(X[k])
        wall.append(1e6 * (time.perf_counter() - t0) / n / models)
        cpu.append(1e6 * (time.process_time() - c0) / n / models)
    return {"logs": len(logs), "samples": n,
            "us_per_observation_per_model": {"min": min(wall), "median": float(np.median(wall))},
            "cpu_us_per_observation_per_model": {"min": min(cpu), "median": float(np.median(cpu))}}


# ---------------------------------------------------------------- the figures and tables of the docs
def report(out_dir: str = "docs", sturm: str = "../shared/data/articulation/sturm2010") -> dict:
    """Regenerate docs/articulation*.png and the numbers in docs/articulation.md."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from artmotion.articulation.online import estimate_online
    from artmotion.articulation.temporal import compare_orders, configuration_monte_carlo, pendulum, plot_orders
    from artmotion.io import save_figure

    rep = {}
    # Table 4.1
    rep["table_4_1"] = configuration_monte_carlo(runs=500, seed=0)
    rep["table_4_1_accelerating"] = configuration_monte_carlo(runs=500, seed=0, alpha=0.01)
    # Fig. 4.5
    t, q, truth = pendulum(duration=10.0, dt=0.02, noise_std=0.01, seed=0)
    orders = compare_orders(q, t, orders=(1, 2, 3), obs_var=1e-4, truth=truth, horizon=10)
    plot_orders(t, q, truth, orders, os.path.join(out_dir, "articulation_orders.png"))
    rep["orders"] = {n: {k: v for k, v in r.items() if not hasattr(v, "shape")} for n, r in orders.items()}
    # Fig. 4.6-like: model probabilities over time, synthetic points and one real log of each kind
    rng = np.random.default_rng(0)
    s = np.linspace(0, 1, 150)
    synth = {
        "static": np.tile([0.4, -0.2, 0.9], (150, 1)) + rng.normal(0, 0.003, (150, 3)),
        "prismatic": np.array([0.1, 0.2, 0.3]) + 0.5 * s[:, None] * np.array([0.6, 0.8, 0.0]) + rng.normal(0, 0.003, (150, 3)),
        "revolute": np.column_stack([0.45 * np.cos(1.5 * s), 0.45 * np.sin(1.5 * s), 0 * s]) + rng.normal(0, 0.003, (150, 3)),
    }
    for name in ("drawer/001", "left_door/001", "dishwasher/001"):
        p = os.path.join(sturm, name + ".log")
        if os.path.exists(p):
            synth["sturm " + name] = np.loadtxt(p)
    fig, axes = plt.subplots(2, 3, figsize=(13, 6))
    for ax, (name, X) in zip(axes.ravel(), synth.items()):
        r = estimate_online(X)
        for j, m in enumerate(r.names):
            ax.plot(r.history[:, j], label=m)
        ax.axhline(0.75, color="0.5", ls=":", lw=0.8)
        if r.decided_at is not None:
            ax.axvline(r.decided_at, color="k", ls="--", lw=0.8)
        ax.set_title(f"{name}: {r.model} @ {r.decided_at}", fontsize=9)
        ax.set_ylim(-0.02, 1.02)
    axes[0, 0].legend(fontsize=7)
    fig.supxlabel("sample")
    fig.supylabel("model probability (Eq. 4.16)")
    fig.tight_layout()
    save_figure(fig, os.path.join(out_dir, "articulation_online.png"), dpi=80)
    rep["bench"] = {"online": bench_online(2000), "online_sturm": bench_online_sturm(sturm)}
    return rep


if __name__ == "__main__":
    if "--report" in sys.argv:
        print(json.dumps(report(), indent=1, default=str))
        sys.exit(0)
    quick = "--quick" in sys.argv
    report_ = {
        "online": bench_online(500 if quick else 2000),
        "online_sturm": bench_online_sturm(),
    }
    print(json.dumps(report_, indent=1))
