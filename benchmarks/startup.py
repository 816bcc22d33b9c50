#!/usr/bin/env python
"""Start-up time of the command line: ``artmotion --help`` and a few commands' ``--help``, the
median wall time of ``--repeat`` runs each (issue #13: at most 0.3 s on this machine class).
Writes docs/startup.md (``--out -``: print only)."""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

from _docs import compile_package

ROOT = Path(__file__).resolve().parents[1]
CLI = Path(sys.executable).with_name("artmotion")
COMMANDS = [["--help"], ["track", "--help"], ["run", "--help"], ["pose", "--help"], ["articulation", "--help"]]


def seconds(args: list[str], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        subprocess.run([str(CLI), *args], check=True, capture_output=True)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=11)
    ap.add_argument("--out", default=str(ROOT / "docs" / "startup.md"))
    args = ap.parse_args(argv)
    compile_package()
    rows = [(" ".join(c), seconds(c, args.repeat)) for c in COMMANDS]
    table = "\n".join(["| command | median seconds |", "|---|---:|"] +
                      [f"| `artmotion {c}` | {s:.3f} |" for c, s in rows])
    text = ("# Start-up time\n\n"
            f"`python benchmarks/startup.py`: median of {args.repeat} runs each, {os.cpu_count()} cores "
            f"({platform.machine()}), load average {os.getloadavg()[0]:.1f}, Python {platform.python_version()}. "
            "The command line imports NumPy, OpenCV and the rest only when a command runs "
            "(`tests/shared/test_startup.py` checks that `--help` imports none of them).\n\n" + table + "\n")
    print(text)
    if args.out != "-":
        Path(args.out).write_text(text)
    worst = max(s for _, s in rows)
    return 0 if worst <= 0.3 else 1


if __name__ == "__main__":
    sys.exit(main())
