#!/usr/bin/env python
"""The built-in person detectors (issue #12) on the five shared sequences, against the published
Faster R-CNN detections: detection quality (average precision at IoU 0.5), what the tracker makes
of them (MOTA / IDF1 / HOTA with the package's default settings) and what they cost.

Candidates: SSDLite-MobileNetV2 (``ssdlite``) with the shorter side of its input at 300 (its
training size), 384 or 480 pixels, and OpenCV's HOG (``hog``, the floor). The input size is chosen
by leave-one-sequence-out on the tracking objective (the mean of (MOTA + IDF1 + HOTA) / 3, as in
``benchmarks/tracking_loo.py``). Then the cheaper schedule of issue #12: the detector on every
k-th frame only, the tracking experts carrying the boxes in between.

Detections are cached per sequence and candidate (``out/detections-<hash>/``, MOTChallenge text
with the seconds they took), so a re-run only tracks. Prints the tables and writes them into
docs/tracking.md (``--out -``: print only).

Usage::

    python benchmarks/detector.py [--out docs/tracking.md] [--sequences PETS09-S2L1,...]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from tracking import replace_block  # noqa: E402
from tracking_loo import KEYS, SEQUENCES  # noqa: E402

from artmotion.geometry import iou  # noqa: E402
from artmotion.io import read_mot, write_mot  # noqa: E402
from artmotion.tracking import MultiObjectTracker, TrackerConfig, evaluate, open_sequence, run_tracker  # noqa: E402
from artmotion.tracking.api import _work_reduce  # noqa: E402
from artmotion.tracking.detect import load_detections  # noqa: E402
from artmotion.tracking.detectors import HOGDetector, SSDLiteDetector  # noqa: E402

SIDES = (300, 384, 480)
CANDIDATES = {**{f"ssdlite-{s}": (SSDLiteDetector, {"short_side": s}) for s in SIDES}, "hog": (HOGDetector, {})}
EVERY = (1, 2, 3, 5)


def _hash() -> str:
    return hashlib.sha256((ROOT / "src/artmotion/tracking/detectors.py").read_bytes()).hexdigest()[:12]


def detections(name: str, cand: str, frames, cache: Path) -> tuple[dict, float]:
    """``{frame: (N, 5)}`` of candidate ``cand`` on sequence ``name`` and the seconds it took
    (from the cache when there)."""
    path = cache / name / f"{cand}.txt"
    meta = path.with_suffix(".json")
    if not meta.is_file():
        cls, params = CANDIDATES[cand]
        det = cls(**params)
        rows, t0 = [], time.perf_counter()
        for n, img in frames():
            d = det(img)
            rows += [[n, -1, *r[:4], r[4], -1, -1, -1] for r in d]
        seconds = time.perf_counter() - t0
        path.parent.mkdir(parents=True, exist_ok=True)
        write_mot(path, np.array(rows).reshape(-1, 10))
        meta.write_text(json.dumps({"seconds": seconds}))
    return (load_detections(path) if path.stat().st_size else {}), json.loads(meta.read_text())["seconds"]


def ground_truth(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(boxes to find, boxes to ignore) as MOT rows: MOT17 rules for 9-column ground truth
    (pedestrians with consider = 1; distractor classes ignored), else rows with conf 0 ignored."""
    g = read_mot(path)
    care = (g[:, 6] == 1) & (g[:, 7] == 1) if g.shape[1] == 9 else g[:, 6] != 0
    return g[care], g[~care]


