#!/usr/bin/env python
"""Leave-one-sequence-out choice of the tracker's settings, and the ablation of its components.

Every setting of :class:`artmotion.tracking.TrackerConfig` that matters (and the set of tracking
experts) has a few candidate values in :data:`SPACE`. A *fold* holds one sequence out: a greedy
coordinate search moves, one setting at a time, to the value that raises the **objective on the
four training sequences** — the mean over them of ``(MOTA + IDF1 + HOTA) / 3`` — by more than
``--min-gain``, and stops when a whole pass over the settings moves nothing. It runs from a fixed,
data-independent start (:data:`START`) and from two seeded random points; the end point with the
best training objective is the fold's choice. The held-out sequence is then scored with it; its
scores never enter the choice. The defaults of the package are the same procedure run on all five
sequences (``fold: all``); the leave-one-out scores estimate how well the procedure transfers.

Two variants of the procedure: ``--agree`` accepts only moves that more training sequences gain
from than lose (each sequence's items averaged; a move must not be one sequence's large gain paid
for by the others), ``--objective worst`` maximises the worst training item instead of the mean.
``--builtin`` adds five items, the sequences with the built-in SSDLite detector's boxes on every
second frame (what ``artmotion track`` uses without detections; cached by
``benchmarks/detector.py``).

Every configuration is scored on every sequence once and cached (``--cache``, JSON lines), so
folds share work and a re-run only computes what is new. Frames are decoded once per sequence (at
the size the tracker works at) and the tracker runs in two forked worker processes.

The **ablation** starts from the package defaults and switches one component at a time (each
expert, group nodes, the parts of the offline pass, entry/exit tests, appearance, camera motion,
low-score detections), reporting the mean MOTA/IDF1/HOTA over the five sequences with and without.

Usage::

    python benchmarks/tracking_loo.py [--cache out/tracking_loo.jsonl] [--workers 2] [--folds all,PETS09-S2L1,...]
        [--agree] [--builtin] [--objective mean|worst] [--no-ablation]

Prints the tables; ``benchmarks/tracking.py`` writes them into docs/tracking.md.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import sys
import time
from dataclasses import asdict, fields
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
sys.path.insert(0, str(ROOT / "src"))

from artmotion.tracking import DEFAULT_EXPERTS, TrackerConfig, open_sequence, run_tracker  # noqa: E402
from artmotion.tracking.api import _work_reduce  # noqa: E402
from artmotion.tracking.config import DETECT_EVERY  # noqa: E402
from artmotion.tracking.detect import load_detections  # noqa: E402
from artmotion.tracking.metrics import evaluate  # noqa: E402
from artmotion.tracking.mot import MultiObjectTracker  # noqa: E402

SEQUENCES = {
    "PETS09-S2L1": SHARED / "mot15" / "PETS09-S2L1",
    "TUD-Campus": SHARED / "mot15" / "TUD-Campus",
    "ETH-Sunnyday": SHARED / "mot15" / "ETH-Sunnyday",
    "KITTI-17": SHARED / "mot15" / "KITTI-17",
    "MOT16-09": SHARED / "mot16" / "MOT16-09",
}
#: the weaker published detections of a sequence (ACF; DPM, whose scores are margins): a user's
#: detector has its own score scale and quality, so the settings are chosen on these too
WEAK = {"ETH-Sunnyday": "det_acf.txt", "KITTI-17": "det_acf.txt", "MOT16-09": "det_dpm.txt"}
#: what a point is scored on: each sequence with its published detections (``det.txt``), and
#: ``"SEQ:det_x.txt"`` with its weak ones; a fold holds out every item of its sequence
ITEMS = [*SEQUENCES, *(f"{n}:{d}" for n, d in WEAK.items())]
#: the built-in detector's boxes (``benchmarks/detector.py``'s cache), used on every
#: ``DETECT_EVERY``-th frame as ``artmotion track`` does without detections
BUILTIN = "ssdlite"
#: where its boxes are cached (default: ``out/detections-<hash of detectors.py>``, as detector.py)
BUILTIN_CACHE: Path | None = None


def use_builtin() -> None:
    """Add the five sequences with the built-in detector's boxes to :data:`ITEMS` (``--builtin``)."""
    ITEMS.extend(i for i in (f"{n}:{BUILTIN}" for n in SEQUENCES) if i not in ITEMS)


