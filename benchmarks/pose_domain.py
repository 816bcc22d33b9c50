"""Does a pose model apply to these crops? ``PoseRegressor.domain_auc`` on renders and real instruments.

    .venv/bin/python benchmarks/pose_domain.py MODEL [MODEL ...] --renders DIR [DIR ...] [--lap DIR] [--no-write]

MODEL: pose models (``artmotion pose train``); DIR: render folders (``artmotion pose render``: crops/,
labels.csv, boxes.csv) the models were not trained on; ``--lap``: the shared laparoscopic frames and
tools.csv, whose true heads are cropped as ``artmotion run --tool-model`` crops tracked heads (a
square of the head's size). For each model and set: the AUC with which the crops are told from
their nearest training crops, over the whole set and over stretches of 100 and 300 crops (the
smallest and largest), and whether ``artmotion run`` would say anything about the opening.
Writes docs/surgical.md's table between ``<!-- pose-domain -->``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np
from _docs import replace_block

from artmotion.pose.data import load_labelled, read_views
from artmotion.pose.features import box_views
from artmotion.pose.model import PoseRegressor, is_foreign
from artmotion.tracking.instruments.annotations import read_tools_csv


def render_set(folder: Path):
    _, paths, crops, _ = load_labelled(folder / "crops", folder / "labels.csv")
    return crops, read_views(folder / "boxes.csv", paths)


def lap_set(root: Path):
    gt = read_tools_csv(root / "tools.csv")
    crops, boxes = [], []
    for f in sorted(gt):
        img = cv2.imread(str(root / "frames" / f"{f:06d}.png"))
        H, W = img.shape[:2]
        for x, y, s, _a in gt[f]:
            x0, y0, x1, y1 = int(max(0, x - s / 2)), int(max(0, y - s / 2)), int(min(W, x + s / 2)), int(min(H, y + s / 2))
            if x1 - x0 >= 4 and y1 - y0 >= 4:
                crops.append(img[y0:y1, x0:x1])
                boxes.append((x0, y0, x1 - x0, y1 - y0))
    return crops, box_views(boxes, (W, H))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("models", nargs="+", type=Path)
    ap.add_argument("--renders", nargs="+", type=Path, default=[])
    ap.add_argument("--lap", type=Path, default=Path("../shared/data/surgical/lap-tools"))
    ap.add_argument("--no-write", action="store_true")
    a = ap.parse_args(argv)
    sets = {f"renders {d.name}": render_set(d) for d in a.renders}
    sets["real laparoscopic heads"] = lap_set(a.lap)
    lines = ["| pose model | crops | n | AUC, all | AUC, stretches of 100 | AUC, stretches of 300 | opening said |",
             "|---|---|---|---|---|---|---|"]
    for path in a.models:
        m = PoseRegressor.load(path)
        for name, (crops, views) in sets.items():
            v = views if m.uses_views_ else None
            X = m.features(crops)  # once for the whole set and its stretches
            whole = m.domain_auc(X, v)
            span = []
            for w in (100, 300):
                aucs = [a for a in (m.domain_auc(X[s:s + w], None if v is None else v[s:s + w])
                                    for s in range(0, len(crops) - w + 1, w)) if not np.isnan(a)]
                span.append(f"{min(aucs):.2f}–{max(aucs):.2f}" if aucs else "—")
            said = "yes (not judged)" if np.isnan(whole) else "no" if is_foreign(whole) else "yes"
            lines.append(f"| {m.feature} ({path.name}) | {name} | {len(crops)} | {whole:.2f} | {span[0]} | {span[1]} | "
                         f"{said} |")
            print(lines[-1], flush=True)
    text = "\n".join(lines)
    print(text)
    if not a.no_write:
        replace_block(Path(__file__).resolve().parents[1] / "docs" / "surgical.md", "pose-domain", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
