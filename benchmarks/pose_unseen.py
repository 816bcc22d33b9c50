"""Pose on motion the model has never seen (issue 17): HOG + GP vs the cnn feature + GP.

    .venv/bin/python benchmarks/pose_unseen.py [--out out/pose] [--no-docs] [--skip-cv] [--save MODEL] [--resume]

Renders (once, cached under --out) seven training sets of 4000 frames: ``normal`` (the
pick-and-place script, seed 0), ``cover`` (``--motion cover --scenes 10``: the joint ranges covered
evenly, ten backgrounds), ``cover_random`` (the same motion with ``--style random --scenes 100``:
a hundred scenes, each in a random look of tissue and metal), ``script3``, ``script4``, ``script5``
(the script with seeds 3, 4 and 5) and ``cover5`` (the cover motion with seed 5, ten backgrounds),
and ``cover_random10`` (ten random looks: an earlier recipe, for its ablation); pooled with each
set a group (``fit(groups=...)``: the last 20 % of every set calibrate the variance, and the
network never sees them), and four unseen test sequences of 600 frames: pick
and place with seeds 1 and 2, each in normal light and dark (``--dark``: the same frames in low
light). Then, every model trained on the training crops only:

* unseen sequences: HOG (the thesis' model on the script set, and on the pooled sets) and cnn
  (the recipe: all seven sets, with the boxes' places in their frames); raw, Kalman-filtered and
  smoothed (forward and back);
  ±3σ coverage;
* protocols side by side on the recipe's 28,000 crops: random 5-fold (the thesis), contiguous 5-fold;
* learning curve: the cnn model on 1000-28,000 training crops (evenly spaced rows of the seven sets);
* ablations of the cnn model (mean over the four unseen sequences): the tool's keypoints as
  auxiliary targets (not adopted), the previous recipes (five sets, without ``script5`` and
  ``cover5``; ten random looks, not a hundred; three sets; two without the random looks), no box views, no
  augmentation, equal loss weights, the smooth L1 loss's wider zone, cover set only, script set only;
* the recipe with and without keypoints, three seeds each (one training is one draw);
* error against the distance from a test pose to the nearest training pose;
* cost: training time on 4000 crops, one frame's prediction, batch throughput (run it alone).

The recipe's model is saved (``--save``) for benchmarks/pose_look.py. Every result is also kept in
``OUT/pose_unseen.cache.pkl`` as it comes; ``--resume`` reuses it (after an interrupted run, or to
time the cost alone on a quiet machine): only with the same code, which the caller must ensure.

Prints Markdown and writes it between ``<!-- pose-unseen -->`` markers of docs/pose.md, and
docs/pose_unseen.json.
"""

from __future__ import annotations

import argparse
import json
import pickle
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _docs import replace_block  # noqa: E402

from artmotion.pose.data import load_labelled, read_keypoints, read_views  # noqa: E402
from artmotion.pose.evaluate import Columns, cross_validate, errors, summary  # noqa: E402
from artmotion.pose.model import PoseRegressor  # noqa: E402
from artmotion.pose.render import write_dataset  # noqa: E402

RENDERS = {  # name: (poses, seed, dark, motion, scenes, style)
    "normal": (4000, 0, False, "script", 1, "default"),
    "cover": (4000, 0, False, "cover", 10, "default"),
    "cover_random": (4000, 0, False, "cover", 100, "random"),
    "cover_random10": (4000, 0, False, "cover", 10, "random"),
    "script3": (4000, 3, False, "script", 1, "default"),
    "script4": (4000, 4, False, "script", 1, "default"),
    "script5": (4000, 5, False, "script", 1, "default"),
    "cover5": (4000, 5, False, "cover", 10, "default"),
    "test": (600, 1, False, "script", 1, "default"),
    "dark": (600, 1, True, "script", 1, "default"),
    "test2": (600, 2, False, "script", 1, "default"),
    "dark2": (600, 2, True, "script", 1, "default"),
}
#: the training sets of the recipe (the script, the cover motion, the cover motion in random looks, three more
#: script renders, the cover motion again); the last 20 % of every set calibrate the variance (the network
#: never sees them)
RECIPE = ("cover", "normal", "cover_random", "script3", "script4", "script5", "cover5")
RECIPE_LABEL = "cnn + views, seven sets (default recipe)"
KEYPOINTS = "cnn + views + keypoints, seven sets (not adopted)"

