"""Figures for docs/pose.md from the outputs of ``artmotion pose eval --out DIR``.

    .venv/bin/python benchmarks/pose_figures.py out/pose/eval_random out/pose/normal out/pose/test out/pose/dark

(``eval`` run with ``--test-images/--test-labels`` and ``--dark-images/--dark-labels`` for those
two renders.) Writes docs/pose_regression_comparison.png (Sec. 3.3.2), docs/pose_band.png
(Fig. 3.4, cross-validated), docs/pose_filter.png (Fig. 3.6, cross-validated) and
docs/pose_filter_unseen.png (the same on the unseen normal-light sequence), docs/pose_dark.png (Table 3.2 / Fig. 3.8), docs/pose_samples.png and
docs/pose_dark_samples.png (rendered frames with boxes), and prints the frame-to-frame jitter
of the raw and filtered estimates on the unseen sequences.
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from artmotion.io import atomic_path  # noqa: E402
from artmotion.pose import plots  # noqa: E402
from artmotion.pose.data import read_labels  # noqa: E402


def load_pred(path):
    names, imgs, P = read_labels(path)
    return [n for n in names if not n.endswith("_std")], imgs, P[:, 0::2], P[:, 1::2]


def samples(data: Path, out: Path, frames=(40, 400, 900, 1500, 2300, 3100)):
    boxes = {r.split(",")[0]: [int(v) for v in r.split(",")[1:5]] for r in (data / "boxes.csv").read_text().splitlines()[1:]}
    tiles = []
    for f in frames:
        name = f"{f:06d}.jpg"
        if name not in boxes:
            continue
        img = cv2.imread(str(data / "frames" / name))
        x, y, w, h = boxes[name]
        cv2.rectangle(img, (x, y), (x + w, y + h), (0, 255, 0), 2)
        tiles.append(cv2.resize(img, (320, 240)))
    while len(tiles) % 3:
        tiles.append(np.zeros_like(tiles[0]))
    grid = np.vstack([np.hstack(tiles[i : i + 3]) for i in range(0, len(tiles), 3)])
    with atomic_path(out) as tmp:
        cv2.imwrite(str(tmp), grid)


def main():
    ev, data, test, dark = (Path(a) for a in sys.argv[1:5])
    docs = ROOT / "docs"
    print(plots.regression_comparison(docs / "pose_regression_comparison.png"))
    names, _, Y = read_labels(data / "labels.csv")
    k = names.index("opening")
    _, _, m, s = load_pred(ev / "cv_hog.csv")
    _, _, fm, _ = load_pred(ev / "cv_hog_filtered.csv")
    plots.band_plot(docs / "pose_band.png", Y[:, k], m[:, k], s[:, k], "opening (cross-validated)", start=3300, length=300)
    plots.filter_plot(docs / "pose_filter.png", Y[:, k], m[:, k], fm[:, k], "opening (cross-validated)", 3300, 300)
    samples(data, docs / "pose_samples.png")
    for key, seq in (("test", test), ("dark", dark)):
        _, _, tY = read_labels(seq / "labels.csv")
        _, _, tm, ts = load_pred(ev / f"{key}_hog.csv")
        _, _, fm, _ = load_pred(ev / f"{key}_hog_filtered.csv")
        jit = lambda P: np.abs(np.diff(P - tY, axis=0)).mean(0)  # noqa: E731  frame-to-frame error change
        print(key, "jitter raw     ", dict(zip(names, jit(tm).round(2))))
        print(key, "jitter filtered", dict(zip(names, jit(fm).round(2))))
        if key == "test":
            plots.filter_plot(docs / "pose_filter_unseen.png", tY[:, k], tm[:, k], fm[:, k], "opening (unseen sequence)", 0, 300)
        else:
            plots.band_plot(docs / "pose_dark.png", tY[:, k], tm[:, k], ts[:, k], "opening (dark, HOG)", 0, 300)
            samples(dark, docs / "pose_dark_samples.png", (20, 150, 280))


if __name__ == "__main__":
    main()
