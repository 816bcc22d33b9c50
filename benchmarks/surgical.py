"""Surgical instruments (#15): held-out accuracy of `artmotion tool` against OpenCV's CSRT and KCF.

    .venv/bin/python benchmarks/surgical.py [--data DIR] [--epochs 30] [--folds 4] [--cache DIR] [--no-write]

The 400 annotated frames are cut into ``--folds`` contiguous blocks. For each block: a detector is
trained on the other blocks (as ``artmotion tool train`` does) and the block is tracked (as
``artmotion tool track`` does); every detection above 0.05 may update a head it is assigned to,
and the score a detection needs to start a new head (``birth``) and the frames a head is reported
without a detection (``coast``) are chosen, per block, by the mean F1 of the *other* blocks'
held-out results (never on the block itself). The peers, OpenCV's CSRT and
KCF trackers, are started on the true heads of the block's first frame (a square of the head's
size around it; a human would have to start them) and follow them through the block. Scores by
``artmotion tool eval``'s rules: heads within 15 px (one-to-one), median shaft-angle error,
identity switches, frames/s. The last block is the issue's split (trained on the 300 frames before
it); its tracked frames are drawn into docs/surgical.jpg. Each component of the tracker is then
taken out (or the dense-flow expert added) at the defaults. Writes docs/surgical.md's table between
``<!-- tools-benchmark -->``.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import sys
import time
from pathlib import Path

import cv2
import numpy as np
from _docs import replace_block

from artmotion.tracking.instruments.annotations import read_tools_csv
from artmotion.tracking.instruments.detector import ToolDetector
from artmotion.tracking.instruments.evaluate import evaluate_tools
from artmotion.tracking.instruments.track import ToolTracker, track_tools

BIRTHS = (0.4, 0.5, 0.6)
COASTS = (0, 3)
SETTINGS = [(b, c) for b in BIRTHS for c in COASTS]  # (birth, coast)
#: components taken out one at a time (the tracker's defaults otherwise)
ABLATIONS = {"all experts (default)": {}, "without KLT": {"klt": False}, "without the camera's motion": {"camera": False},
             "without merging heads": {"merge": 0.0}, "with dense flow (DIS), not a default": {"flow": True},
             "dense flow instead of KLT, not a default": {"flow": True, "klt": False}}
FLOOR = 0.05  # detections below are dropped; above, they may update the head they are assigned to
#: the frames resized by these factors (a user's video of another size; annotations and radius scale too)
SCALES = (2.0, 1.6, 0.75)


def f1(r: dict) -> float:
    p, q = r["recall"] or 0.0, r["precision"] or 0.0
    return 2 * p * q / (p + q) if p + q else 0.0


def pooled(rs: list[dict]) -> tuple[float, float]:
    """Recall and precision over several blocks' results, counted together."""
    m = sum(r["matched"] for r in rs)
    return m / sum(r["gt"] for r in rs), m / max(sum(r["pred"] for r in rs), 1)


def peer(kind: str, frames: list[int], imgs: dict, gt: dict) -> tuple[dict, float]:
    """CSRT or KCF started on the true heads of the first frame."""
    make = {"csrt": cv2.TrackerCSRT.create, "kcf": cv2.TrackerKCF.create}[kind]
    trackers = []
    for j, (x, y, s, _a) in enumerate(gt[frames[0]]):
        t = make()
        half = max(8.0, 0.5 * s)
        t.init(imgs[frames[0]], (int(x - half), int(y - half), int(2 * half), int(2 * half)))
        trackers.append((j, t, gt[frames[0]][j][3]))
    pred = {frames[0]: np.array([[j, x, y, s, a, 1.0] for j, (x, y, s, a) in enumerate(gt[frames[0]])])}
    t0 = time.perf_counter()
    for f in frames[1:]:
        rows = []
        for j, t, a in trackers:
            ok, (bx, by, bw, bh) = t.update(imgs[f])
            if ok:
                rows.append([j, bx + bw / 2, by + bh / 2, bw, a, 1.0])
        pred[f] = np.array(rows, float).reshape(-1, 6)
    fps = (len(frames) - 1) / (time.perf_counter() - t0)
    return evaluate_tools({f: gt[f] for f in frames}, pred, fps=fps), fps


DOCS = Path(__file__).resolve().parents[1] / "docs"


