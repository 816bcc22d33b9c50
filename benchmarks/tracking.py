#!/usr/bin/env python
"""Tracking benchmark: artmotion against SORT, ByteTrack, OC-SORT and BoT-SORT, on every sequence.

Every tracker gets the SAME detections of a sequence in the same run and is scored by
:func:`artmotion.tracking.metrics.evaluate` (MOTChallenge rules: MOT15 for 10-column ground truth,
MOT17 — pedestrians only, distractors removed — for MOT16-09; both agree with TrackEval, see
tests/tracking/test_metrics.py). The peers come from the PyPI package ``trackers`` and run in their
own environment (``.venv-peers``, made by ``make bench``; ``trackers`` pulls ``opencv-python``,
which would replace the contrib ``cv2``), through ``benchmarks/_peer_worker.py``. BoT-SORT in
``trackers`` has no ReID model: it runs motion-only, with its camera-motion compensation.

Tables:

* **published detections** (``det/det.txt``, Faster R-CNN): every tracker on every sequence, the
  mean over sequences, and the best peer per column;
* **weak detections** (``det_acf.txt``, ``det_dpm.txt`` where the sequence has them; DPM scores are
  not in [0, 1] and are replaced by their mid-rank, for every tracker);
* **speed**: the whole ``artmotion track`` command (the console script in a fresh process,
  start-up included) against the time of merely decoding the sequence's frames in one process (the
  decode floor), the two timed in alternation, five of each, the best of each kept (so that both
  see the same load); artmotion's peak memory.

Usage::

    python benchmarks/tracking.py [--data ROOT ...] [--methods artmotion,sort,...] [--out docs/benchmarks.md]

It rewrites docs/benchmarks.md and the block between ``<!-- tracking-benchmark -->`` markers in
docs/tracking.md. Timings are only meaningful on an otherwise idle machine.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
from _docs import compile_package, replace_block

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
PEERS_PY = ROOT / ".venv-peers" / "bin" / "python"
PEERS = ["sort", "bytetrack", "ocsort", "botsort"]
LABELS = {"artmotion": "artmotion", "sort": "SORT", "bytetrack": "ByteTrack", "ocsort": "OC-SORT",
          "botsort": "BoT-SORT (motion only)"}
KEYS = ("MOTA", "IDF1", "HOTA")


def find_sequences(roots) -> list[Path]:
    out = []
    for root in roots:
        root = Path(root)
        if root.is_dir():
            out += sorted(p for p in root.iterdir() if (p / "gt" / "gt.txt").is_file() and (p / "det").is_dir())
    return out


_DECODE = """
import sys, time, cv2
from pathlib import Path
seq = Path(sys.argv[1])
n = 0
if (seq / "img1").is_dir():
    for p in sorted((seq / "img1").iterdir()):
        n += cv2.imread(str(p)) is not None
else:
    cap = cv2.VideoCapture(str(next(p for p in sorted(seq.iterdir()) if p.suffix.lower() in (".mp4", ".avi"))))
    while cap.read()[0]:
        n += 1