KEYS = ("MOTA", "IDF1", "HOTA")

#: candidate values of every setting searched (``experts``: the tracking experts)
SPACE: dict[str, list] = {
    "experts": ["det,motion", "det,klt,motion", "det,klt,blob,motion", "det,klt,flow,motion",
                "det,klt,blob,flow,motion"],
    "experts_when": ["lost"],      # "all" is over the speed budget (ablation only)
    "high": [0.5, 0.6, 0.7, 0.8, 0.9],
    "low": [0.1, 0.3, 0.5],
    "accel": [0.25, 0.35, 0.5, 0.7, 1.0, 1.4, 2.0],
    "size_accel": [0.1, 0.25, 0.5, 1.0],
    "meas": [0.03, 0.05, 0.08, 0.12],
    "size_meas": [0.03, 0.05, 0.08, 0.12],
    "adapt_noise": [False, True],
    "noise_horizon": [0.5, 1.0, 2.0],
    "camera": [True, False],
    "match_iou": [0.05, 0.1, 0.2, 0.3, 0.4],
    "app_weight": [0.0, 0.1, 0.3, 0.5, 1.0],
    "app_parts": [1, 2, 3],
    "reacquire_kl": [0.0, 0.5, 1.0, 2.0],
    "birth_iou": [0.3, 0.5, 0.7],
    "confirm_hits": [1, 2, 3, 4, 5],
    "tentative_misses": [0, 1, 2],
    "max_lost": [0.5, 1.0, 1.5, 2.0, 3.0],
    "exit_test": [False, True],
    "groups": [True, False],
    "merge_iou": [0.2, 0.3, 0.5],
    "max_group": [1.0, 3.0, 5.0],
    "split_app": [False, True],
    "smooth": [True, False],
    "max_interp": [0.0, 0.25, 0.5, 1.0, 2.0],
    "tail": [0.0, 0.25, 0.5],
    "stitch": [False, True],
    "max_gap": [1.0, 2.0, 3.0, 5.0],
    "stitch_dist": [0.25, 0.5, 1.0],
    "stitch_kl": [0.5, 1.0, 1.5, 3.0],
    "min_life": [0.0, 0.3, 0.6, 1.0],
    "min_track_score": [0.0, 0.7, 0.8, 0.85, 0.9],
    "duplicate_share": [0.0, 0.1, 0.2, 0.3, 0.6],     # added later: chosen by benchmarks/tracking_setting.py
    "duplicate_drift": [0.04, 0.06, 0.08],
}
#: settings the search leaves at their :data:`START` value: no fold of the first search (published
#: detections only, docs/tracking.md) moved them; they are ablated instead
FIXED = ("experts", "experts_when", "noise_horizon", "camera", "app_parts", "birth_iou", "tentative_misses",
         "exit_test", "groups", "merge_iou", "max_group", "smooth", "tail", "max_gap", "stitch_kl")
#: settings that only matter when another one is on
NEEDS = {"noise_horizon": ("adapt_noise", True), "merge_iou": ("groups", True), "max_group": ("groups", True), "split_app": ("groups", True),
         "max_gap": ("stitch", True), "stitch_dist": ("stitch", True), "stitch_kl": ("stitch", True),
         "experts_when": ("experts", lambda v: v != "det,motion"), "duplicate_drift": ("duplicate_share", lambda v: v > 0)}


#: the modules whose code decides the scores (reading files, the CLI and the video writer do not)
SCORED = ("appearance", "association", "camera", "entry_exit", "experts", "groups", "metrics", "mot", "offline",
          "online", "pote", "state")


def code_hash() -> str:
    """A hash of the tracker's source: cached scores are only reused for the same code. The
    settings module counts only through the defaults of the settings not searched (a point sets
    every searched one), so writing the chosen defaults into it keeps the cache."""
    import hashlib

    h = hashlib.sha256()
    for name in SCORED:
        path = ROOT / "src" / "artmotion" / "tracking" / f"{name}.py"
        h.update(path.name.encode() + path.read_bytes())
    fixed = {k: v for k, v in asdict(TrackerConfig()).items() if k not in SPACE}
    h.update(json.dumps(fixed, sort_keys=True).encode())
    return h.hexdigest()[:12]


