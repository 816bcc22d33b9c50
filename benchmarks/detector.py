#!/usr/bin/env python
"""The built-in person detectors (issue #12) on the five shared sequences, against the published
Faster R-CNN detections: detection quality (average precision at IoU 0.5), what the tracker makes
of them (MOTA / IDF1 / HOTA with the package's default settings) and what they cost.

Candidates: SSDLite-MobileNetV2 (``ssdlite``) with the shorter side of its input at 300 (its
training size), 384 or 480 pixels, and OpenCV's HOG (``hog``, the floor). The input size is chosen
by leave-one-sequence-out on the tracking objective (the mean of (MOTA + IDF1 + HOTA) / 3, as in
``benchmarks/tracking_loo.py``). Then the cheaper schedule of issue #12: the detector on every
k-th frame only, the tracking experts carrying the boxes in between. Last, the four peer trackers
of ``benchmarks/tracking.py`` on the same SSDLite boxes (``--no-peers`` skips them; they need
``.venv-peers``, made by ``make bench``): their score settings were made for other detectors' scores,
so each peer's are chosen by leave-one-sequence-out too (:data:`PEER_GRID`), and the held-out
scores are set against artmotion's default, the detector on every second frame.

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
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _docs import replace_block  # noqa: E402
from tracking_loo import KEYS, SEQUENCES, _load  # noqa: E402

from artmotion.geometry import iou  # noqa: E402
from artmotion.io import read_mot, write_mot  # noqa: E402
from artmotion.tracking import MultiObjectTracker, TrackerConfig, evaluate, open_sequence, run_tracker  # noqa: E402
from artmotion.tracking.config import DETECT_EVERY  # noqa: E402
from artmotion.tracking.detect import load_detections  # noqa: E402
from artmotion.tracking.detectors import HOGDetector, SSDLiteDetector  # noqa: E402
from artmotion.tracking.metrics import apply_rules  # noqa: E402

COUNTS = ("IDS", "FP", "FN")
SIDES = (300, 384, 480)
CANDIDATES = {**{f"ssdlite-{s}": (SSDLiteDetector, {"short_side": s}) for s in SIDES}, "hog": (HOGDetector, {})}
EVERY = (1, 2, 3, 5)
#: each peer's score settings searched on the built-in detector's boxes, its defaults first (the
#: keyword arguments of its constructor), each with the boxes under a score dropped beforehand
#: (:data:`PEER_DROP`; 0.05 is the detector's own floor: none dropped)
_PAIRS = ({}, {"track_activation_threshold": 0.5, "high_conf_det_threshold": 0.4},
          {"track_activation_threshold": 0.4, "high_conf_det_threshold": 0.3},
          {"track_activation_threshold": 0.3, "high_conf_det_threshold": 0.2})
PEER_GRID = {"sort": ({}, *({"track_activation_threshold": t} for t in (0.4, 0.55, 0.7))),
             "bytetrack": _PAIRS,
             "ocsort": ({}, *({"high_conf_det_threshold": h} for h in (0.4, 0.3, 0.2))),
             "botsort": _PAIRS}
PEER_DROP = (0.05, 0.2, 0.3, 0.4)


def _hash() -> str:
    return hashlib.sha256((ROOT / "src/artmotion/tracking/detectors.py").read_bytes()).hexdigest()[:12]


def detections(name: str, cand: str, cache: Path) -> tuple[dict, float]:
    """``{frame: (N, 5)}`` of candidate ``cand`` on sequence ``name`` and the seconds it took
    (from the cache when there; frames are decoded only to fill it)."""
    path = cache / name / f"{cand}.txt"
    meta = path.with_suffix(".json")
    if not meta.is_file():
        cls, params = CANDIDATES[cand]
        det = cls(**params)
        rows, t0 = [], time.perf_counter()
        for n, img in open_sequence(SEQUENCES[name]).frames():
            rows += [[n, -1, *r[:4], r[4], -1, -1, -1] for r in det(img)]
        seconds = time.perf_counter() - t0
        path.parent.mkdir(parents=True, exist_ok=True)
        write_mot(path, np.array(rows).reshape(-1, 10))
        meta.write_text(json.dumps({"seconds": seconds}))
    return (load_detections(path) if path.stat().st_size else {}), json.loads(meta.read_text())["seconds"]


def average_precision(dets: dict, gt_path: Path) -> dict:
    """PASCAL VOC all-point average precision at IoU 0.5 over all frames, under the rules the
    tracks are scored by (:func:`artmotion.tracking.metrics.apply_rules`: MOT17's on MOT16-09 —
    pedestrians only, detections on distractors removed). Also the recall and precision of the
    detections scored >= 0.5."""
    rows = np.array([[f, -1, *r] for f, d in dets.items() for r in d]).reshape(-1, 7)
    gt, rows = apply_rules(read_mot(gt_path), rows, "auto")
    hits = []
    for f in np.unique(rows[:, 0]):
        d, g = rows[rows[:, 0] == f], gt[gt[:, 0] == f, 2:6]
        free = np.ones(len(g), bool)
        for i in np.argsort(-d[:, 6], kind="stable"):
            o = np.where(free, iou(d[i, 2:6], g), -1.0) if len(g) else np.zeros(1) - 1.0
            j = int(np.argmax(o))
            hit = bool(o[j] >= 0.5)
            if hit:
                free[j] = False
            hits.append((d[i, 6], hit))
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


def track_scores(name: str, dets: dict, experts=("det", "motion"), every: int = 1,
                 config: TrackerConfig | None = None) -> dict:
    """MOTA/IDF1/HOTA of the tracker (``config``, default settings) on ``dets`` of sequence
    ``name``, the detections used on every ``every``-th frame (frames decoded once, by
    tracking_loo's loader)."""
    seq, red, frames, _, gt_path = _load(name)
    tracker = MultiObjectTracker(seq.fps, seq.width, seq.height, experts=experts, config=config or TrackerConfig())
    n = run_tracker(tracker, iter(frames), dets, reduce=red, decode=red, detect_every=every)
    rows, _ = tracker.finish(n)
    return _scores(evaluate(gt_path, rows))


def _scores(s: dict) -> dict:
    """The scores of :func:`~artmotion.tracking.metrics.evaluate`'s answer that the tables show."""
    return {**{k: float(s[k]) for k in KEYS}, **{k: int(s[k]) for k in COUNTS}}


def objective(s: dict) -> float:
    return float(np.mean([s[k] for k in KEYS]))


def _cells(s: dict, keys=KEYS) -> str:
    return " | ".join(f"{100 * s[k]:.1f}" for k in keys)


def run(names, cache: Path, log=print) -> dict:
    res: dict = {"seq": {}}
    for name in names:
        seq, _, _, published, gt_path = _load(name)
        r: dict = {"published": {**average_precision(published, gt_path), **track_scores(name, published)}}
        for cand in CANDIDATES:
            dets, seconds = detections(name, cand, cache)
            r[cand] = {**average_precision(dets, gt_path), **track_scores(name, dets), "fps": seq.length / seconds}
            log(f"{name} {cand}: AP {r[cand]['AP']:.3f}  MOTA/IDF1/HOTA {_cells(r[cand])}  {r[cand]['fps']:.1f} frames/s")
        res["seq"][name] = r
    return res


def loo_choice(scores: dict, names) -> dict:
    """Leave one sequence out: for each held-out sequence (and ``all``), the candidate of
    ``scores`` (candidate -> sequence -> MOTA/IDF1/HOTA) with the best mean objective on the
    others; ties go to the first candidate."""
    cands = list(scores)
    return {held: max(cands, key=lambda c: (np.mean([objective(scores[c][n]) for n in names if n != held]),
                                            -cands.index(c)))
            for held in [*names, "all"]}


def every_k(side: int, names, cache: Path, log=print) -> dict:
    """Tracking with the detector on every k-th frame, with and without the KLT expert:
    ``{(k, experts): {sequence: scores}}``."""
    out: dict = {}
    for name in names:
        dets, _ = detections(name, f"ssdlite-{side}", cache)
        for k in EVERY:
            for experts in (("det", "motion"), ("det", "klt", "motion")):
                out.setdefault((k, ",".join(experts)), {})[name] = track_scores(name, dets, experts, k)
        log(f"{name}: every-k done")
    return out


def peers_on_builtin(names, cache: Path, side: int, every_frame: dict, log=print) -> str:
    """The peers on SSDLite's boxes (every frame, the ``side`` input), each peer's score settings
    chosen by leave-one-sequence-out over :data:`PEER_GRID` x :data:`PEER_DROP`, against artmotion's
    default (the detector on every second frame; ``every_frame``: its scores with the detector on
    every frame, per sequence, for reference, as :func:`run` measured them): a markdown table of
    the held-out scores."""
    from concurrent.futures import ThreadPoolExecutor

    from tracking import LABELS, PEERS, run_peer, score_table

    points = {m: [(drop, p) for drop in PEER_DROP for p in PEER_GRID[m]] for m in PEERS}
    res: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        jobs = []
        for name in names:
            d = read_mot(cache / name / f"ssdlite-{side}.txt")
            for drop in PEER_DROP:
                path = Path(tmp) / f"{name}-{drop}.txt"
                write_mot(path, d[d[:, 6] >= drop])
                jobs += [(m, name, k, drop, path) for m in PEERS for k in range(len(PEER_GRID[m]))]

        def go(job):
            m, name, k, drop, path = job
            out = Path(tmp) / f"{m}-{name}-{k}-{drop}.out"
            run = run_peer(m, SEQUENCES[name], path, out, PEER_GRID[m][k])
            if "error" in run:
                raise RuntimeError(f"{m} on {name}: {run['error']}")
            s = evaluate(SEQUENCES[name] / "gt" / "gt.txt", read_mot(out) if out.stat().st_size else np.zeros((0, 7)))
            return m, name, (drop, PEER_GRID[m][k]), _scores(s)

        with ThreadPoolExecutor(2) as pool:   # each job a process of its own
            for m, name, point, s in pool.map(go, jobs):
                res[(m, name, json.dumps(point))] = s
    log("peers on the built-in detector's boxes: done")
    held: dict = {}
    chosen = {}
    for m in PEERS:
        per = {json.dumps(pt): {n: res[(m, n, json.dumps(pt))] for n in names} for pt in points[m]}
        choice = loo_choice(per, names)     # ties: the first point (the defaults, nothing dropped)
        for name in names:
            chosen[(m, name)] = json.loads(choice[name])
            held[(m, name)] = per[choice[name]][name]
    dets = {n: detections(n, f"ssdlite-{side}", cache)[0] for n in names}
    for n in names:
        held[("artmotion", n)] = track_scores(n, dets[n], every=DETECT_EVERY)
    table, verdict = score_table(held, names, ["artmotion", *PEERS])
    every1 = {k: float(np.mean([every_frame[n][k] for n in names])) for k in KEYS}
    lines = ["| peer | chosen per held-out sequence (boxes dropped under; settings) |", "|---|---|"]
    for m in PEERS:
        lines.append(f"| {LABELS[m]} | " + "; ".join(
            f"{n}: {chosen[(m, n)][0]:g}, {', '.join(f'{k}={v:g}' for k, v in chosen[(m, n)][1].items()) or 'defaults'}"
            for n in names) + " |")
    a, b = verdict["_means"]["artmotion"], verdict["_best_mean"]
    wins = [n for n in names if verdict.get(n)]
    mean = lambda s: _cells(s).replace(" | ", " / ")  # noqa: E731
    return (f"artmotion (SSDLite on every k-th frame, k = {DETECT_EVERY}) is at least the best peer in MOTA, IDF1 and "
            f"HOTA on {len(wins)} of {len(names)} sequences; mean {mean(a)} against the best peer's {mean(b)} "
            f"(HOTA {100 * (a['HOTA'] - b['HOTA']):+.1f}); artmotion with SSDLite on every frame {mean(every1)}."
            "\n\n" + table + "\n\nThe peers' settings, chosen on the other four sequences:\n\n" + "\n".join(lines))


def tables(res: dict, sides: dict, every: dict | None) -> str:
    """The markdown tables; ``sides``: :func:`loo_choice` of the short side."""
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
        ks = loo_choice({k: every[(k, "det,motion")] for k in EVERY}, names)
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
    ap.add_argument("--no-peers", action="store_true", help="skip the peers on the built-in detector's boxes")
    args = ap.parse_args(argv)
    names = args.sequences.split(",")
    cache = Path(args.cache or ROOT / "out" / f"detections-{_hash()}")
    log = lambda m: print(m, flush=True)  # noqa: E731
    res = run(names, cache, log)
    sides = loo_choice({side: {n: res["seq"][n][f"ssdlite-{side}"] for n in names} for side in SIDES}, names)
    every = None if args.no_every else every_k(sides["all"], names, cache, log)
    text = tables(res, sides, every)
    print(text)
    if args.out != "-":
        replace_block(Path(args.out), "detector-benchmark", text)
    if not args.no_peers:
        text = peers_on_builtin(names, cache, sides["all"], {n: res["seq"][n][f"ssdlite-{sides['all']}"] for n in names},
                                log)
        print(text)
        if args.out != "-":
            replace_block(Path(args.out), "detector-peers", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