print(n)
"""


def _best_wall(cmd: list[str], runs: int = 3, env=None) -> tuple[float, str, int]:
    """Best wall time of ``runs`` fresh processes (start-up included), the last one's stdout and
    the largest peak RSS (bytes) of one of them (``os.wait4`` reports each child's own)."""
    best, out, peak = float("inf"), "", 0
    for _ in range(runs):
        with tempfile.TemporaryFile() as fout, tempfile.TemporaryFile() as ferr:
            t0 = time.perf_counter()
            proc = subprocess.Popen(cmd, stdout=fout, stderr=ferr, env=env)
            _, status, usage = os.wait4(proc.pid, 0)
            best = min(best, time.perf_counter() - t0)
            proc.returncode = os.waitstatus_to_exitcode(status)
            fout.seek(0)
            ferr.seek(0)
            out, err = fout.read().decode(), ferr.read().decode()
        if proc.returncode != 0:
            raise RuntimeError((err or out).strip().splitlines()[-1] if (err or out).strip() else f"exit {proc.returncode}")
        peak = max(peak, usage.ru_maxrss * 1024)
    return best, out, peak


def decode_floor(seq: Path, runs: int = 3) -> tuple[int, float]:
    """A fresh Python process that imports OpenCV and decodes every frame of ``seq`` at full size
    (``cv2.imread`` / ``VideoCapture.read``): frames and best wall time of ``runs`` runs."""
    seconds, out, _ = _best_wall([sys.executable, "-c", _DECODE, str(seq)], runs=runs)
    return int(out.split()[0]), seconds


def run_artmotion(seq: Path, det: Path, out: Path) -> dict:
    """``artmotion track`` in a fresh process, by the console script a user runs (``python -m
    artmotion`` when it is not installed): wall time with start-up, peak memory."""
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    script = Path(sys.executable).with_name("artmotion")
    cmd = [str(script)] if script.is_file() else [sys.executable, "-m", "artmotion"]
    cmd += ["track", str(seq), "--det", str(det), "--out", str(out), "--no-progress"]
    try:
        seconds, _, peak = _best_wall(cmd, runs=1, env=env)
    except RuntimeError as exc:
        return {"error": str(exc)}
    return {"seconds": seconds, "peak_bytes": peak}


def speed_pair(seq: Path, det: Path, out: Path, rounds: int = 5) -> tuple[int, float, dict]:
    """The decode floor and ``artmotion track`` timed in alternation (``rounds`` of each, the best
    of each kept), so that both see the same load: frames, floor seconds, and the run. The package's
    bytecode is compiled first (:func:`compile_package`), as the floor's NumPy and OpenCV are."""
    compile_package()
    floor, run = float("inf"), {"seconds": float("inf"), "peak_bytes": 0}
    n = 0
    for _ in range(rounds):
        n, sec = decode_floor(seq, runs=1)
        r = run_artmotion(seq, det, out)
        if "error" in r:
            raise RuntimeError(r["error"])
        floor = min(floor, sec)
        run = {"seconds": min(run["seconds"], r["seconds"]), "peak_bytes": max(run["peak_bytes"], r["peak_bytes"])}
    return n, floor, run


def run_peer(name: str, seq: Path, det: Path, out: Path, params: dict | None = None) -> dict:
    """Peer ``name`` on ``det`` of ``seq``, rows written to ``out``; ``params``: keyword arguments
    of its constructor (default: its defaults)."""
    if not PEERS_PY.exists():
        return {"error": "peers not installed (make bench creates .venv-peers)"}
    proc = subprocess.run([str(PEERS_PY), str(ROOT / "benchmarks" / "_peer_worker.py"), name, str(seq), str(det),
                           str(out), json.dumps(params or {})], capture_output=True, text=True)
    if proc.returncode != 0:
        return {"error": (proc.stderr or proc.stdout).strip().splitlines()[-1]}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def score_table(results: dict, seqs: list[str], methods: list[str]) -> tuple[str, dict]:
    """Markdown table of MOTA/IDF1/HOTA (%), IDS/FP/FN per sequence and method, with the mean over
    sequences and the best peer per column; returns it and the per-sequence verdicts."""
    lines = ["| sequence | method | MOTA | IDF1 | HOTA | IDS | FP | FN |", "|---|---|---:|---:|---:|---:|---:|---:|"]
    verdict = {}
    for s in seqs:
        best = {k: max((results[(m, s)][k] for m in methods if m != "artmotion" and (m, s) in results), default=None)
                for k in KEYS}
        for m in methods:
            r = results.get((m, s))
            if r is None:
                continue
            cells = []
            for k in KEYS:
                v = f"{100 * r[k]:.1f}"
                cells.append(f"**{v}**" if m == "artmotion" and best[k] is not None and r[k] >= best[k] else v)
            lines.append(f"| {s} | {LABELS[m]} | {' | '.join(cells)} | {r['IDS']} | {r['FP']} | {r['FN']} |")
        if best["MOTA"] is not None and ("artmotion", s) in results:
            lines.append(f"| {s} | *best peer* | {' | '.join(f'{100 * best[k]:.1f}' for k in KEYS)} | | | |")
            verdict[s] = all(results[("artmotion", s)][k] >= best[k] for k in KEYS)
    means = {}
    for m in methods:
        if all((m, s) in results for s in seqs):
            means[m] = {k: float(np.mean([results[(m, s)][k] for s in seqs])) for k in KEYS}
            lines.append(f"| **mean** | {LABELS[m]} | {' | '.join(f'{100 * means[m][k]:.1f}' for k in KEYS)} | | | |")
    peers = [m for m in means if m != "artmotion"]
    if peers:
        best_mean = {k: max(means[m][k] for m in peers) for k in KEYS}
        lines.append(f"| **mean** | *best peer per column* | {' | '.join(f'{100 * best_mean[k]:.1f}' for k in KEYS)} | | | |")
        verdict["_best_mean"] = best_mean
    verdict["_means"] = means
    return "\n".join(lines), verdict


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", nargs="*", default=[str(SHARED / "mot15"), str(SHARED / "mot16")],
                    help="folders of MOTChallenge sequences")
    ap.add_argument("--methods", default=",".join(["artmotion", *PEERS]))
    ap.add_argument("--out", default=str(ROOT / "docs" / "benchmarks.md"), help="markdown report ('-': none)")
    ap.add_argument("--no-speed", action="store_true", help="skip the decode-floor measurement")
    ap.add_argument("--no-loo", action="store_true", help="skip the leave-one-out search and the ablation")
    ap.add_argument("--loo-folds", default=None, help="folds of the leave-one-out search (default: all and every sequence)")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT / "src"))
    from artmotion.io import atomic_write
    from artmotion.tracking.metrics import evaluate

    seqs = find_sequences(args.data)
    if not seqs:
        print("benchmarks/tracking.py: error: no sequences found", file=sys.stderr)
        return 2
    methods = [m for m in args.methods.split(",") if m]
    results: dict = {}
    weak: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        for seq in seqs:
            gt = seq / "gt" / "gt.txt"
            for det in sorted(seq.glob("det/det*.txt")):
                kind = det.stem.replace("det_", "") if det.stem != "det" else "published"
                for m in methods:
                    out = Path(tmp) / f"{seq.name}-{kind}-{m}.txt"
                    if m == "artmotion":
                        run = run_artmotion(seq, det, out)
                    else:
                        run = run_peer(m, seq, det, out)
                    if "error" in run:
                        print(f"[{seq.name} {kind}] {m}: FAILED: {run['error']}", file=sys.stderr)
                        continue
                    s = evaluate(gt, np.loadtxt(out, delimiter=",", ndmin=2) if out.stat().st_size else np.zeros((0, 7)))
                    (results if kind == "published" else weak)[(m, seq.name if kind == "published" else f"{seq.name} ({kind})")] = s
                    print(f"[{seq.name} {kind}] {m}: MOTA {s['MOTA']:.3f} IDF1 {s['IDF1']:.3f} HOTA {s['HOTA']:.3f}",
                          file=sys.stderr)
    names = [s.name for s in seqs]
    table, verdict = score_table(results, names, methods)
    weak_names = sorted({s for _, s in weak})
    weak_table, _ = score_table(weak, weak_names, methods) if weak else ("(no weak detections found)", {})
    speed = ["| sequence | frames | size | decode floor s | artmotion track s | ratio | frames/s | peak MiB |",
             "|---|---:|---|---:|---:|---:|---:|---:|"]
    for seq in [] if args.no_speed else [s for s in seqs if ("artmotion", s.name) in results]:
        with tempfile.TemporaryDirectory() as tmp:
            n, dec, run = speed_pair(seq, seq / "det" / "det.txt", Path(tmp) / "speed.txt")
        ini = (seq / "seqinfo.ini").read_text()
        size = "x".join(re.search(rf"{k}\s*=\s*(\d+)", ini).group(1) for k in ("imWidth", "imHeight"))
        speed.append(f"| {seq.name} | {n} | {size} | {dec:.2f} | {run['seconds']:.2f} | {run['seconds'] / dec:.2f}x | "
                     f"{n / run['seconds']:.0f} | {run['peak_bytes'] / 2 ** 20:.0f} |")
    wins = [s for s in names if verdict.get(s)]
    means = verdict.get("_means", {})
    summary = ""
    if "artmotion" in means and "_best_mean" in verdict:
        a, b = means["artmotion"], verdict["_best_mean"]
        summary = (f"artmotion is at least the best peer in MOTA, IDF1 and HOTA on {len(wins)} of {len(names)} "
                   f"sequences ({', '.join(wins) or 'none'}); mean MOTA/IDF1/HOTA {100 * a['MOTA']:.1f} / "
                   f"{100 * a['IDF1']:.1f} / {100 * a['HOTA']:.1f} against the best peer's "
                   f"{100 * b['MOTA']:.1f} / {100 * b['IDF1']:.1f} / {100 * b['HOTA']:.1f} "
                   f"(HOTA {100 * (a['HOTA'] - b['HOTA']):+.1f} points).")
    peers_version = "not installed"
    if PEERS_PY.exists():
        peers_version = subprocess.run([str(PEERS_PY), "-c", "from importlib.metadata import version; print(version('trackers'))"],
                                       capture_output=True, text=True).stdout.strip() or peers_version
    when = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    load = os.getloadavg()[0]
    report = f"""# Tracking benchmark

Generated by `python benchmarks/tracking.py` on {when} ({platform.machine()}, {os.cpu_count()} CPUs,
load average {load:.1f} at the end, Python {platform.python_version()}, trackers {peers_version}).
Every method gets the same detections; scores by `artmotion.tracking.metrics.evaluate` (MOT15 rules
for MOT15, MOT17 rules for MOT16-09), in %; **bold**: artmotion at least the best peer.
Peers run with their default parameters and the sequence's frame rate in their own environment.

{summary}

## Published detections (Faster R-CNN, `det/det.txt`)

{table}

## Weak detections (ACF, DPM; robustness)

{weak_table}

## Speed

The whole `artmotion track SEQ --det DET --out FILE` in a fresh process (Python start-up and
imports included) against the decode floor: a fresh Python process that imports OpenCV and decodes
every frame at full size (`cv2.imread` / `VideoCapture.read`), timed in alternation, the best of
five runs each.

{chr(10).join(speed)}
"""
    print(report)
    if args.out != "-":
        with atomic_write(args.out) as fh:
            fh.write(report)
        block = (f"{summary}\n\n{table}\n\nWeak detections:\n\n{weak_table}\n\nSpeed (load average {load:.1f}):\n\n"
                 + "\n".join(speed))
        replace_block(ROOT / "docs" / "tracking.md", "tracking-benchmark", block)
        print(f"written: {args.out} and docs/tracking.md", file=sys.stderr)
    if not args.no_loo:
        loo_and_ablation(write=args.out != "-", folds=args.loo_folds)
    return 0


def loo_and_ablation(write: bool, folds: str | None = None) -> None:
    """The leave-one-out choice of settings and the ablation (benchmarks/tracking_loo.py; scores
    are cached per version of the tracker's code, so a re-run only computes what changed)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import tracking_loo

    results = tracking_loo.run(folds=folds)
    loo = tracking_loo.held_out_table(results)
    print(loo)
    print(results["ablation"])
    if write:
        replace_block(ROOT / "docs" / "tracking.md", "tracking-loo", loo)
        replace_block(ROOT / "docs" / "tracking.md", "tracking-ablation", results["ablation"])


if __name__ == "__main__":
    sys.exit(main())