#: where every search starts: ``TrackerConfig.textbook()`` (SORT/ByteTrack-like values, detector
#: and Kalman filter only), independent of the data, so that no fold starts from a point chosen
#: with its held-out sequence
START: dict = {k: v for k, v in asdict(TrackerConfig.textbook()).items() if k in SPACE} | {"experts": "det,motion"}


def defaults() -> dict:
    """The package's current defaults, as a point of :data:`SPACE`."""
    cfg = asdict(TrackerConfig())
    point = {k: cfg[k] for k in SPACE if k in cfg}
    point["experts"] = ",".join(DEFAULT_EXPERTS)
    return point


def starts(n: int, seed: int = 0) -> list[dict]:
    """:data:`START` and ``n - 1`` random points of :data:`SPACE` (a fixed seed)."""
    rng = np.random.default_rng(seed)
    out = [dict(START)]
    while len(out) < n:
        p = {k: v[int(rng.integers(len(v)))] for k, v in SPACE.items()}
        if _valid(p):
            out.append(p)
    return out


def key(point: dict) -> str:
    return json.dumps({k: point[k] for k in sorted(point)}, sort_keys=True)


def _per_item(scores: dict, items) -> list[float]:
    """(MOTA + IDF1 + HOTA) / 3 of each of ``items``."""
    return [float(np.mean([scores[s][k] for k in KEYS])) for s in items]


def objective(scores: dict, items) -> float:
    """Mean over ``items`` of (MOTA + IDF1 + HOTA) / 3."""
    return float(np.mean(_per_item(scores, items)))


def worst_objective(scores: dict, items) -> float:
    """The worst item's (MOTA + IDF1 + HOTA) / 3: a choice that must not give up any sequence
    (held out better than the mean in docs/tracking.md)."""
    return min(_per_item(scores, items))


OBJECTIVES = {"mean": objective, "worst": worst_objective}


def weak_items(items) -> list[str]:
    """The items of ``items`` with weak detections (not the published ones, not the built-in
    detector's)."""
    return [i for i in items if ":" in i and not i.endswith(BUILTIN)]


def items_of(seqs) -> list[str]:
    """The items (:data:`ITEMS`) of the sequences ``seqs``."""
    return [i for i in ITEMS if i.split(":")[0] in seqs]


# ---------------------------------------------------------------------------------------------
# scoring (frames decoded once per sequence, inherited by the forked workers)
# ---------------------------------------------------------------------------------------------
_FRAMES: dict = {}


_DETS: dict = {}


def _load(name: str, det: str = "det.txt"):
    path = SEQUENCES[name]
    if name not in _FRAMES:
        seq = open_sequence(path)
        red = _work_reduce(seq.width, seq.height)
        _FRAMES[name] = (seq, red, list(seq.frames(reduce=red)))
    if (name, det) not in _DETS:
        if det == BUILTIN:
            from detector import _hash, detections  # benchmarks/detector.py imports this module
            cache = BUILTIN_CACHE or ROOT / "out" / f"detections-{_hash()}"
            _DETS[(name, det)] = detections(name, "ssdlite-300", cache)[0]
        else:
            _DETS[(name, det)] = load_detections(path / "det" / det)
    return (*_FRAMES[name], _DETS[(name, det)], path / "gt" / "gt.txt")


def score_point(point: dict, names=None) -> dict:
    """Per-item scores (:data:`ITEMS`, default all) of the tracker with the settings ``point``."""
    cfg_names = {f.name for f in fields(TrackerConfig)}
    cfg = TrackerConfig(**{k: v for k, v in point.items() if k in cfg_names})
    experts = tuple(point.get("experts", ",".join(DEFAULT_EXPERTS)).split(","))
    out = {}
    for item in names or ITEMS:
        name, _, det = item.partition(":")
        seq, red, frames, dets, gt = _load(name, det or "det.txt")
        tracker = MultiObjectTracker(seq.fps, seq.width, seq.height, experts=experts, config=cfg,
                                     online=bool(point.get("online", False)))
        t0 = time.perf_counter()
        n = run_tracker(tracker, iter(frames), dets, reduce=red, decode=red,
                        detect_every=DETECT_EVERY if det == BUILTIN else 1)
        rows, _ = tracker.finish(n)
        seconds = time.perf_counter() - t0
        s = evaluate(gt, rows)
        out[item] = {k: s[k] for k in (*KEYS, "IDS", "FP", "FN")} | {"seconds": seconds}
    return out


