"""Synthetic sequences with known truth: textured blobs moving over a textured background."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

W, H = 320, 240


def background(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    small = rng.integers(60, 140, size=(H // 8, W // 8, 3), dtype=np.uint8)
    bg = cv2.resize(small, (W, H), interpolation=cv2.INTER_CUBIC)
    return cv2.GaussianBlur(bg, (5, 5), 0)


def texture(w: int, h: int, colour, seed: int) -> np.ndarray:
    """A blob's own texture: a base colour with fixed random detail (KLT needs corners)."""
    rng = np.random.default_rng(seed)
    noise = rng.integers(-60, 60, size=(h // 3 + 1, w // 3 + 1, 1))
    noise = np.repeat(np.repeat(noise, 3, axis=0), 3, axis=1)[:h, :w]
    return np.clip(np.asarray(colour, dtype=int)[None, None, :] + noise, 0, 255).astype(np.uint8)


def render(boxes: dict, bg: np.ndarray, textures: dict, order=None) -> np.ndarray:
    """Draw blobs ``{id: [x, y, w, h]}`` (later ids in ``order`` in front)."""
    img = bg.copy()
    for i in order or sorted(boxes):
        x, y, w, h = (int(round(v)) for v in boxes[i])
        tex = textures[i]
        x0, y0 = max(0, x), max(0, y)
        x1, y1 = min(W, x + w), min(H, y + h)
        if x1 <= x0 or y1 <= y0:
            continue
        img[y0:y1, x0:x1] = tex[y0 - y:y1 - y, x0 - x:x1 - x]
    return img


def moving_blob(n: int = 30, v=(4.0, 1.0), start=(40.0, 80.0), size=(30, 60)):
    """Frames and true boxes of one blob moving at constant velocity ``v`` px/frame."""
    bg = background()
    tex = {1: texture(size[0], size[1], (40, 40, 220), seed=1)}
    frames, truth = [], []
    for k in range(n):
        box = np.array([start[0] + v[0] * k, start[1] + v[1] * k, *size], dtype=float)
        frames.append(render({1: box}, bg, tex))
        truth.append(box)
    return frames, np.array(truth)


def crossing(n: int = 40):
    """Two blobs of different colours crossing horizontally (red in front during the overlap)."""
    bg = background(3)
    size = (28, 64)
    tex = {1: texture(*size, (30, 30, 230), seed=5), 2: texture(*size, (230, 90, 30), seed=6)}
    truth = {1: [], 2: []}
    frames = []
    for k in range(n):
        b1 = np.array([30.0 + 6 * k, 90.0, *size])
        b2 = np.array([262.0 - 6 * k, 96.0, *size])
        truth[1].append(b1)
        truth[2].append(b2)
        frames.append(render({1: b1, 2: b2}, bg, tex, order=[2, 1]))
    return frames, {k: np.array(v) for k, v in truth.items()}


def write_mot_folder(root: Path, frames, dets: list[list], fps: float = 10.0, name: str = "synth") -> Path:
    """A MOTChallenge folder: img1/*.png, seqinfo.ini, det/det.txt (rows frame,-1,x,y,w,h,score)."""
    (root / "img1").mkdir(parents=True)
    (root / "det").mkdir()
    for k, img in enumerate(frames, start=1):
        cv2.imwrite(str(root / "img1" / f"{k:06d}.png"), img)
    (root / "seqinfo.ini").write_text(
        f"[Sequence]\nname={name}\nimDir=img1\nframeRate={fps:g}\nseqLength={len(frames)}\n"
        f"imWidth={W}\nimHeight={H}\nimExt=.png\n")
    with open(root / "det" / "det.txt", "w") as fh:
        for r in dets:
            fh.write(",".join(f"{v:g}" for v in r) + "\n")
    return root


def replay_groups(events):
    """Replay merge/split events as a state machine; check that they are consistent."""
    active = {}
    for e in events:
        if e["type"] == "merge":
            g = e["group"]
            assert g not in active or set(e["tracks"]) > active[g], e
            active[g] = set(e["tracks"])
        elif e["type"] == "split":
            assert active.get(e["group"]) == set(e["tracks"]), e
            del active[e["group"]]
        else:
            continue
        members = [t for ids in active.values() for t in ids]
        assert len(members) == len(set(members)), f"a track in two groups at frame {e['frame']}"
    return active