def average_precision(dets: dict, gt: np.ndarray, ignored: np.ndarray) -> dict:
    """PASCAL VOC all-point average precision at IoU 0.5 over all frames; a detection on an ignored
    box is neither right nor wrong. Also the recall and precision of the detections scored >= 0.5."""
    hits = []
    for f in np.unique(np.concatenate([gt[:, 0], np.array(list(dets), dtype=float)])).astype(int):
        d = dets.get(f)
        if d is None or not len(d):
            continue
        g, ig = gt[gt[:, 0] == f, 2:6], ignored[ignored[:, 0] == f, 2:6]
        free = np.ones(len(g), bool)
        for i in np.argsort(-d[:, 4], kind="stable"):
            if len(g):
                o = np.where(free, np.asarray(iou(d[i:i + 1, :4], g)).reshape(-1), -1.0)
                j = int(np.argmax(o))
                if o[j] >= 0.5:
                    free[j] = False
                    hits.append((d[i, 4], 1))
                    continue
            if len(ig) and np.asarray(iou(d[i:i + 1, :4], ig)).max() >= 0.5:
                continue
            hits.append((d[i, 4], 0))
    if not hits or not len(gt):
        return {"AP": 0.0, "R@0.5": 0.0, "P@0.5": 0.0}
    score, hit = np.array(sorted(hits, key=lambda h: -h[0])).T
    tp = np.cumsum(hit)
    recall, precision = tp / len(gt), tp / np.arange(1, len(tp) + 1)
    envelope = np.maximum.accumulate(precision[::-1])[::-1]
    ap = float(np.sum(np.diff(np.concatenate([[0.0], recall])) * envelope))
    n5 = int((score >= 0.5).sum())
    return {"AP": ap, "R@0.5": float(tp[n5 - 1] / len(gt)) if n5 else 0.0,
            "P@0.5": float(tp[n5 - 1] / n5) if n5 else 0.0}


def track_scores(seq, frames, dets: dict, gt_path: Path, experts=("det", "motion"), every: int = 1) -> dict:
    """MOTA/IDF1/HOTA of the tracker (default settings) on ``dets`` kept on every ``every``-th frame."""
    red = _work_reduce(seq.width, seq.height)
    tracker = MultiObjectTracker(seq.fps, seq.width, seq.height, experts=experts, config=TrackerConfig())
    n = run_tracker(tracker, frames(red), dets, reduce=red, decode=red, detect_every=every)
    rows, _ = tracker.finish(n)
    s = evaluate(gt_path, rows)
    return {k: float(s[k]) for k in KEYS}


def objective(s: dict) -> float:
    return float(np.mean([s[k] for k in KEYS]))


def _cells(s: dict, keys=KEYS) -> str:
    return " | ".join(f"{100 * s[k]:.1f}" for k in keys)


def run(names, cache: Path, log=print) -> dict:
    res: dict = {"seq": {}}
    for name in names:
        path = SEQUENCES[name]
        seq = open_sequence(path)
        full = list(seq.frames())
        small: dict = {}

        def frames(reduce: int = 1, full=full, seq=seq, small=small):
            if reduce == 1:
                return iter(full)
            if reduce not in small:
                small[reduce] = list(seq.frames(reduce=reduce))
            return iter(small[reduce])

        gt, ignored = ground_truth(path / "gt" / "gt.txt")
        r: dict = {"frames": len(full), "size": f"{seq.width}x{seq.height}"}
        pub = load_detections(path / "det" / "det.txt")
        r["published"] = {**average_precision(pub, gt, ignored),
                          **track_scores(seq, frames, pub, path / "gt" / "gt.txt")}
        for cand in CANDIDATES:
            dets, seconds = detections(name, cand, frames, cache)
            r[cand] = {**average_precision(dets, gt, ignored), **track_scores(seq, frames, dets, path / "gt" / "gt.txt"),
                       "fps": len(full) / seconds}
            log(f"{name} {cand}: AP {r[cand]['AP']:.3f}  MOTA/IDF1/HOTA {_cells(r[cand])}  {r[cand]['fps']:.1f} frames/s")
        res["seq"][name] = r
    return res


def choose_side(res: dict) -> dict:
    """Leave one sequence out: the short side with the best mean objective on the others."""
    names = list(res["seq"])
    out = {}
    for held in [*names, "all"]:
        train = [n for n in names if n != held]
        side = max(SIDES, key=lambda s: (np.mean([objective(res["seq"][n][f"ssdlite-{s}"]) for n in train]), -s))
        out[held] = side
    return out


def choose_every(every: dict, names) -> dict:
    """Leave one sequence out: the k (detector on every k-th frame, experts det,motion) with the
    best mean objective on the others."""
    ks = sorted({k for k, e in every if e == "det,motion"})
    out = {}
    for held in [*names, "all"]:
        train = [n for n in names if n != held]
        out[held] = max(ks, key=lambda k: (np.mean([objective(every[(k, "det,motion")][n]) for n in train]), -k))
    return out


