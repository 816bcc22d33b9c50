"""Annotated video: boxes, ids and trails drawn on the frames, written atomically as mp4."""

from __future__ import annotations

import os
from collections import defaultdict, deque

import cv2
import numpy as np

from artmotion.errors import InputError
from artmotion.geometry import box_center, fit_size
from artmotion.io import atomic_path
from artmotion.io.media import check_written_video, cv2_name, ffmpeg_quiet

__all__ = ["colour_of", "draw_boxes", "write_annotated"]


def colour_of(track_id: int) -> tuple[int, int, int]:
    """A stable, distinct BGR colour per id (golden-ratio hues)."""
    hue = int((track_id * 0.618033988749895 % 1.0) * 179)
    hsv = np.array([[[hue, 220, 255]]], dtype=np.uint8)
    b, g, r = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0]
    return int(b), int(g), int(r)


def draw_boxes(img: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Draw MOT rows (``frame,id,x,y,w,h,...``) of one frame with their ids onto ``img`` (in place)."""
    for r in rows:
        tid = int(r[1])
        x, y, bw, bh = r[2:6]
        col = colour_of(tid)
        cv2.rectangle(img, (int(x), int(y)), (int(x + bw), int(y + bh)), col, 2)
        cv2.putText(img, str(tid), (int(x), max(12, int(y) - 4)), cv2.FONT_HERSHEY_SIMPLEX, 0.55, col, 2, cv2.LINE_AA)
    return img


#: the annotated video's sides at most (MPEG-4 Part 2 takes at most 8191) and at least (it takes
#: no side of 1), and its frame rate at least (it takes none below 0.002 frames/s; a margin)
MAX_VIDEO_SIDE = 8000
MIN_VIDEO_SIDE = 2
MIN_VIDEO_FPS = 0.01


def video_geometry(width: int, height: int) -> tuple[float, tuple[int, int], tuple[int, int]]:
    """How frames of ``width`` x ``height`` go into the annotated video: the scale (below 1 when a
    side exceeds :data:`MAX_VIDEO_SIDE`), the scaled frame's size and the video's (the scaled frame
    padded to :data:`MIN_VIDEO_SIDE` a side)."""
    scale, inner = fit_size(width, height, MAX_VIDEO_SIDE, MAX_VIDEO_SIDE)
    return scale, inner, (max(MIN_VIDEO_SIDE, inner[0]), max(MIN_VIDEO_SIDE, inner[1]))


def write_annotated(path: str | os.PathLike, frames, tracks: np.ndarray, fps: float, size: tuple[int, int],
                    trail: int = 20, events: list[dict] | None = None) -> None:
    """Draw ``tracks`` (MOT rows) over ``frames`` (iterable of ``(n, BGR)``) into an mp4 at ``path``.
    Frames with a side over :data:`MAX_VIDEO_SIDE` are scaled down, a side of 1 pixel is padded,
    and the video plays at ``fps`` but never below :data:`MIN_VIDEO_FPS` (the codec takes none of
    those as they are: every frame size and rate artmotion reads gets its video)."""
    by_frame: dict[int, np.ndarray] = defaultdict(lambda: np.zeros((0, 10)))
    scale, inner, (w, h) = video_geometry(*size)
    tracks = np.asarray(tracks, dtype=float).reshape(-1, 10).copy()
    tracks[:, 2:6] *= scale
    for f in np.unique(tracks[:, 0]).astype(int):
        by_frame[f] = tracks[tracks[:, 0] == f]
    ev_by_frame = defaultdict(list)
    for ev in events or []:
        ev_by_frame[ev["frame"]].append(ev)
    trails: dict[int, deque] = defaultdict(lambda: deque(maxlen=trail))
    banner: list[tuple[int, str]] = []
    with atomic_path(path, suffix=".mp4") as tmp:
        # the stubs lack OpenCV's module-level alias of VideoWriter.fourcc
        fourcc = cv2.VideoWriter_fourcc(*"mp4v")  # type: ignore[attr-defined]
        with ffmpeg_quiet():
            writer = cv2.VideoWriter(cv2_name(tmp), fourcc, max(float(fps or 25.0), MIN_VIDEO_FPS), (w, h))
        if not writer.isOpened():
            raise InputError("cannot open a video writer (mp4v)", path=path)
        written = 0
        try:
            for n, img in frames:
                img = img.copy() if scale == 1.0 else cv2.resize(img, inner, interpolation=cv2.INTER_AREA)
                if (w, h) != inner:
                    img = cv2.copyMakeBorder(img, 0, h - inner[1], 0, w - inner[0], cv2.BORDER_CONSTANT)
                for r in by_frame[n]:
                    tid = int(r[1])
                    trails[tid].append(tuple(int(v) for v in box_center(r[2:6]) + [0, r[5] / 2]))
                    pts = list(trails[tid])
                    for a, b in zip(pts[:-1], pts[1:]):
                        cv2.line(img, a, b, colour_of(tid), 2, cv2.LINE_AA)
                draw_boxes(img, by_frame[n])
                for ev in ev_by_frame.get(n, []):
                    banner.append((n, f"{ev['type']} {','.join(map(str, ev['tracks']))}"))
                banner = [(f, s) for f, s in banner if n - f < max(1, int(fps))][-4:]
                for k, (_, s) in enumerate(banner):
                    cv2.putText(img, s, (8, 20 + 18 * k), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 2,
                                cv2.LINE_AA)
                cv2.putText(img, f"#{n}", (8, h - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
                writer.write(img)     # (not captured: the frames' reader captures on its own thread)
                written += 1
        finally:
            with ffmpeg_quiet():
                writer.release()
        check_written_video(tmp, written, where=path)    # a full disk drops frames without a word
