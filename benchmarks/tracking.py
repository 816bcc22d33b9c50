#!/usr/bin/env python
"""Tracking benchmark: artmotion against SORT, ByteTrack, OC-SORT and BoT-SORT on MOT15 sequences.

Every tracker gets the SAME published detections (``<seq>/det/det.txt``) in the same run and is
scored with :func:`artmotion.tracking.metrics.evaluate` (MOT15 conventions, agrees with TrackEval).
The peers come from the PyPI package ``trackers`` (the ``bench`` extra); they are fed our
detection boxes as ``supervision.Detections`` (no detector model). BoT-SORT in ``trackers`` has no
ReID branch: it runs motion-only, with its camera-motion compensation on the decoded frames.

Each (method, sequence) runs in a fresh worker process so that timings and memory are isolated:
``fps`` is frames / wall time of the run (including frame decoding for the methods that read the
images: artmotion and BoT-SORT); ``peak MiB`` is the worker's peak resident memory above its
resident memory just before the run (``resource.getrusage`` max RSS). ``decode`` is the time of
merely decoding the frames with OpenCV; ``track/decode`` is artmotion's time over it.

Usage::

    python benchmarks/tracking.py [DATA_ROOT] [--out docs/benchmarks.md] [--methods artmotion,sort,...]

``DATA_ROOT`` defaults to ``../shared/data/mot15`` relative to the repository root; every
sub-folder with ``det/det.txt`` and ``gt/gt.txt`` is a sequence.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "data" / "mot15"
PEERS = {
    "sort": "SORTTracker",
    "bytetrack": "ByteTrackTracker",
    "ocsort": "OCSORTTracker",
    "botsort": "BoTSORTTracker",
}
LABELS = {"artmotion": "artmotion", "sort": "SORT", "bytetrack": "ByteTrack", "ocsort": "OC-SORT",
          "botsort": "BoT-SORT (motion only)"}
METHODS = ["artmotion", *PEERS]


# --------------------------------------------------------------------------- worker side


def _rss_bytes() -> int:
    """Current resident memory of this process."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except OSError:
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def _peak_bytes() -> int:
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak if sys.platform == "darwin" else peak * 1024


def _run_decode(seq_dir: Path) -> dict:
    from artmotion.tracking import open_sequence

    seq = open_sequence(seq_dir)
    base = _rss_bytes()
    times = []
    for _ in range(2):  # the first pass also warms the file cache; report the faster
        t0 = time.perf_counter()
        n = sum(1 for _ in seq.frames())
        times.append(time.perf_counter() - t0)
    return {"frames": n, "seconds": min(times), "peak_bytes": _peak_bytes() - base}


def _run_artmotion(seq_dir: Path) -> dict:
    from artmotion.tracking import open_sequence, track

    length = open_sequence(seq_dir).length
    base = _rss_bytes()
    t0 = time.perf_counter()
    result = track(seq_dir, det=seq_dir / "det" / "det.txt")
    dt = time.perf_counter() - t0
    rows = np.asarray(result.tracks, float).reshape(-1, np.shape(result.tracks)[-1] if np.size(result.tracks) else 10)
    return {"frames": length, "seconds": dt, "peak_bytes": _peak_bytes() - base, "rows": rows[:, :7].tolist()}


def _run_peer(name: str, seq_dir: Path) -> dict:
    import supervision as sv
    import trackers

    from artmotion.geometry import xywh_to_xyxy
    from artmotion.io import read_mot
    from artmotion.tracking import open_sequence

    seq = open_sequence(seq_dir)
    det = read_mot(seq_dir / "det" / "det.txt")
    by_frame = {int(f): det[det[:, 0] == f] for f in np.unique(det[:, 0])}
    empty = np.zeros((0, 10))
    tracker = getattr(trackers, PEERS[name])(frame_rate=seq.fps)
    needs_frames = name == "botsort"  # camera-motion compensation works on the images
    out = []

    def step(f: int, image) -> None:
        d = by_frame.get(f, empty)
        xyxy = xywh_to_xyxy(d[:, 2:6]).astype(np.float32)
        dets = sv.Detections(xyxy=xyxy.reshape(-1, 4), confidence=d[:, 6].astype(np.float32),
                             class_id=np.zeros(len(d), dtype=int))
        tracked = tracker.update(dets, frame=image) if needs_frames else tracker.update(dets)
        if len(tracked) == 0 or tracked.tracker_id is None:
            return
        keep = tracked.tracker_id >= 0  # -1: not (yet) a confirmed track
        for (x1, y1, x2, y2), tid, c in zip(tracked.xyxy[keep], tracked.tracker_id[keep],
                                            (tracked.confidence[keep] if tracked.confidence is not None
                                             else np.ones(int(keep.sum())))):
            out.append([f, int(tid) + 1, float(x1), float(y1), float(x2 - x1), float(y2 - y1), float(c)])

    base = _rss_bytes()
    t0 = time.perf_counter()
    if needs_frames:
        for f, image in seq.frames():
            step(f, image)
    else:
        for f in range(1, seq.length + 1):
            step(f, None)
    dt = time.perf_counter() - t0
    return {"frames": seq.length, "seconds": dt, "peak_bytes": _peak_bytes() - base, "rows": out}


