"""Figures for docs/pose.md from the outputs of ``artmotion pose eval --out DIR``.

    .venv/bin/python benchmarks/pose_figures.py out/pose/eval out/pose/normal [out/pose/dark]

Writes docs/pose_regression_comparison.png (Sec. 3.3.2), docs/pose_band.png (Fig. 3.4),
docs/pose_filter.png (Fig. 3.6), docs/pose_dark.png (Table 3.2 / Fig. 3.8) and
docs/pose_samples.png (rendered frames with boxes).
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
    boxes = {r.split(",")[0]: [int(v) for v in r.split(",")[1:]] for r in (data / "boxes.csv").read_text().splitlines()[1:]}
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
    ev, data = Path(sys.argv[1]), Path(sys.argv[2])
    dark = Path(sys.argv[3]) if len(sys.argv) > 3 else None
    docs = ROOT / "docs"
    print(plots.regression_comparison(docs / "pose_regression_comparison.png"))
    names, _, Y = read_labels(data / "labels.csv")
    k = names.index("opening")
    _, _, m, s = load_pred(ev / "cv_hog.csv")
    _, _, fm, _ = load_pred(ev / "cv_hog_filtered.csv")
    jit = lambda P: np.abs(np.diff(P - Y, axis=0)).mean(0)  # noqa: E731  frame-to-frame error change
    print("jitter raw     ", dict(zip(names, jit(m).round(2))))
    print("jitter filtered", dict(zip(names, jit(fm).round(2))))
    plots.band_plot(docs / "pose_band.png", Y[:, k], m[:, k], s[:, k], "opening", start=3300, length=300)
    plots.filter_plot(docs / "pose_filter.png", Y[:, k], m[:, k], fm[:, k], "opening", start=3300, length=300)
    samples(data, docs / "pose_samples.png")
    if dark is not None and (ev / "dark_hog.csv").exists():
        _, _, dY = read_labels(dark / "labels.csv")
        _, _, dm, ds = load_pred(ev / "dark_hog.csv")
        plots.band_plot(docs / "pose_dark.png", dY[:, k], dm[:, k], ds[:, k], "opening (dark, HOG)", 0, 300)
        samples(dark, docs / "pose_dark_samples.png", (20, 150, 280))


if __name__ == "__main__":
    main()
