"""Interrupting a command (Ctrl-C, SIGTERM) leaves nothing half-written and says so in one line."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

SRC = Path(__file__).resolve().parents[2] / "src"


@pytest.fixture(scope="module")
def long_video(tmp_path_factory):
    """A 600-frame video and detections of a box crossing it: writing the annotated video takes
    long enough to be interrupted in the middle."""
    root = tmp_path_factory.mktemp("long")
    video = root / "walk.avi"
    out = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, (320, 240))
    rng = np.random.default_rng(0)
    bg = cv2.GaussianBlur(rng.integers(0, 255, (240, 320, 3), dtype=np.uint8), (5, 5), 0)
    rows = []
    for k in range(600):
        img = bg.copy()
        x = 10 + (k % 250)
        img[80:150, x:x + 30] = (40, 40, 220)
        out.write(img)
        rows.append(f"{k + 1},-1,{x},80,30,70,0.95")
    out.release()
    det = root / "det.txt"
    det.write_text("\n".join(rows) + "\n")
    return video, det


@pytest.mark.parametrize("sig, code, word", [(signal.SIGTERM, 143, "terminated"), (signal.SIGINT, 130, "interrupted")])
def test_interrupted_track_leaves_nothing_half_written(tmp_path, long_video, sig, code, word):
    video, det = long_video
    out = tmp_path / "out"
    out.mkdir()
    proc = subprocess.Popen([sys.executable, "-m", "artmotion", "track", str(video), "--det", str(det),
                             "--out", str(out / "res.txt"), "--video", str(out / "ann.mp4"), "--no-progress"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, PYTHONPATH=str(SRC)))
    deadline = time.monotonic() + 120
    # the outputs' temporary names exist from the start; the video's own (a temporary name of its
    # temporary name) once it is being written
    while not list(out.glob("..ann.mp4.*")) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)                      # wait until the annotated video is being written
    assert proc.poll() is None, "finished before it could be interrupted"
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"artmotion: {word}") and "half-written" in lines[0], err
    assert sorted(p.name for p in out.iterdir()) == [], "a temporary or partial output was left"


_TORCH_IMPORT = """
import os, signal, sys
def prof(frame, event, arg):
    if event == "c_call" and getattr(arg, "__name__", "") == "_autograd_init":
        sys.setprofile(None)
        os.kill(os.getpid(), signal.SIGINT)      # while torch's native start-up runs
sys.setprofile(prof)
try:
    import artmotion._torch
except KeyboardInterrupt:
    print("torch" in sys.modules and hasattr(sys.modules["torch"], "nn"))
"""


def test_ctrl_c_during_the_import_of_torch_waits_for_it():
    """A Ctrl-C while torch's native start-up runs aborted the process (a C++ "terminate called",
    exit 134, a stack dump) when it landed in a call back into Python: it is held until torch is
    imported, then interrupts as anywhere else."""
    pytest.importorskip("torch")
    proc = subprocess.run([sys.executable, "-c", _TORCH_IMPORT], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, PYTHONPATH=str(SRC)))
    assert proc.returncode == 0 and proc.stdout.strip() == "True", (proc.stdout, proc.stderr)


def test_a_second_signal_does_not_cut_the_clean_up_short():
    """The first signal interrupts the command; those after it, while the outputs being written are
    removed, are ignored (a second Ctrl-C 20 ms after the first left a hidden partial folder)."""
    from artmotion import cli
    from artmotion.errors import Interrupted

    sigs = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
    before = {s: signal.getsignal(s) for s in sigs}
    try:
        for s in sigs:
            signal.signal(s, cli._terminate)
        with pytest.raises(Interrupted):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.1)                          # (the handler runs at once)
        os.kill(os.getpid(), signal.SIGINT)          # during the clean-up: nothing happens
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.05)
    finally:
        for s, handler in before.items():
            signal.signal(s, handler)
