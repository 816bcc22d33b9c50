"""Speed of the pose pipeline: features + GP prediction + Kalman step per frame, batch throughput,
training time and its growth with n (exact GP with local or exact variance vs sparse GP).

    .venv/bin/python benchmarks/pose.py [--data out/pose/normal] [--sizes 1000,2000,4000,8000] [--no-docs]

Uses rendered crops (``artmotion pose render``) when ``--data`` exists, otherwise renders a few
hundred. Sizes beyond the number of crops reuse crops with a small feature jitter (timing only).
Prints a Markdown table and writes it between the ``<!-- bench:pose -->`` markers of docs/pose.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from artmotion.pose.data import load_labelled  # noqa: E402
from artmotion.pose.filter import PoseFilter  # noqa: E402
from artmotion.pose.model import PoseRegressor  # noqa: E402


def best_of(fn, repeat=5):
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return min(ts), float(np.median(ts))


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", default=str(ROOT / "out" / "pose" / "normal"))
    ap.add_argument("--sizes", default="1000,2000,4000,8000")
    ap.add_argument("--exact-max", type=int, default=8000, help="largest n timed with the exact GP")
    ap.add_argument("--exact-var-max", type=int, default=2000, help="largest n timed with the exact O(n^2) variance")
    ap.add_argument("--inducing", default="1000", help="inducing-point counts of the sparse GP rows")
    ap.add_argument("--no-docs", action="store_true")
    args = ap.parse_args(argv)
    data = Path(args.data)
    if (data / "labels.csv").exists():
        names, paths, imgs, Y = load_labelled(data / "crops", data / "labels.csv")
    else:
        from artmotion.pose.render import write_dataset

        tmp = ROOT / "out" / "pose" / "bench"
        write_dataset(tmp, 400, seed=3, frames=False)
        names, paths, imgs, Y = load_labelled(tmp / "crops", tmp / "labels.csv")
    X = PoseRegressor().features(imgs)  # the default feature: HOG of the blurred 64x48 crop
    rng = np.random.default_rng(0)
    lines = []
    say = lambda s="": (print(s), lines.append(s))  # noqa: E731
    say(f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs (shared), "
        f"numpy {np.__version__}; {len(imgs)} rendered crops, HOG {X.shape[1]}-d → PCA 128, {Y.shape[1]} angles. "
        "exact/local = exact GP mean, variance from the 16 nearest training crops (the default up to n = 6000); "
        "exact/exact = the O(n²) variance.")
    say()
    # ---- training time and prediction cost vs n
    sizes = [int(s) for s in args.sizes.split(",")]
    say("| n | GP | train (s) | one frame: HOG + PCA + GP mean/std + Kalman (ms) | batch (frames/s, HOG + GP) |")
    say("|---|---|---|---|---|")
    one = imgs[len(imgs) // 2]
    kf = PoseFilter(np.ones(Y.shape[1]))
    batch_imgs = [imgs[i % len(imgs)] for i in range(2000)]
    for n in sizes:
        idx = rng.choice(len(X), size=n, replace=n > len(X))
        Xn = X[idx] + (rng.normal(0, 1e-3, (n, X.shape[1])) if n > len(X) else 0.0)
        Yn = Y[idx]
        variants = [("exact", "local", 0), ("exact", "exact", 0)] + [("sparse", "", int(m)) for m in args.inducing.split(",")]
        for method, var, m_ind in variants:
            label = f"{method}/{var}" if method == "exact" else f"sparse (m={m_ind})"
            if method == "exact" and n > (args.exact_max if var == "local" else args.exact_var_max):
                continue
            if method == "sparse" and n <= m_ind:
                continue
            t = time.perf_counter()
            reg = PoseRegressor(feature="hog", method=method, n_inducing=m_ind, neighbours=16 if var == "local" else None)
            reg.fit(Xn.astype(np.float32), Yn, names)
            train = time.perf_counter() - t

            def frame():
                m, s = reg.predict([one], return_std=True)
                kf.step(m[0], s[0])

            frame()
            t1, _ = best_of(frame, 20)
            tb, _ = best_of(lambda: reg.predict(batch_imgs, return_std=True), 2)
            say(f"| {n} | {label} | {train:.1f} | "
                f"{1000 * t1:.2f} | {len(batch_imgs) / tb:.0f} |")
    say()
    hog, lbp = PoseRegressor(feature="hog"), PoseRegressor(feature="lbp")
    t_feat, _ = best_of(lambda: hog.features([one]), 50)
    t_feat_b, _ = best_of(lambda: hog.features(batch_imgs), 2)
    t_lbp, _ = best_of(lambda: lbp.features([one]), 50)
    t_kf, _ = best_of(lambda: kf.step(np.zeros(Y.shape[1]), np.ones(Y.shape[1])), 200)
    say(f"Parts of one frame: HOG (resize, blur) {1000 * t_feat:.2f} ms (batch {len(batch_imgs) / t_feat_b:.0f} frames/s), "
        f"LBP {1000 * t_lbp:.2f} ms, Kalman step (4 angles) {1000 * t_kf:.3f} ms.")
    text = "\n".join(lines)
    doc = ROOT / "docs" / "pose.md"
    if not args.no_docs and doc.exists():
        s = doc.read_text()
        new = re.sub(r"<!-- bench:pose -->.*<!-- /bench:pose -->",
                     lambda _: "<!-- bench:pose -->\n" + text + "\n<!-- /bench:pose -->", s, flags=re.S)
        from artmotion.io import atomic_write

        with atomic_write(doc) as fh:
            fh.write(new)
        print(f"updated {doc}")


if __name__ == "__main__":
    main()
