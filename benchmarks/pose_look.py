"""Pose models on another look of the same tool: ``pose render --style alt`` (a proxy for crops from a
renderer we do not have).

    .venv/bin/python benchmarks/pose_look.py MODEL [MODEL ...] [--out out/pose] [--no-write]

For each model (``artmotion pose train``; one that uses box views is given them), the unseen
sequences of benchmarks/pose_unseen.py (seeds 1 and 2, the pick-and-place script, 600 frames) are
scored in the default look and in the ``alt`` look — yellow tissue, brass jaws, a lighter stem, the
same motion and scene — rendered into ``--out`` when missing: orientation and opening error
(degrees), all four angles inside ±3σ, and the domain test's AUC
(:meth:`~artmotion.pose.model.PoseRegressor.domain_auc`). Writes docs/pose.md's table between
``<!-- pose-look -->``: the rows of the models given replace their earlier rows, the rows of other
models (scored by earlier runs) stay.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from _docs import replace_block

from artmotion.pose.data import load_labelled, read_views
from artmotion.pose.evaluate import Columns, summary
from artmotion.pose.model import PoseRegressor
from artmotion.pose.render import write_dataset

ROOT = Path(__file__).resolve().parents[1]
SETS = {"test": (1, "default"), "test_alt": (1, "alt"), "test2": (2, "default"), "test2_alt": (2, "alt")}


def load(out: Path, name: str):
    d = out / name
    seed, style = SETS[name]
    if not (d / "boxes.csv").exists():
        print(f"rendering {d} ...", flush=True)
        write_dataset(d, 600, seed, frames=True, style=style)
    _, paths, crops, Y = load_labelled(d / "crops", d / "labels.csv")
    return crops, Y, read_views(d / "boxes.csv", paths)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("models", nargs="+", type=Path)
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "pose")
    ap.add_argument("--no-write", action="store_true")
    a = ap.parse_args(argv)
    data = {k: load(a.out, k) for k in SETS}
    lines = ["| model | sequence | look | orientation | opening | all 4 in ±3σ | domain AUC |",
             "|---|---|---|---|---|---|---|"]
    for path in a.models:
        m = PoseRegressor.load(path)
        cols = Columns.from_names(m.names_)
        for name, (seed, style) in SETS.items():
            crops, Y, V = data[name]
            views = V if m.uses_views_ else None
            X = m.features(crops)  # once, for the prediction and the domain test
            mu, sd = m.predict(X, return_std=True, views=views)
            s = summary(Y, mu, sd, mu, cols, m.names_)
            lines.append(f"| {m.feature} ({path.name}) | seed {seed} | {style} | {s['orientation']:.2f} | "
                         f"{s['opening']:.2f} | {100 * s['all in 3sd']:.1f} % | {m.domain_auc(X, views):.2f} |")
            print(lines[-1], flush=True)
    doc = ROOT / "docs" / "pose.md"
    # rows of models not scored in this run stay (earlier models whose files are gone): the
    # block is a record of every model scored, each model's rows from its latest run
    names = {f"({path.name})" for path in a.models}
    block = re.search(r"<!-- pose-look -->\n(.*?)<!-- /pose-look -->", doc.read_text(encoding="utf-8"), re.S)
    kept = [line for line in (block.group(1).splitlines()[2:] if block else [])
            if line.startswith("| ") and not any(n in line for n in names)]
    text = "\n".join(lines[:2] + kept + lines[2:])
    print(text)
    if not a.no_write:
        replace_block(doc, "pose-look", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