def figure(path: Path, block: list[int], imgs: dict, gt: dict, pred: dict, n: int = 4) -> None:
    """``n`` frames of the block side by side: true heads (white ring, shaft), tracked heads (their
    track's colour: a dot, the shaft direction, the track number)."""
    tiles = []
    for f in block[len(block) // (2 * n)::len(block) // n][:n]:
        img = imgs[f].copy()
        for x, y, s, a in gt[f]:
            cv2.circle(img, (int(x), int(y)), 15, (255, 255, 255), 1, cv2.LINE_AA)
            cv2.line(img, (int(x), int(y)), (int(x + 1.2 * s * np.cos(a)), int(y + 1.2 * s * np.sin(a))), (255, 255, 255),
                     1, cv2.LINE_AA)
        for t, x, y, s, a, _ in pred.get(f, []):
            colour = [(0, 200, 255), (255, 120, 0), (80, 220, 80), (200, 80, 255)][int(t) % 4]
            cv2.circle(img, (int(x), int(y)), 4, colour, -1, cv2.LINE_AA)
            cv2.line(img, (int(x), int(y)), (int(x + s * np.cos(a)), int(y + s * np.sin(a))), colour, 2, cv2.LINE_AA)
            cv2.putText(img, str(int(t) + 1), (int(x) + 6, int(y) - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.5, colour, 1,
                        cv2.LINE_AA)
        cv2.putText(img, f"frame {f}", (6, 280), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
        tiles.append(img)
    cv2.imwrite(str(path), np.hstack(tiles), [cv2.IMWRITE_JPEG_QUALITY, 85])


def fold_detector(a, k: int, frames: list, heads: list) -> ToolDetector:
    """The detector of fold ``k``: trained here, or loaded from ``--cache`` when an earlier run with the
    same folds, epochs, threshold and annotations kept it (its training time is kept beside it). The
    frames are not in the key: the same annotations with other frames would be another data set."""
    key = hashlib.sha1(Path(a.data, "tools.csv").read_bytes()).hexdigest()[:10]
    path = Path(a.cache, f"fold{k}of{a.folds}-e{a.epochs}-t{FLOOR}-{key}.pt") if a.cache else None
    if path is not None and path.is_file():
        det = ToolDetector.load(path)
        det.train_seconds_ = float(path.with_suffix(".seconds").read_text())
        return det
    det = ToolDetector(epochs=a.epochs, threshold=FLOOR)
    det.fit(frames, heads)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        det.save(path)
        path.with_suffix(".seconds").write_text(f"{det.train_seconds_}\n")
    return det


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default="../shared/data/surgical/lap-tools")
    ap.add_argument("--epochs", type=int, default=30)
    ap.add_argument("--folds", type=int, default=4)
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--cache", default=None, help="folder to keep each fold's trained detector in (re-used when present)")
    a = ap.parse_args(argv)
    gt = read_tools_csv(os.path.join(a.data, "tools.csv"))
    frames = sorted(gt)
    imgs = {f: cv2.imread(os.path.join(a.data, "frames", f"{f:06d}.png")) for f in frames}
    blocks = np.array_split(np.array(frames), a.folds)
    held: dict[int, dict] = {}  # fold -> {(birth, coast): result}
    preds: dict[tuple, dict] = {}  # (fold, birth, coast) -> {frame: rows}
    scaled: dict[float, list] = {}  # frame scale -> results per fold
    ablation: dict[str, list] = {}  # component -> results per fold
    train_s = []
    for k, block in enumerate(blocks):
        train = [f for f in frames if f not in set(block.tolist())]
        det = fold_detector(a, k, [imgs[f] for f in train], [gt[f] for f in train])
        train_s.append(det.train_seconds_ * 400 / len(train))
        t0 = time.perf_counter()
        dets = {f: det.detect(imgs[f]) for f in block}
        det_s = time.perf_counter() - t0
        held[k] = {}
        for birth, coast in SETTINGS:
            tr = ToolTracker(det, birth=birth, coast=coast)
            t0 = time.perf_counter()
            pred = dict(track_tools(((f, imgs[f], dets[f]) for f in block), det, tr))
            fps = len(block) / (time.perf_counter() - t0 + det_s)
            held[k][birth, coast] = evaluate_tools({f: gt[f] for f in block}, pred, fps=fps)
            preds[k, birth, coast] = pred
        for name, off in ABLATIONS.items():  # each component off, at the default settings
            pred = dict(track_tools(((f, imgs[f], dets[f]) for f in block), det, **off))
            ablation.setdefault(name, []).append(evaluate_tools({f: gt[f] for f in block}, pred))
        for sc in SCALES:  # the block's frames at another size (the detector brings them to its own)
            interp = cv2.INTER_LINEAR if sc > 1 else cv2.INTER_AREA
            pred = dict(track_tools(((f, cv2.resize(imgs[f], None, fx=sc, fy=sc, interpolation=interp)) for f in block),
                                    det))
            truth = {f: gt[f] * np.array([sc, sc, sc, 1.0]) for f in block}
            scaled.setdefault(sc, []).append(evaluate_tools(truth, pred, radius=15 * sc))
        print(f"fold {k}: frames {block[0]}-{block[-1]}, trained in {det.train_seconds_:.0f} s; "
              + ", ".join(f"{t}: {held[k][t]['recall']:.3f}/{held[k][t]['precision']:.3f}" for t in SETTINGS),
              flush=True)
    lines = ["| held-out frames | method | birth, coast | recall (15 px) | precision | median angle error | ID switches "
             "| frames/s |",
             "|---|---|---|---|---|---|---|---|"]
    tot = {"ours": [], "csrt": [], "kcf": []}
    for k, block in enumerate(blocks):
        others = [j for j in held if j != k]
        thr = max(SETTINGS, key=lambda t: np.mean([f1(held[j][t]) for j in others]))
        r = held[k][thr]
        tot["ours"].append(r)
        if k == len(blocks) - 1 and not a.no_write:  # the last block: trained on the frames before it
            figure(DOCS / "surgical.jpg", [int(f) for f in block], imgs, gt, preds[(k, *thr)])
        rows = [("artmotion tool track", f"{thr[0]}, {thr[1]}", r)]
        for kind in ("csrt", "kcf"):
            pr, _ = peer(kind, [int(f) for f in block], imgs, gt)
            tot[kind].append(pr)
            rows.append((f"{kind.upper()} (started on the truth)", "—", pr))
        for name, t, res in rows:
            ang = "—" if res["median_angle_error_deg"] is None else f"{res['median_angle_error_deg']:.1f}°"
            lines.append(f"| {block[0]}–{block[-1]} | {name} | {t} | {res['recall']:.3f} | {res['precision'] or 0:.3f} | "
                         f"{ang} | {res['id_switches']} | {res['fps']:.0f} |")
    for name, key in (("artmotion tool track", "ours"), ("CSRT", "csrt"), ("KCF", "kcf")):
        rs = tot[key]
        rec, prec = pooled(rs)
        lines.append(f"| **all, held out** | {name} | | **{rec:.3f}** | {prec:.3f} | | {sum(r['id_switches'] for r in rs)} | |")
    lines += ["", "Ablation (tracker defaults, each component taken out or added; all four blocks held out):", "",
              "| tracker | recall | precision | ID switches |", "|---|---|---|---|"]
    for name, rs in ablation.items():
        rec, prec = pooled(rs)
        lines.append(f"| {name} | {rec:.3f} | {prec:.3f} | {sum(r['id_switches'] for r in rs)} |")
    lines += ["", "Frames of another size (tracker defaults, the annotations and the 15 px radius scaled with the "
              "frames; all four blocks held out):", "", "| frames | recall | precision |", "|---|---|---|"]
    h0, w0 = imgs[frames[0]].shape[:2]
    for sc, rs in scaled.items():
        rec, prec = pooled(rs)
        lines.append(f"| {round(w0 * sc)}×{round(h0 * sc)} ({sc:g}×) | {rec:.3f} | {prec:.3f} |")
    mean_f1 = {t: float(np.mean([f1(held[j][t]) for j in held])) for t in SETTINGS}
    best = max(SETTINGS, key=mean_f1.get)
    default = ToolTracker(None)
    lines += ["", f"Best on all four blocks: birth {best[0]}, coast {best[1]} (mean F1 {mean_f1[best]:.3f}); the "
              f"tracker's default: birth {default.birth}, coast {default.coast} (mean F1 "
              f"{mean_f1.get((default.birth, default.coast), float('nan')):.3f}).",
              "", f"Training: {np.mean(train_s):.0f} s for 400 frames ({a.epochs} epochs; measured on "
              f"{len(frames) - len(blocks[0])} and scaled), 2 cores."]
    text = "\n".join(lines)
    print(text)
    if not a.no_write:
        replace_block(DOCS / "surgical.md", "tools-benchmark", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