def every_k(res: dict, side: int, names, cache: Path, log=print) -> dict:
    """Tracking with the detector on every k-th frame, with and without the KLT expert."""
    out: dict = {}
    for name in names:
        path = SEQUENCES[name]
        seq = open_sequence(path)
        small = list(seq.frames(reduce=_work_reduce(seq.width, seq.height)))
        dets, _ = detections(name, f"ssdlite-{side}", None, cache)
        for k in EVERY:
            for experts in (("det", "motion"), ("det", "klt", "motion")):
                s = track_scores(seq, lambda red, small=small: iter(small), dets, path / "gt" / "gt.txt", experts, k)
                out.setdefault((k, ",".join(experts)), {})[name] = s
        log(f"{name}: every-k done")
    return out


def tables(res: dict, sides: dict, every: dict | None) -> str:
    names = list(res["seq"])
    cols = ["published", *CANDIDATES]
    lines = ["| sequence | detections | AP@0.5 | recall / precision at score 0.5 | MOTA | IDF1 | HOTA | detector frames/s |",
             "|---|---|---:|---:|---:|---:|---:|---:|"]
    for name in names:
        r = res["seq"][name]
        for c in cols:
            s = r[c]
            fps = f"{s['fps']:.1f}" if "fps" in s else ""
            lines.append(f"| {name} | {c} | {100 * s['AP']:.1f} | {100 * s['R@0.5']:.0f} / {100 * s['P@0.5']:.0f} | "
                         f"{_cells(s)} | {fps} |")
    for c in cols:
        m = {k: float(np.mean([res["seq"][n][c][k] for n in names])) for k in ("AP", *KEYS)}
        lines.append(f"| **mean** | {c} | {100 * m['AP']:.1f} | | {_cells(m)} | |")
    held = [res["seq"][n][f"ssdlite-{sides[n]}"] for n in names]
    hm = {k: float(np.mean([h[k] for h in held])) for k in KEYS}
    lines += ["", "Leave one sequence out, the short side of the SSDLite input chosen on the other four "
              "(tracking objective):", "",
              "| held out | chosen short side | MOTA | IDF1 | HOTA |", "|---|---:|---:|---:|---:|"]
    for n, h in zip(names, held):
        lines.append(f"| {n} | {sides[n]} | {_cells(h)} |")
    lines.append(f"| **mean** | (all five: {sides['all']}) | {_cells(hm)} |")
    if every:
        lines += ["", f"The detector (short side {sides['all']}) on every k-th frame only, the tracker carrying the "
                  "boxes in between; mean over the sequences:", "",
                  "| every k-th frame | experts | MOTA | IDF1 | HOTA |", "|---:|---|---:|---:|---:|"]
        for (k, experts), per in every.items():
            m = {key: float(np.mean([per[n][key] for n in names])) for key in KEYS}
            lines.append(f"| {k} | {experts} | {_cells(m)} |")
        ks = choose_every(every, names)
        held = [every[(ks[n], "det,motion")][n] for n in names]
        lines += ["", "Leave one sequence out, k chosen on the other four (experts det,motion):", "",
                  "| held out | chosen k | MOTA | IDF1 | HOTA | every frame: MOTA | IDF1 | HOTA |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|"]
        for n, h in zip(names, held):
            lines.append(f"| {n} | {ks[n]} | {_cells(h)} | {_cells(every[(1, 'det,motion')][n])} |")
        m1 = {key: float(np.mean([every[(1, "det,motion")][n][key] for n in names])) for key in KEYS}
        hm = {key: float(np.mean([h[key] for h in held])) for key in KEYS}
        lines.append(f"| **mean** | (all five: {ks['all']}) | {_cells(hm)} | {_cells(m1)} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "tracking.md"), help="markdown file to update; - to print only")
    ap.add_argument("--sequences", default=",".join(SEQUENCES))
    ap.add_argument("--cache", default=None, help="detections cache (default: out/detections-<hash of detectors.py>)")
    ap.add_argument("--no-every", action="store_true", help="skip the every-k-th-frame schedule")
    args = ap.parse_args(argv)
    names = args.sequences.split(",")
    cache = Path(args.cache or ROOT / "out" / f"detections-{_hash()}")
    log = lambda m: print(m, flush=True)  # noqa: E731
    res = run(names, cache, log)
    sides = choose_side(res)
    every = None if args.no_every else every_k(res, sides["all"], names, cache, log)
    text = tables(res, sides, every)
    print(text)
    if args.out != "-":
        replace_block(Path(args.out), "detector-benchmark", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