def _work(job: tuple[dict, list[str]]) -> tuple[str, dict]:
    return key(job[0]), score_point(*job)


class Scorer:
    """Scores points on every item, with a cache on disk and a pool of forked workers. A point
    cached without some items (an older cache) is scored on those only."""

    def __init__(self, cache: Path, workers: int):
        self.cache_path = cache
        self.cache: dict[str, dict] = {}
        if cache.is_file():
            for line in cache.read_text().splitlines():
                if line.strip():
                    rec = json.loads(line)
                    self.cache.setdefault(rec["key"], {}).update(rec["scores"])
        for item in ITEMS:
            name, _, det = item.partition(":")
            _load(name, det or "det.txt")
        self.pool = mp.get_context("fork").Pool(workers) if workers > 1 else None

    def scores(self, points: list[dict]) -> list[dict]:
        # one job per point and item, so that the workers stay busy when one point is missing
        todo = {(key(p), i): (p, [i]) for p in points for i in ITEMS if i not in self.cache.get(key(p), {})}
        if todo:
            it = self.pool.imap_unordered(_work, todo.values()) if self.pool else map(_work, todo.values())
            self.cache_path.parent.mkdir(parents=True, exist_ok=True)
            with open(self.cache_path, "a") as fh:
                for k, sc in it:
                    self.cache.setdefault(k, {}).update(sc)
                    fh.write(json.dumps({"key": k, "scores": sc}) + "\n")
                    fh.flush()
        return [self.cache[key(p)] for p in points]

    def close(self):
        if self.pool:
            self.pool.close()


# ---------------------------------------------------------------------------------------------
# the search
# ---------------------------------------------------------------------------------------------
def _active(point: dict, name: str) -> bool:
    if name not in NEEDS:
        return True
    other, want = NEEDS[name]
    return want(point[other]) if callable(want) else point[other] == want


def _valid(point: dict) -> bool:
    return point["low"] <= point["high"]


def _by_sequence(scores: dict, items) -> dict:
    """Each sequence's mean over its ``items`` of (MOTA + IDF1 + HOTA) / 3."""
    per: dict[str, list] = {}
    for item, v in zip(items, _per_item(scores, items)):
        per.setdefault(item.split(":")[0], []).append(v)
    return {k: float(np.mean(v)) for k, v in per.items()}


def agrees(new: dict, old: dict, items, tol: float = 0.001) -> bool:
    """More training sequences gain than lose (each by more than ``tol``) going from ``old`` to
    ``new``: a move must not be one sequence's large gain paid for by the others."""
    a, b = _by_sequence(new, items), _by_sequence(old, items)
    up = sum(a[k] > b[k] + tol for k in a)
    down = sum(a[k] < b[k] - tol for k in a)
    return up > down


def coordinate_search(scorer: Scorer, train: list[str], start: dict, min_gain: float, max_passes: int = 6,
                      log=print, objective=objective, agree: bool = False) -> tuple[dict, list]:
    """Greedy coordinate ascent of ``objective`` (:data:`OBJECTIVES`) on ``train`` from ``start``;
    with ``agree``, only moves that more training sequences gain from than lose (:func:`agrees`)."""
    point = dict(start)
    current = scorer.scores([point])[0]
    best = objective(current, train)
    path = [("start", None, best)]
    for p in range(max_passes):
        moved = False
        for name in SPACE:
            if name in FIXED or not _active(point, name):
                continue
            cands = [dict(point, **{name: v}) for v in SPACE[name] if v != point[name]]
            cands = [c for c in cands if _valid(c)]
            if not cands:
                continue
            cand_scores = scorer.scores(cands)
            objs = [objective(s, train) if not agree or agrees(s, current, train) else -np.inf for s in cand_scores]
            i = int(np.argmax(objs))
            if objs[i] > best + min_gain:
                log(f"    pass {p + 1}: {name} {point[name]} -> {cands[i][name]}: {100 * best:.2f} -> {100 * objs[i]:.2f}")
                point, best, current = cands[i], objs[i], cand_scores[i]
                path.append((name, point[name], best))
                moved = True
        if not moved:
            break
    return point, path


def _means(scores: dict, items) -> dict:
    return {k: float(np.mean([scores[i][k] for i in items])) for k in KEYS}


def _cells(m: dict) -> str:
    return " | ".join(f"{100 * m[k]:.1f}" for k in KEYS)