UNSEEN = ("test", "dark", "test2", "dark2")


def load(out: Path, name: str):
    d = out / name
    n, seed, dark, motion, scenes, style = RENDERS[name]
    want = {"poses": n, "seed": seed, "motion": motion, "scenes": scenes, "style": style, "dark": dark}
    meta = d / "rendering.json"
    have = json.loads(meta.read_text()) if meta.exists() else {}
    if any(have.get(k) != v for k, v in want.items()) or not (d / "keypoints.csv").exists():  # (or from before
        print(f"rendering {d} ...", flush=True)                                               # keypoints)
        write_dataset(d, n, seed, dark, frames=True, motion=motion, scenes=scenes, style=style)
    names, paths, imgs, Y = load_labelled(d / "crops", d / "labels.csv")
    K = read_keypoints(d / "keypoints.csv", paths, [(c.shape[1], c.shape[0]) for c in imgs])[1]
    return names, imgs, Y, read_views(d / "boxes.csv", paths), K


def score(reg, data, cols, names, views: bool) -> dict:
    """Per unseen sequence: summary(); plus the means over the four."""
    res = {}
    for k in UNSEEN:
        _, imgs, Y, V, _ = data[k]
        m, s = reg.predict(imgs, return_std=True, views=V if views else None)
        kf = reg.make_filter()
        res[k] = summary(Y, m, s, kf.filter(m, s)[0], cols, names, smooth=kf.smooth(m, s))
        res[k]["pred"] = m
    for q in ("orientation", "opening", "orientation filtered", "opening filtered", "orientation smoothed",
              "opening smoothed", "all in 3sd", "opening in 3sd", "all in 3sd smoothed"):
        res[f"mean {q}"] = float(np.mean([res[k][q] for k in UNSEEN]))
    for q in ("orientation", "opening"):
        res[f"dark/normal {q}"] = float(np.mean([res[d][q] / res[t][q] for t, d in (("test", "dark"), ("test2", "dark2"))]))
    return res


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=str(ROOT / "out" / "pose"))
    ap.add_argument("--no-docs", action="store_true")
    ap.add_argument("--save", default=str(ROOT / "out" / "pose" / "models" / "cnn-recipe.npz"),
                    help="where the recipe's model is written (for benchmarks/pose_look.py; '' to skip)")
    ap.add_argument("--skip-cv", action="store_true", help="leave out the 5-fold protocols (10 cnn trainings)")
    ap.add_argument("--resume", action="store_true", help="reuse the results kept by an earlier run of this code")
    args = ap.parse_args(argv)
    out = Path(args.out)
    cache_path = out / "pose_unseen.cache.pkl"
    cache: dict = pickle.loads(cache_path.read_bytes()) if args.resume and cache_path.exists() else {}

    def keep(label, value):
        cache[label] = value
        tmp = cache_path.with_suffix(".tmp")
        tmp.write_bytes(pickle.dumps(cache))
        tmp.replace(cache_path)
        return value
    data = {k: load(out, k) for k in RENDERS}
    names = data["normal"][0]
    cols = Columns.from_names(names)
    def pooled(sets):
        """Crops, angles, views, the set of every row (``fit(groups=...)``) and keypoints."""
        return ([c for k in sets for c in data[k][1]], np.concatenate([data[k][2] for k in sets]),
                np.concatenate([data[k][3] for k in sets]), np.repeat(sets, [len(data[k][2]) for k in sets]),
                np.concatenate([data[k][4] for k in sets]))

    imgs, Y, V, G, K = pooled(RECIPE)
    imgs2, Y2, V2, G2, _ = pooled(RECIPE[:2])
    lines: list[str] = []
    say = lambda s="": (print(s, flush=True), lines.append(s))  # noqa: E731
    results: dict = {}

    def train(label, feature, tr_imgs, tr_Y, tr_V=None, tr_G=None, tr_K=None, **kw):
        if label in cache and (label != RECIPE_LABEL or (args.save and Path(args.save).exists())):
            results[label] = res = cache[label]
            print(f"  {label}: {res['mean orientation']:.2f} / {res['mean opening']:.2f} (kept)", flush=True)
            return (PoseRegressor.load(args.save) if label == RECIPE_LABEL else None), res
        t = time.perf_counter()
        reg = PoseRegressor(feature=feature, **kw).fit(tr_imgs, tr_Y, names, views=tr_V, groups=tr_G, keypoints=tr_K)
        sec = time.perf_counter() - t
        res = score(reg, data, cols, names, tr_V is not None)
        res["train seconds"], res["n"] = sec, len(tr_Y)
        results[label] = res
        if label == RECIPE_LABEL and args.save:
            Path(args.save).parent.mkdir(parents=True, exist_ok=True)
            reg.save(args.save)
        keep(label, res)
        print(f"  {label}: {res['mean orientation']:.2f} / {res['mean opening']:.2f} ({sec:.0f} s)", flush=True)
        return reg, res

    # -- unseen sequences
    train("HOG, script set (the thesis' model)", "hog", data["normal"][1], data["normal"][2])
    train("HOG, script and cover sets", "hog", imgs2, Y2, tr_G=G2)
    train("HOG, seven sets", "hog", imgs, Y, tr_G=G)
    cnn_reg, _ = train(RECIPE_LABEL, "cnn", imgs, Y, V, G)
    say("#### Unseen sequences (trained on rendered sets only; mean error in degrees, orientation / opening)")
    say()
    say("| model | n | seq 1 | seq 1 dark | seq 2 | seq 2 dark | **mean** | mean, Kalman-filtered | mean, smoothed | "
        "dark / normal | opening in ±3σ | all 4 in ±3σ | smoothed: all 4 in ±3σ |")
    say("|---|---|---|---|---|---|---|---|---|---|---|---|---|")

    def row(label):
        r = results[label]
        cells = " | ".join(f"{r[k]['orientation']:.2f} / {r[k]['opening']:.2f}" for k in UNSEEN)
        say(f"| {label} | {r['n']} | {cells} | **{r['mean orientation']:.2f} / {r['mean opening']:.2f}** | "
            f"{r['mean orientation filtered']:.2f} / {r['mean opening filtered']:.2f} | "
            f"{r['mean orientation smoothed']:.2f} / {r['mean opening smoothed']:.2f} | "
            f"{r['dark/normal orientation']:.2f}× / {r['dark/normal opening']:.2f}× | "
            f"{100 * r['mean opening in 3sd']:.1f} % | {100 * r['mean all in 3sd']:.1f} % | "
            f"{100 * r['mean all in 3sd smoothed']:.1f} % |")

    for label in list(results):
        row(label)
    # -- ablations of the cnn recipe
    five = RECIPE[:5]  # the recipe before the thirtieth session (2026-11-30)
    before = tuple("cover_random10" if k == "cover_random" else k for k in five)  # ten random looks
    train(KEYPOINTS, "cnn", imgs, Y, V, G, K)
    train("cnn + views, five sets (the recipe before)", "cnn", *pooled(five)[:4])
    train("cnn + views, five sets, ten random looks (an earlier recipe)", "cnn", *pooled(before)[:4])
    train("cnn + views, three sets (an earlier recipe)", "cnn", *pooled(before[:3])[:4])
    train("cnn, script and cover sets (no random looks)", "cnn", imgs2, Y2, V2, G2)
    train("cnn without views", "cnn", imgs, Y, tr_G=G)
    train("cnn without augmentation", "cnn", imgs, Y, V, G, augment=False)
    train("cnn, opening weight 1 (not 3)", "cnn", imgs, Y, V, G, opening_weight=1.0)
    train("cnn, smooth L1 loss with β = 0.5 (the loss before; not 0.05)", "cnn", imgs, Y, V, G, net_beta=0.5)
    train("cnn + views, seven sets, variance calibrated on the last set only", "cnn", imgs, Y, V)
    train("cnn, cover set only", "cnn", data["cover"][1], data["cover"][2], data["cover"][3])
    train("cnn, script set only", "cnn", data["normal"][1], data["normal"][2], data["normal"][3])
    for label in (KEYPOINTS, "cnn + views, seven sets, variance calibrated on the last set only",
                  "cnn + views, five sets (the recipe before)",
                  "cnn + views, five sets, ten random looks (an earlier recipe)",
                  "cnn + views, three sets (an earlier recipe)",
                  "cnn, script and cover sets (no random looks)", "cnn without views",
                  "cnn without augmentation", "cnn, opening weight 1 (not 3)",
                  "cnn, smooth L1 loss with β = 0.5 (the loss before; not 0.05)", "cnn, cover set only",
                  "cnn, script set only"):
        row(label)
    say()
    # -- one training is one draw: the recipe with and without keypoints, three seeds each
    say("#### Three trainings each (seeds 0, 1, 2; mean over the four unseen sequences, orientation / opening; "
        "one training to the next moves a mean by 0.1-0.3°)")
    say()
    say("| model | seed 0 | seed 1 | seed 2 | **mean of three** | all 4 in ±3σ (mean) |")
    say("|---|---|---|---|---|---|")
    for label, tr_K in ((RECIPE_LABEL, None), (KEYPOINTS, K)):
        runs = [results[label]] + [train(f"{label}, seed {seed}", "cnn", imgs, Y, V, G, tr_K, seed=seed)[1]
                                   for seed in (1, 2)]
        cells = " | ".join(f"{r['mean orientation']:.2f} / {r['mean opening']:.2f}" for r in runs)
        o, q, band = (np.mean([r[k] for r in runs]) for k in ("mean orientation", "mean opening", "mean all in 3sd"))
        say(f"| {label} | {cells} | **{o:.2f} / {q:.2f}** | {100 * band:.1f} % |")
    say()
    # -- learning curve
    say("#### Learning curve (cnn + views; every k-th frame of the recipe's seven training sets; mean over the four "
        "unseen sequences)")
    say()
    say("| training crops | orientation | opening | all 4 in ±3σ | training (s) |")
    say("|---|---|---|---|---|")
    sizes = (1000, 2000, 4000, 8000, 12000, 20000)
    for n in sizes:
        idx = np.round(np.linspace(0, len(Y), n, endpoint=False)).astype(int)
        train(f"cnn, {n} crops", "cnn", [imgs[i] for i in idx], Y[idx], V[idx], G[idx])
    curve = [(f"cnn, {n} crops", n) for n in sizes] + [(RECIPE_LABEL, len(Y))]
    for label, n in curve:
        r = results[label]
        say(f"| {n} | {r['mean orientation']:.2f} | {r['mean opening']:.2f} | {100 * r['mean all in 3sd']:.1f} % | "
            f"{r['train seconds']:.0f} |")
    say()
    # -- error vs distance to the nearest training pose
    from scipy.spatial import cKDTree

    scale = Y.std(0)
    tree = cKDTree(Y / scale)
    rows = []
    for k in ("test", "test2"):
        d, _ = tree.query(data[k][2] / scale)
        e = errors(data[k][2], results[RECIPE_LABEL][k]["pred"], cols, names)
        eh = errors(data[k][2], results["HOG, script set (the thesis' model)"][k]["pred"], cols, names)
        rows.append((d, e["orientation"], e["opening"], eh["orientation"], eh["opening"]))
    d, eo, ep, ho, hp = (np.concatenate(c) for c in zip(*rows))
    say("#### Error against the distance from a test pose to the nearest training pose (unseen normal-light sequences; "
        "distance in standard deviations of the four angles)")
    say()
    say("| distance | frames | cnn: orientation / opening | HOG (script set): orientation / opening |")
    say("|---|---|---|---|")
    edges = np.quantile(d, [0, 0.25, 0.5, 0.75, 1.0])
    for lo, hi in zip(edges[:-1], edges[1:]):
        s = (d >= lo) & (d <= hi)
        say(f"| {lo:.2f}–{hi:.2f} | {s.sum()} | {eo[s].mean():.2f} / {ep[s].mean():.2f} | "
            f"{ho[s].mean():.2f} / {hp[s].mean():.2f} |")
    say()
    # -- protocols side by side
    if not args.skip_cv:
        say(f"#### Protocols side by side (the recipe's training sets, {len(Y)} crops; mean error, degrees, "
            "orientation / opening)")
        say()
        say("| protocol | HOG | cnn + views | HOG, all 4 in ±3σ | cnn, all 4 in ±3σ |")
        say("|---|---|---|---|---|")
        for split in ("random", "contiguous"):
            cells = []
            for feature, views in (("hog", None), ("cnn", V)):
                label = f"{feature} {split} 5-fold"
                if label not in cache:
                    X = PoseRegressor(feature=feature).features(imgs)
                    m, s, fm, _, _ = cross_validate(X, Y, names, 5, split=split, feature=feature, views=views)
                    keep(label, summary(Y, m, s, fm, cols, names))
                cells.append(cache[label])
                results[label] = cells[-1]
            say(f"| {split} 5-fold | {cells[0]['orientation']:.2f} / {cells[0]['opening']:.2f} | "
                f"{cells[1]['orientation']:.2f} / {cells[1]['opening']:.2f} | {100 * cells[0]['all in 3sd']:.1f} % | "
                f"{100 * cells[1]['all in 3sd']:.1f} % |")
        r = results[RECIPE_LABEL]
        h = results["HOG, seven sets"]
        say(f"| unseen sequences (mean of four) | {h['mean orientation']:.2f} / {h['mean opening']:.2f} | "
            f"{r['mean orientation']:.2f} / {r['mean opening']:.2f} | {100 * h['mean all in 3sd']:.1f} % | "
            f"{100 * r['mean all in 3sd']:.1f} % |")
        say()
    # -- cost
    one_img, one_view = data["test"][1][300], data["test"][3][300:301]
    kf = cnn_reg.make_filter()

    def frame():
        m, s = cnn_reg.predict([one_img], return_std=True, views=one_view)
        kf.step(m[0], s[0])

    frame()
    t1 = min(_timed(frame) for _ in range(30))
    batch, bviews = data["test"][1] * 4, np.concatenate([data["test"][3]] * 4)
    tb = min(_timed(lambda: cnn_reg.predict(batch, return_std=True, views=bviews)) for _ in range(2))
    t4000 = results["cnn, cover set only"]["train seconds"]
    say(f"Cost (2 CPU cores): training on 4000 crops {t4000:.0f} s (cover set; {len(Y)} crops: "
        f"{results[RECIPE_LABEL]['train seconds']:.0f} s: the network's cost is its "
        f"3000 mini-batches, whatever n), one frame (resize, network, GP mean and variance, Kalman step) "
        f"{1000 * t1:.2f} ms, batch {len(batch) / tb:.0f} frames/s.")
    text = "\n".join(lines)
    if not args.no_docs:
        replace_block(ROOT / "docs" / "pose.md", "pose-unseen", text)
        slim = {k: {q: ({kk: vv for kk, vv in v.items() if kk != "pred"} if isinstance(v, dict) else v)
                    for q, v in r.items()} for k, r in results.items()}
        (ROOT / "docs" / "pose_unseen.json").write_text(json.dumps(slim, indent=1, default=float) + "\n")
        print("updated docs/pose.md and docs/pose_unseen.json")


def _timed(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


if __name__ == "__main__":
    main()
