"""Peak memory of ``track`` does not grow with the length of the sequence."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from _synth import H, W, background, render, texture

SRC = Path(__file__).resolve().parents[2] / "src"


def _walkers(n: int, root: Path, until: int | None = None) -> tuple[Path, Path]:
    """A video of ``n`` frames where a person enters every 40 frames and walks across in 80
    (about two in view at a time, ``n / 40`` tracks in all), and its detections. ``until``: no one
    enters after this frame (the rest of the video is the empty background)."""
    bg = background(7)
    size = (24, 56)
    video = root / f"walk{n}-{until}.mp4"
    out = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 25.0, (W, H))
    rng = np.random.default_rng(n)
    rows = []
    textures = {}
    for k in range(n):
        boxes = {}
        for i in range(max(0, (k - 80) // 40), min(k, until or n) // 40 + 1):
            age = k - 40 * i
            if 0 <= age < 80:
                boxes[i] = np.array([-20.0 + 4.2 * age, 60.0 + 40 * (i % 3), *size])
                if i not in textures:
                    textures[i] = texture(*size, tuple(int(c) for c in rng.integers(30, 230, 3)), seed=i)
        out.write(render(boxes, bg, textures))
        for i, b in boxes.items():
            if rng.random() < 0.9:
                j = b + rng.normal(0, 1.0, 4) * [1, 1, 0.5, 0.5]
                rows.append(f"{k + 1},-1,{j[0]:.1f},{j[1]:.1f},{j[2]:.1f},{j[3]:.1f},{rng.uniform(0.7, 1):.3f}")
        for tid in [t for t in textures if t < k // 40 - 3]:
            del textures[tid]
    out.release()
    det = root / f"det{n}-{until}.txt"
    det.write_text("\n".join(rows) + "\n")
    return video, det


_PEAK = """
import resource, sys
from artmotion.tracking import track
res = track(sys.argv[1], det=sys.argv[2])
print(res.frames, res.num_tracks, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, len(res.tracks))
"""


def _peak_kib(video: Path, det: Path) -> tuple[int, int, int, int]:
    """Frames, tracks, peak RSS (KiB) and reported boxes of ``track`` in a fresh process."""
    out = subprocess.run([sys.executable, "-c", _PEAK, str(video), str(det)], capture_output=True, text=True,
                         env={"PYTHONPATH": str(SRC), "PATH": "/usr/bin:/bin"}, check=True)
    frames, tracks, peak, boxes = (int(v) for v in out.stdout.split())
    return frames, tracks, peak, boxes


@pytest.mark.slow
def test_peak_memory_is_flat_in_sequence_length(tmp_path):
    short = _peak_kib(*_walkers(300, tmp_path))
    long = _peak_kib(*_walkers(3000, tmp_path))
    assert short[0] == 300 and long[0] == 3000
    assert long[1] >= 8 * short[1]          # ten times the frames, about ten times the people
    assert long[2] <= 1.10 * short[2], f"peak RSS {short[2]} KiB at 300 frames, {long[2]} KiB at 3000"


@pytest.mark.slow
def test_peak_memory_is_flat_over_10000_frames(tmp_path):
    """Issue 13: a 10,000-frame synthetic sequence is tracked in the memory of a 1,000-frame one
    when both have the same people (nothing per frame is kept); with ten times the people, memory
    grows only with the result (at most 2 KiB per reported box)."""
    short = _peak_kib(*_walkers(1000, tmp_path))
    empty_tail = _peak_kib(*_walkers(10_000, tmp_path, until=1000))
    assert short[0] == 1000 and empty_tail[0] == 10_000
    assert empty_tail[2] <= 1.05 * short[2], f"peak RSS {short[2]} KiB at 1000 frames, {empty_tail[2]} KiB at 10000"
    full = _peak_kib(*_walkers(10_000, tmp_path))
    assert full[1] >= 8 * short[1]
    per_box = (full[2] - short[2]) / (full[3] - short[3])
    assert per_box <= 2.0, f"{per_box:.2f} KiB more per reported box ({short[2]} KiB at 1000 frames, {full[2]} at 10000)"