def held_out_table(results: dict) -> str:
    """The held-out scores of every fold (each item of the held-out sequence) and their means,
    for the published and for the weak detections; next to them, the scores of the
    data-independent start (:data:`START`), which are held-out scores on every item too."""
    lines = ["| held out | detections | MOTA | IDF1 | HOTA | training objective | the fold's choice (changes from the fixed start) |",
             "|---|---|---:|---:|---:|---:|---|"]
    held: dict = {}
    for name in SEQUENCES:
        if name not in results:
            continue
        r = results[name]
        for item in items_of([name]):
            held[item] = r["scores"][item]
            det = item.partition(":")[2] or "det.txt"
            lines.append(f"| {name} | {det} | {_cells(held[item])} | {100 * r['train_objective']:.1f} | "
                         f"{r['changes'] or '(none)'} |")
    main = [i for i in held if ":" not in i]
    weak = weak_items(held)
    builtin = [i for i in held if i.endswith(BUILTIN)]
    for label, items in (("published", main), ("weak", weak), ("built-in SSDLite", builtin)):
        if items:
            lines.append(f"| **mean** | {label} | {_cells(_means(held, items))} | | |")
            if "textbook" in results:
                lines.append(f"| mean of the textbook start (no search) | {label} | "
                             f"{_cells(_means(results['textbook'], items))} | | |")
    return "\n".join(lines)


def changes(point: dict, base: dict) -> str:
    return ", ".join(f"{k}={point[k]}" for k in SPACE if point.get(k) != base.get(k))


# ---------------------------------------------------------------------------------------------
# ablation
# ---------------------------------------------------------------------------------------------
def ablations(base: dict) -> list[tuple[str, dict]]:
    """``(label, point)`` pairs: the defaults with one component switched."""
    ex = base["experts"].split(",")
    out = []
    for e in ("klt", "blob", "flow", "motion"):
        flipped = [x for x in ex if x != e] if e in ex else ex + [e]
        out.append((f"{'without' if e in ex else 'with'} the {e} expert", dict(base, experts=",".join(flipped))))
    if ex != ["det", "motion"]:
        other = "all" if base["experts_when"] == "lost" else "lost"
        out.append((f"image experts on {other} tracks", dict(base, experts_when=other)))
    toggles = {
        "groups": "group nodes (merge/split, Sec. 2.5.2)",
        "smooth": "RTS smoothing (offline, Sec. 2.5.3)",
        "stitch": "tracklet stitching (offline)",
        "camera": "camera-motion compensation",
        "exit_test": "appearance exit test (Sec. 2.5.4)",
        "split_app": "appearance at group splits",
        "adapt_noise": "noise levels estimated from the detections",
    }
    for k, label in toggles.items():
        out.append((f"{'without' if base[k] else 'with'} {label}", dict(base, **{k: not base[k]})))
    numeric = {
        "max_interp": ("interpolation through gaps", 0.0, 1.0),
        "min_life": ("dropping short tracks inside the image (offline)", 0.0, 0.6),
        "app_weight": ("appearance in the association", 0.0, 0.3),
        "reacquire_kl": ("appearance gate for re-acquiring lost tracks", 0.0, 1.0),
        "tail": ("lost tail after the last detection", 0.0, 0.5),
        "min_track_score": ("dropping tracks of low mean score (offline)", 0.0, 0.85),
        "duplicate_share": ("dropping duplicate tracks of one person (offline)", 0.0, 0.2),
    }
    for k, (label, off, on) in numeric.items():
        out.append((f"{'without' if base[k] != off else 'with'} {label}", dict(base, **{k: off if base[k] != off else on})))
    if base["low"] < base["high"]:
        out.append(("without low-score detections (second stage)", dict(base, low=base["high"])))
    else:
        out.append(("with low-score detections (second stage, low=0.1)", dict(base, low=0.1)))
    out.append(("online: no offline pass (causal results)", dict(base, online=True)))
    if base["confirm_hits"] > 1:
        out.append(("without confirmation (every detection a track)", dict(base, confirm_hits=1)))
    return out