def _worker(method: str, seq_dir: str) -> None:
    import warnings

    warnings.filterwarnings("ignore")
    seq_dir = Path(seq_dir)
    if method == "decode":
        res = _run_decode(seq_dir)
    elif method == "artmotion":
        res = _run_artmotion(seq_dir)
    else:
        res = _run_peer(method, seq_dir)
    sys.stdout.write("\n@@RESULT@@" + json.dumps(res) + "\n")


# --------------------------------------------------------------------------- driver side


def _spawn(method: str, seq_dir: Path, timeout: float) -> dict:
    cmd = [sys.executable, os.fspath(Path(__file__).resolve()), "--worker", method, os.fspath(seq_dir)]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=ROOT)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout:g} s"}
    marker = proc.stdout.rfind("@@RESULT@@")
    if proc.returncode != 0 or marker < 0:
        tail = (proc.stderr or proc.stdout).strip().splitlines()
        return {"error": tail[-1] if tail else f"exit status {proc.returncode}"}
    return json.loads(proc.stdout[marker + len("@@RESULT@@"):].strip().splitlines()[0])


def _fmt_pct(v) -> str:
    return f"{100 * v:.1f}"


def find_sequences(data: Path) -> list[Path]:
    return sorted(p for p in data.iterdir()
                  if p.is_dir() and (p / "det" / "det.txt").is_file() and (p / "gt" / "gt.txt").is_file())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", nargs="?", default=os.fspath(DEFAULT_DATA), help="folder of MOT15 sequences")
    ap.add_argument("--out", default=os.fspath(ROOT / "docs" / "benchmarks.md"), help="markdown report ('-' for none)")
    ap.add_argument("--methods", default=",".join(METHODS), help="comma-separated subset of " + ",".join(METHODS))
    ap.add_argument("--timeout", type=float, default=1800, help="seconds allowed per method and sequence")
    ap.add_argument("--worker", nargs=2, metavar=("METHOD", "SEQ"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        _worker(*args.worker)
        return 0

    sys.path.insert(0, os.fspath(ROOT / "src"))
    from artmotion.io import atomic_write, read_mot
    from artmotion.tracking.metrics import evaluate, evaluate_sequences

    data = Path(args.data)
    if not data.is_dir():
        print(f"benchmarks/tracking.py: error: no such folder: {data}", file=sys.stderr)
        return 2
    seqs = find_sequences(data)
    if not seqs:
        print(f"benchmarks/tracking.py: error: no sequence with det/det.txt and gt/gt.txt in {data}", file=sys.stderr)
        return 2
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    unknown = sorted(set(methods) - set(METHODS))
    if unknown:
        print(f"benchmarks/tracking.py: error: unknown method(s) {', '.join(unknown)}", file=sys.stderr)
        return 2

    rows = []  # (method, seq, scores or None, run)
    decode = {}
    per_method_pairs = {m: [] for m in methods}
    for seq in seqs:
        gt = read_mot(seq / "gt" / "gt.txt")
        decode[seq.name] = _spawn("decode", seq, args.timeout)
        print(f"[{seq.name}] decode: {decode[seq.name].get('seconds', float('nan')):.2f} s", file=sys.stderr)
        for m in methods:
            run = _spawn(m, seq, args.timeout)
            scores = None
            if "error" not in run:
                res = np.asarray(run["rows"], float).reshape(-1, 7)
                scores = evaluate(gt, res)
                per_method_pairs[m].append((gt, res))
                print(f"[{seq.name}] {m}: MOTA {scores['MOTA']:.3f} IDF1 {scores['IDF1']:.3f} "
                      f"HOTA {scores['HOTA']:.3f} in {run['seconds']:.2f} s", file=sys.stderr)
            else:
                print(f"[{seq.name}] {m}: FAILED: {run['error']}", file=sys.stderr)
            rows.append((m, seq.name, scores, run))

    head = "| sequence | method | MOTA | IDF1 | HOTA | IDS | FP | FN | fps | peak MiB |"
    sep = "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"
    lines = [head, sep]
    for m, name, s, run in rows:
        if s is None:
            lines.append(f"| {name} | {LABELS[m]} | failed: {run['error'][:80]} | | | | | | | |")
            continue
        fps = run["frames"] / run["seconds"] if run["seconds"] > 0 else float("inf")
        lines.append(f"| {name} | {LABELS[m]} | {_fmt_pct(s['MOTA'])} | {_fmt_pct(s['IDF1'])} | {_fmt_pct(s['HOTA'])} "
                     f"| {s['IDS']} | {s['FP']} | {s['FN']} | {fps:.1f} | {run['peak_bytes'] / 2**20:.1f} |")
    if len(seqs) > 1:
        for m in methods:
            pairs = per_method_pairs[m]
            if len(pairs) != len(seqs):
                continue
            s = evaluate_sequences(pairs)
            runs = [r for mm, _, sc, r in rows if mm == m and sc is not None]
            fps = sum(r["frames"] for r in runs) / max(1e-9, sum(r["seconds"] for r in runs))
            peak = max(r["peak_bytes"] for r in runs) / 2**20
            lines.append(f"| **all** | {LABELS[m]} | {_fmt_pct(s['MOTA'])} | {_fmt_pct(s['IDF1'])} | "
                         f"{_fmt_pct(s['HOTA'])} | {s['IDS']} | {s['FP']} | {s['FN']} | {fps:.1f} | {peak:.1f} |")
    table = "\n".join(lines)

    speed = ["| sequence | frames | decode s | decode fps | artmotion track s | track/decode |",
             "|---|---:|---:|---:|---:|---:|"]
    for seq in seqs:
        d = decode[seq.name]
        if "error" in d:
            speed.append(f"| {seq.name} | | decode failed: {d['error'][:80]} | | | |")
            continue
        am = next((r for mm, name, sc, r in rows if mm == "artmotion" and name == seq.name and "error" not in r), None)
        t = f"{am['seconds']:.2f}" if am else "n/a"
        ratio = f"{am['seconds'] / d['seconds']:.1f}x" if am and d["seconds"] > 0 else "n/a"
        speed.append(f"| {seq.name} | {d['frames']} | {d['seconds']:.2f} | {d['frames'] / d['seconds']:.0f} | {t} | {ratio} |")
    speed_table = "\n".join(speed)

    try:
        from importlib.metadata import version

        peers_version = version("trackers")
    except Exception:  # noqa: BLE001 - only for the report
        peers_version = "not installed"
    when = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    report = f"""# Tracking benchmark

Generated by `python benchmarks/tracking.py` on {when} ({platform.machine()}, {os.cpu_count()} CPUs,
Python {platform.python_version()}, trackers {peers_version}). Data: {', '.join(s.name for s in seqs)}
(MOT15 train, published detections `det/det.txt` for every method).

Scores from `artmotion.tracking.metrics.evaluate` (MOT15 conventions, cross-checked against TrackEval;
see docs/metrics.md), in %; IDS/FP/FN are counts. Peers run with their default parameters and the
sequence's frame rate; they get our detection boxes and confidences as `supervision.Detections`.
BoT-SORT in `trackers` has no ReID model: it runs motion-only with camera-motion compensation on the
frames. `fps` = frames / wall time of one run in a fresh process (artmotion and BoT-SORT include
decoding the frames); `peak MiB` = peak resident memory above the level just before the run.
**all** rows score the sequences together (counts summed, as TrackEval's combined result).

{table}

## Speed: decoding alone vs artmotion

Time to merely decode every frame with OpenCV, against the whole `artmotion.tracking.track` run.

{speed_table}
"""
    print(report)
    if args.out != "-":
        with atomic_write(args.out) as fh:
            fh.write(report)
        print(f"written: {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
