#!/usr/bin/env python
"""Leave-one-sequence-out choice of a few settings of the tracker, the others at the defaults.

The full search (``benchmarks/tracking_loo.py``) moves every setting and costs hours; a setting
added later is chosen here on a grid, by the same rule: a fold holds one sequence out, takes the
grid point with the best mean objective ``(MOTA + IDF1 + HOTA) / 3`` over the other sequences'
items, and scores the held-out sequence's items with it. The items are the thirteen of
docs/tracking.md: the five sequences with their published detections, the three with weak ones
(ACF, DPM) and the five with the built-in SSDLite detector's boxes on every second frame (what
most users track; detections cached as by ``benchmarks/detector.py``). Ties on the training items
go to the first grid point (the grid's order, ``off`` first).

Usage::

    python benchmarks/tracking_setting.py --grid duplicate_share=0,0.3,0.45,0.6 \\
        --grid duplicate_drift=0.03,0.05,0.06,0.07,0.08 [--block tracking-duplicates]

Prints the grid's scores and the held-out table; with ``--block`` writes them into that block of
docs/tracking.md.
"""

from __future__ import annotations

import argparse
import itertools
import multiprocessing as mp
import sys
from dataclasses import fields, replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "benchmarks"))

import tracking_loo  # noqa: E402
from _docs import replace_block  # noqa: E402
from detector import _hash, track_scores  # noqa: E402
from tracking_loo import BUILTIN, ITEMS, SEQUENCES, _cells, _load, _means, weak_items  # noqa: E402
from tracking_loo import objective as loo_objective  # noqa: E402

from artmotion.tracking import DEFAULT_EXPERTS, TrackerConfig  # noqa: E402
from artmotion.tracking.config import DETECT_EVERY  # noqa: E402

ALL_ITEMS = [*ITEMS, *(f"{n}:{BUILTIN}" for n in SEQUENCES)]
_DATA: dict = {}


def _prepare(cache: Path) -> None:
    """Frames and detections of every item (tracking_loo's loader caches them), loaded before the
    workers fork: ``{item: (detections, every k-th frame detected)}``."""
    tracking_loo.BUILTIN_CACHE = cache
    for item in ALL_ITEMS:
        name, _, det = item.partition(":")
        _DATA[item] = (_load(name, det or "det.txt")[3], DETECT_EVERY if det == BUILTIN else 1)


def _score(job: tuple[str, dict, str]) -> tuple[str, str, dict]:
    label, changes, item = job
    dets, every = _DATA[item]
    bools = {f.name for f in fields(TrackerConfig) if f.type in ("bool", bool)}
    changes = {k: bool(v) if k in bools else v for k, v in changes.items()}
    return label, item, track_scores(item.partition(":")[0], dets, DEFAULT_EXPERTS, every,
                                     replace(TrackerConfig(), **changes))


def objective(scores: dict, items) -> float:
    """Mean (MOTA + IDF1 + HOTA) / 3 over ``items``, in %."""
    return 100 * loo_objective(scores, items)


def run(grid: dict[str, list[float]], off: dict, cache: Path, workers: int = 2) -> dict:
    """``{label: {item: scores}}`` for ``off`` and every point of ``grid``."""
    points = {"off": off}
    for values in itertools.product(*grid.values()):
        points[", ".join(f"{k}={v:g}" for k, v in zip(grid, values))] = dict(zip(grid, values))
    _prepare(cache)
    jobs = [(label, p, item) for label, p in points.items() for item in ALL_ITEMS]
    res: dict = {label: {} for label in points}
    with mp.get_context("fork").Pool(workers) as pool:
        for label, item, s in pool.imap_unordered(_score, jobs):
            res[label][item] = s
    return res


def tables(res: dict) -> str:
    grid = ["| setting | " + " | ".join(ALL_ITEMS) + " | objective |", "|---|" + "---:|" * (len(ALL_ITEMS) + 1)]
    for label, s in res.items():
        grid.append(f"| {label} | " + " | ".join(f"{objective(s, [i]):.1f}" for i in ALL_ITEMS)
                    + f" | {objective(s, ALL_ITEMS):.2f} |")
    held, lines = {}, ["| held out | chosen on the other sequences | detections | MOTA | IDF1 | HOTA | off |",
                       "|---|---|---|---:|---:|---:|---|"]
    for name in SEQUENCES:
        train = [i for i in ALL_ITEMS if i.split(":")[0] != name]
        choice = max(res, key=lambda label: objective(res[label], train))   # ties: the first ("off")
        for item in (i for i in ALL_ITEMS if i.split(":")[0] == name):
            held[item] = res[choice][item]
            lines.append(f"| {name} | {choice} | {item.partition(':')[2] or 'det.txt'} | {_cells(held[item])} | "
                         f"{_cells(res['off'][item]).replace(' | ', ' / ')} |")
    for group, items in (("published", list(SEQUENCES)), ("weak", weak_items(ITEMS)),
                         ("SSDLite", [i for i in ALL_ITEMS if i.endswith(BUILTIN)])):
        lines.append(f"| **mean** | | {group} | {_cells(_means(held, items))} | "
                     f"{_cells(_means(res['off'], items)).replace(' | ', ' / ')} |")
    summary = (f"Held-out objective over the thirteen items {objective(held, ALL_ITEMS):.2f} against "
               f"{objective(res['off'], ALL_ITEMS):.2f} with the setting off.")
    return "Mean of (MOTA + IDF1 + HOTA) / 3 per item:\n\n" + "\n".join(grid) + "\n\nHeld out:\n\n" + "\n".join(lines) + \
        "\n\n" + summary


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grid", action="append", required=True, help="NAME=V1,V2,... (a setting of TrackerConfig)")
    ap.add_argument("--off", default=None, help="NAME=V: the setting that turns the component off "
                                                "(default: the first --grid setting at 0)")
    ap.add_argument("--cache", default=None, help="SSDLite detections (default: out/detections-<hash of detectors.py>)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--block", default=None, help="write the tables into this block of docs/tracking.md")
    args = ap.parse_args(argv)
    grid = {}
    for g in args.grid:
        name, _, values = g.partition("=")
        grid[name] = [float(v) for v in values.split(",")]
    name, _, value = (args.off or f"{next(iter(grid))}=0").partition("=")
    off = {name: float(value)}
    grid[name] = [v for v in grid[name] if v != off[name]]
    res = run(grid, off, Path(args.cache or ROOT / "out" / f"detections-{_hash()}"), args.workers)
    text = tables(res)
    print(text)
    if args.block:
        replace_block(ROOT / "docs" / "tracking.md", args.block, text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
