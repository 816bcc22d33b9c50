"""Batch throughput on Dask with 1 and 2 local workers (issue: archive scale).

Builds an archive of N copies of the shipped TUD-Campus sample (71 frames each), runs
``artmotion.app.run_batch`` on it with 1 and then 2 worker processes into fresh output folders,
and prints and writes frames/s and items/min into docs/app.md.

    .venv/bin/python benchmarks/app.py [--copies 6]
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from artmotion.app import run_batch  # noqa: E402
from artmotion.tracking import open_sequence  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--copies", type=int, default=6)
    ap.add_argument("--sample", type=Path, default=ROOT / "data" / "TUD-Campus")
    ap.add_argument("--doc", type=Path, default=ROOT / "docs" / "app.md")
    args = ap.parse_args()
    frames = open_sequence(args.sample).length
    load_before = os.getloadavg()[0]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        archive = Path(tmp) / "archive"
        archive.mkdir()
        for i in range(args.copies):
            shutil.copytree(args.sample, archive / f"campus-{i:02d}")
        for workers in (1, 2):
            t0 = time.perf_counter()
            report = run_batch(archive, Path(tmp) / f"out-{workers}", workers=workers)
            dt = time.perf_counter() - t0
            done = len(report.by_status("done"))
            rows.append((workers, done, dt, done * frames / dt, 60 * done / dt))
            print(f"{workers} worker(s): {done} items, {dt:.1f} s, {done * frames / dt:.1f} frames/s,"
                  f" {60 * done / dt:.1f} items/min", flush=True)
    table = ["| workers | items | seconds (incl. cluster start) | frames/s | items/min |", "|---|---|---|---|---|"]
    table += [f"| {w} | {n} | {dt:.1f} | {fps:.1f} | {ipm:.1f} |" for w, n, dt, fps, ipm in rows]
    speedup = rows[1][2] and rows[0][2] / rows[1][2]
    text = (
        "# Application benchmark: batch throughput\n\n"
        f"`python benchmarks/app.py --copies {args.copies}`: {args.copies} copies of the TUD-Campus sample"
        f" ({frames} frames, 640×480) through the whole pipeline (tracking, sentences, metrics, report,"
        f" annotated video) on a local Dask cluster; machine: {os.cpu_count()} cores, {platform.processor() or platform.machine()}.\n\n"
        + "\n".join(table)
        + f"\n\nSpeed-up with 2 workers: {speedup:.2f}×. Load average before the run: {load_before:.1f}"
        " (other work on the machine lowers the 2-worker gain; tracking itself already uses a second"
        " thread for decoding and OpenCV's own threads).\n"
    )
    args.doc.write_text(text)
    print(f"speed-up {speedup:.2f}x; written {args.doc}")


if __name__ == "__main__":
    main()
