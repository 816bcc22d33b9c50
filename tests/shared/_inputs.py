"""Small, valid inputs of every kind a command reads, for the reliability and fuzz tests: each is
made in a few milliseconds and read by the command in a few more, so that many damaged copies can
be tried."""

from __future__ import annotations

import contextlib
import io
import json
import os
from pathlib import Path

import cv2
import numpy as np

W, H, N = 96, 72, 6        # a tiny sequence: 6 frames of 96x72


def frames(n: int = N) -> list[np.ndarray]:
    """A textured background and a box crossing it."""
    rng = np.random.default_rng(0)
    bg = cv2.GaussianBlur(rng.integers(40, 200, (H, W, 3), dtype=np.uint8), (5, 5), 0)
    out = []
    for k in range(n):
        img = bg.copy()
        x = 5 + 10 * k
        img[15:55, x:x + 16] = (40, 40, 220)
        out.append(img)
    return out


def det_rows(n: int = N) -> list[str]:
    return [f"{k + 1},-1,{5 + 10 * k},15,16,40,0.9" for k in range(n)]


def gt_rows(n: int = N) -> list[str]:
    return [f"{k + 1},1,{5 + 10 * k},15,16,40,1,-1,-1,-1" for k in range(n)]


SEQINFO = "[Sequence]\nname=tiny\nimDir=img1\nframeRate=25\nseqLength={n}\nimWidth=96\nimHeight=72\nimExt=.jpg\n"


def sequence(dst: Path, n: int = N) -> Path:
    """A MOTChallenge folder: seqinfo.ini, img1/*.jpg, det/det.txt, gt/gt.txt."""
    (dst / "img1").mkdir(parents=True)
    for k, img in enumerate(frames(n), start=1):
        cv2.imwrite(str(dst / "img1" / f"{k:06d}.jpg"), img)
    (dst / "det").mkdir()
    (dst / "det" / "det.txt").write_text("\n".join(det_rows(n)) + "\n")
    (dst / "gt").mkdir()
    (dst / "gt" / "gt.txt").write_text("\n".join(gt_rows(n)) + "\n")
    (dst / "seqinfo.ini").write_text(SEQINFO.format(n=n))
    return dst


def video(path: Path, n: int = N) -> Path:
    """An MJPG AVI (every frame a JPEG: damage stays local) of the sequence."""
    path.parent.mkdir(parents=True, exist_ok=True)
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, (W, H))
    for img in frames(n):
        out.write(img)
    out.release()
    return path


def pose_model(path: Path) -> Path:
    """A small trained pose model (HOG, 4 principal components, exact GP) and its crops folder
    ``<path stem>-crops`` with labels ``<path stem>-labels.csv``."""
    from artmotion.pose.model import PoseRegressor

    rng = np.random.default_rng(1)
    crops = path.parent / f"{path.stem}-crops"
    crops.mkdir(parents=True)
    imgs, rows = [], []
    for i in range(12):
        img = cv2.GaussianBlur(rng.integers(0, 255, (48, 64, 3), dtype=np.uint8), (3, 3), 0)
        cv2.line(img, (32, 24), (32 + int(20 * np.cos(i / 3)), 24 + int(20 * np.sin(i / 3))), (255, 255, 255), 3)
        cv2.imwrite(str(crops / f"{i:04d}.png"), img)
        imgs.append(img)
        rows.append([10.0 * i, 5.0 * np.sin(i)])
    labels = path.parent / f"{path.stem}-labels.csv"
    labels.write_text("image,opening,roll\n" + "".join(f"{i:04d}.png,{a:.3f},{b:.3f}\n" for i, (a, b) in enumerate(rows)))
    PoseRegressor(n_components=4, method="exact").fit(imgs, np.array(rows), ["opening", "roll"]).save(path)
    return path


def manifest(name: str = "cam1", source: str = "/videos/day1/cam1.mp4") -> dict:
    """A run.json as :func:`artmotion.app.pipeline.run_pipeline` writes it (what the index reads)."""
    return {
        "artmotion": "0.1.0", "name": name, "source": source, "fingerprint": "ab12cd34ef56ab78",
        "sequence": {"length": 50, "fps": 25.0, "width": 640, "height": 480},
        "track_summary": [{"id": 1, "first_frame": 1, "last_frame": 50, "boxes": 50}],
        "events": [{"type": "exit", "frame": 50, "tracks": [1], "side": "left", "x": 3.0, "y": 200.5}],
        "sentences": [{"sentence": "Person 1 exits to the left at 2.0 s (frame 50).", "subject": "person",
                       "verb": "exits", "adjective": "left", "tracks": [1], "frame_start": 50, "frame_end": 50}],
        "metrics": None,
    }


def run_folder(folder: Path, run: dict | None = None) -> Path:
    folder.mkdir(parents=True)
    (folder / "run.json").write_text(json.dumps(run if run is not None else manifest()))
    return folder


EVENTS = [{"type": "enter", "frame": 1, "tracks": [1], "side": "left", "x": 13.0, "y": 35.0},
          {"type": "merge", "frame": 3, "tracks": [1, 2], "group": 100, "x": 40.0, "y": 35.0},
          {"type": "split", "frame": 5, "tracks": [1, 2], "group": 100},
          {"type": "exit", "frame": 6, "tracks": [1], "side": "right"}]


def trajectory(n: int = 30) -> str:
    """An arc (revolute) as 'x y' rows."""
    t = np.linspace(0.0, 1.5, n)
    return "".join(f"{np.cos(a):.6f} {np.sin(a):.6f}\n" for a in t)


def call(*args) -> tuple[int, str, str]:
    """``artmotion ARGS`` in this process: (exit status, stdout, stderr)."""
    from artmotion.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([os.fspath(a) if isinstance(a, os.PathLike) else str(a) for a in args])
    return code, out.getvalue(), err.getvalue()


def assert_one_line_error(code: int, err: str, *needles: str) -> None:
    """Bad input: exit 2 and exactly one line ``artmotion: error: ...`` on stderr, naming no
    temporary file."""
    assert code == 2, f"exit {code}: {err}"
    assert err.endswith("\n") and err.count("\n") == 1, err
    assert err.startswith("artmotion: error: "), err
    assert "Traceback" not in err and ".tmp" not in err, err
    for n in needles:
        assert n in err, (n, err)


def leftovers(folder: Path) -> list[str]:
    """Temporary files or folders anywhere under ``folder`` (what an atomic write leaves when it
    fails to clean up)."""
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if ".tmp" in p.name)
