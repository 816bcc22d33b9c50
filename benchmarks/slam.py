"""SLAM with articulated landmarks (#18): back ends side by side on the named worlds, ablation with
leave-one-world-out, and the cost of a step from 42 to 1000 landmarks.

    .venv/bin/python benchmarks/slam.py [--runs 20] [--quick] [--no-write] [--cost-only]

* Scenario table: every world of ``slam simulate --world`` (Table 4.2, a corridor of doors, a
  warehouse of carts, a loop with only moving landmarks on one half), ``--runs`` runs each, every
  back end on the same runs: increment translation error (mean and 95 % interval over runs),
  rotation error, absolute error, robot-pose NEES (3 if consistent), ms per step; a figure of the
  last run of each world (docs/slam_WORLD.png).
* Ablation of Articulated EKF SLAM's components (entry at once vs delayed, joint shift in the
  state, random-walk drift of undecided landmarks, the chi^2 gate): each variant's mean error per
  world, and for each component the setting chosen on three worlds and scored on the fourth.
* Cost per step with 42-1000 static landmarks around the path, the nearest 20 in view observed,
  timed over the last 100 steps of a lap (when all landmarks are in the state).

Writes the tables into docs/articulation.md between ``<!-- slam-benchmark -->`` markers.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):  # 2 cores: no BLAS threads
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from _docs import replace_block  # noqa: E402

from artmotion.articulation.slam.evaluate import BACKENDS, monte_carlo, plot_run, pose_errors, run_slam  # noqa: E402
from artmotion.articulation.slam.world import WORLDS, SimConfig, make_scenario, make_world, simulate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
HAVE_GRAPH = importlib.util.find_spec("gtsam") is not None
ORDER = ["ekf", "ekf_gated", "articulated_delayed", "articulated"] + (["graph"] if HAVE_GRAPH else [])

#: components of Articulated EKF SLAM: name -> (default, the other setting, what it is)
COMPONENTS = {
    "delayed": (False, True, "entry: a new landmark waits for Algorithm 1 (thesis) instead of entering as static"),
    "joint_shift": (True, False, "a moving landmark's line/centre shift in the state (off: joint taken as exact)"),
    "joint_shape": (True, False, "its radius or direction in the state too, from the fit's covariance (off: as fitted)"),
    "joint_curve": (True, False, "the joint as a path of constant curvature (line and circle alike), "
                                 "its curvature in the state (off: the decided line or circle)"),
    "motion_var": (0.01, 0.1, "acceleration noise of a moving landmark along its path (m^2/s^4)"),
    "undecided_var": (0.0, 0.01, "undecided landmarks drift as a random walk (0.01 m^2/step x P(moving))"),
    "gating": (True, False, "chi^2 gate on every sighting"),
    "gate": (0.01, 0.001, "the gate's false-rejection probability (1 %; 0.1 % was the first default)"),
    "drift_window": (3, 0, "the gate also tests the sum of a landmark's last 3 innovations (0: each sighting alone)"),
}


def scenarios(runs: int, write_figures: bool) -> dict:
    out = {}
    for world in WORLDS:
        t0 = time.perf_counter()
        res = monte_carlo(runs=runs, world=world, seed=0, backends=ORDER, keep_last=True)
        last = res.pop("_last")
        if write_figures:
            plot_run(*last, ROOT / "docs" / f"slam_{world}.png")
        out[world] = res
        print(f"{world}: {time.perf_counter() - t0:.0f} s", flush=True)
    return out


def ablation(runs: int) -> dict:
    """Mean increment translation error of each one-component variant, per world, on the same runs."""
    variants = {"default": {}} | {f"{c}={alt}": {c: alt} for c, (_, alt, _) in COMPONENTS.items()}
    err: dict[str, dict[str, list[float]]] = {v: {w: [] for w in WORLDS} for v in variants}
    for world, (_, steps) in WORLDS.items():
        for r in range(runs):
            s = 1000 * r
            sim = simulate(make_scenario(world, seed=s), steps, seed=s + 1)
            for v, kw in variants.items():
                out = run_slam(sim, "articulated", **kw)
                err[v][world].append(pose_errors(out["poses"], sim["poses"])["translation_error"])
    means = {v: {w: float(np.mean(e)) for w, e in per.items()} for v, per in err.items()}
    loo = {}
    for c in COMPONENTS:
        alt = next(v for v in variants if v.startswith(c + "="))
        rows = {}
        for held in WORLDS:
            # choose on the other worlds by the mean of errors relative to the default's
            rel = {v: np.mean([means[v][w] / means["default"][w] for w in WORLDS if w != held]) for v in ("default", alt)}
            pick = min(rel, key=rel.__getitem__)
            rows[held] = {"chosen": "default" if pick == "default" else alt, "held_out_error": means[pick][held]}
        loo[c] = rows
    return {"runs": runs, "means": means, "leave_one_world_out": loo}


def cost(sizes=(42, 100, 200, 500, 1000), steps: int = 660, timed: int = 100) -> dict:
    """ms per step of each back end, timed over the last ``timed`` steps of a lap."""
    out: dict = {}
    for L in sizes:
        sim = simulate(make_world(L, 0, 0, seed=0), steps, cfg=SimConfig(max_seen=20), seed=1)
        for name in ORDER:
            if name in ("ekf_gated", "articulated_delayed"):
                continue  # same cost as ekf / articulated
            out.setdefault(name, {})[L] = 1e3 * float(run_slam(sim, name)["step_seconds"][-timed:].mean())
        print(f"cost at {L} landmarks: " + ", ".join(f"{n} {out[n][L]:.2f} ms" for n in out), flush=True)
    return out


def _ci(d: dict, f: str = "{:.3f}") -> str:
    return f"{f.format(d['mean'])} [{f.format(d['low'])}, {f.format(d['high'])}]"


def markdown(rep: dict) -> str:
    lines = [f"Measured by `benchmarks/slam.py` ({rep['runs']} runs per world, seed 0; every back end on the same runs; "
             "errors of robot pose increments over all pose pairs, m and rad; the factor graph is scored on its "
             "final smoothed path, NEES on its running estimate):", ""]
    for world, res in rep["scenarios"].items():
        lines += [f"**{world}** — {WORLDS[world][0]}; {res['steps']} steps", "",
                  "| back end | translation [95 % interval] | rotation | absolute translation | NEES | ms/step |",
                  "|---|---|---|---|---|---|"]
        for name in ORDER:
            r = res[name]
            lines.append(f"| {BACKENDS[name][0]} | {_ci(r['translation_error'])} | {r['rotation_error']['mean']:.4f} | "
                         f"{r['absolute_translation_error']['mean']:.3f} | {r['nees']['mean']:.1f} | "
                         f"{1e3 * r['seconds_per_step']['mean']:.2f} |")
        lines.append("")
    ab = rep["ablation"]
    lines += [f"Ablation of Articulated EKF SLAM ({ab['runs']} runs per world; mean increment translation error, m):", "",
              "| variant | " + " | ".join(WORLDS) + " | mean |", "|---" * (len(WORLDS) + 2) + "|"]
    for v, per in ab["means"].items():
        lines.append(f"| {v} | " + " | ".join(f"{per[w]:.3f}" for w in WORLDS) + f" | {np.mean(list(per.values())):.3f} |")
    lines += ["", "Leave one world out (choose each component's setting on three worlds, score the fourth):", "",
              "| component | what | " + " | ".join(f"held out: {w}" for w in WORLDS) + " |", "|---" * (len(WORLDS) + 2) + "|"]
    for c, rows in ab["leave_one_world_out"].items():
        lines.append(f"| {c} | {COMPONENTS[c][2]} | " + " | ".join(
            f"{rows[w]['chosen']}: {rows[w]['held_out_error']:.3f}" for w in WORLDS) + " |")
    sizes = list(next(iter(rep["cost"].values())))
    note = f"; {rep['cost_note']}" if rep.get("cost_note") else ""
    lines += ["", "Cost per step (ms; static landmarks around the path, nearest 20 in view observed, "
              f"last 100 steps of a lap{note}):", "",
              "| back end | " + " | ".join(str(s) for s in sizes) + " |", "|---" * (len(sizes) + 1) + "|"]
    for name, per in rep["cost"].items():
        lines.append(f"| {BACKENDS[name][0]} | " + " | ".join(f"{per[s]:.2f}" for s in sizes) + " |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--quick", action="store_true", help="3 runs, small cost curve, nothing written")
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--cost-only", action="store_true",
                    help="re-measure only the cost per step; the other tables from docs/slam_benchmark.json")
    a = ap.parse_args()
    runs = 3 if a.quick else a.runs
    write = not (a.quick or a.no_write)
    sizes = (42, 200) if a.quick else (42, 100, 200, 500, 1000)
    if a.cost_only:
        rep = json.loads((ROOT / "docs" / "slam_benchmark.json").read_text())
        rep["cost"] = cost(sizes)
        rep["cost_note"] = (f"re-measured alone on {time.strftime('%Y-%m-%d')} (--cost-only); the ms/step of "
                            "the tables above are of the full run's machine")
    else:
        rep = {"runs": runs, "scenarios": scenarios(runs, write), "ablation": ablation(max(3, runs // 2)),
               "cost": cost(sizes)}
    text = markdown(rep)
    print(text)
    if write:
        replace_block(ROOT / "docs" / "articulation.md", "slam-benchmark", text)
        (ROOT / "docs" / "slam_benchmark.json").write_text(json.dumps(rep, indent=1, default=float))


if __name__ == "__main__":
    main()