def ablation_table(scorer: Scorer, base: dict) -> str:
    """Mean MOTA/IDF1/HOTA over the published detections of the five sequences and over the weak
    ones, and the objective over all items, for the defaults and each variant."""
    rows = [("**defaults**", base)] + ablations(base)
    scores = scorer.scores([p for _, p in rows])
    main, weak = list(SEQUENCES), weak_items(ITEMS)
    lines = ["| variant | published: MOTA | IDF1 | HOTA | weak: MOTA | IDF1 | HOTA | objective (all) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|"]
    b = objective(scores[0], ITEMS)
    for (label, _), s in zip(rows, scores):
        o = objective(s, ITEMS)
        delta = "" if label.startswith("**") else f" ({100 * (o - b):+.1f})"
        lines.append(f"| {label} | {_cells(_means(s, main))} | {_cells(_means(s, weak))} | {100 * o:.1f}{delta} |")
    return "\n".join(lines)


def run(cache: str | None = None, workers: int = 2, folds: str | None = None, min_gain: float = 0.001,
        out_json: str | None = None, restarts: int = 1, ablation: bool = True, log=print,
        goal: str = "mean", agree: bool = False) -> dict:
    """Run the folds, then the ablation of the ``all`` fold's choice; return (and save as JSON)
    ``{fold: {point, changes, path, train_objective, held_out, scores}, "ablation": table}``.
    Each fold runs the coordinate search from :func:`starts` (``restarts`` points) and keeps the
    end point with the best training objective."""
    cache = Path(cache or ROOT / "out" / f"tracking_loo-{code_hash()}.jsonl")
    out_json = Path(out_json or cache.with_suffix(".json"))
    scorer = Scorer(cache, workers)
    start_points = starts(restarts)
    goal_of = OBJECTIVES[goal]
    results: dict = {}
    try:
        for fold in (folds or "all," + ",".join(SEQUENCES)).split(","):
            train = items_of([n for n in SEQUENCES if n != fold])
            log(f"fold {fold}: choosing on {', '.join(train)}")
            ends = []
            for k, start in enumerate(start_points):
                log(f"  start {k}")
                point, path = coordinate_search(scorer, train, start, min_gain, log=log, objective=goal_of, agree=agree)
                ends.append((goal_of(scorer.scores([point])[0], train), k, point, path))
            _, k, point, path = max(ends, key=lambda e: (e[0], -e[1]))
            log(f"  chosen: the end of start {k}")
            all_scores = scorer.scores([point])[0]
            results[fold] = {"point": point, "changes": changes(point, START), "path": path, "start": k,
                             "train_objective": goal_of(all_scores, train),
                             "held_out": {i: all_scores[i] for i in items_of([fold])}, "scores": all_scores}
            for item in items_of([fold]) if fold in SEQUENCES else []:
                s = all_scores[item]
                log(f"  held out {item}: MOTA {100 * s['MOTA']:.1f} IDF1 {100 * s['IDF1']:.1f} HOTA {100 * s['HOTA']:.1f}")
        results["textbook"] = scorer.scores([START])[0]
        if ablation:
            results["ablation"] = ablation_table(scorer, results["all"]["point"] if "all" in results else defaults())
    finally:
        scorer.close()
    out_json.parent.mkdir(parents=True, exist_ok=True)
    out_json.write_text(json.dumps(results, indent=1, default=float))
    return results


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cache", default=None,
                    help="scores of every configuration tried (default: out/tracking_loo-<hash of the tracker's code>.jsonl)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--folds", default=None, help="comma-separated: all and/or sequence names (default: all of them)")
    ap.add_argument("--min-gain", type=float, default=0.001, help="smallest objective gain a move needs")
    ap.add_argument("--restarts", type=int, default=1, help="coordinate searches per fold: the fixed start, then seeded random ones")
    ap.add_argument("--no-ablation", action="store_true", help="only the folds")
    ap.add_argument("--objective", choices=sorted(OBJECTIVES), default="mean",
                    help="what a fold maximises over its training items: their mean, or the worst one")
    ap.add_argument("--agree", action="store_true",
                    help="accept only moves that more training sequences gain from than lose")
    ap.add_argument("--builtin", action="store_true",
                    help="five more items: the sequences with the built-in detector's boxes (every second frame)")
    args = ap.parse_args(argv)
    if args.builtin:
        use_builtin()
    results = run(args.cache, args.workers, args.folds, args.min_gain, restarts=args.restarts,
                  ablation=not args.no_ablation, log=lambda m: print(m, flush=True), goal=args.objective,
                  agree=args.agree)
    print(held_out_table(results))
    if "ablation" in results:
        print(results["ablation"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
