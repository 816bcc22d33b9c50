"""A self-contained HTML report of one run: key frames, trajectories, timeline, sentences, metrics.

Images are embedded as data URIs, so the single ``report.html`` opens in any browser with no
server and can be mailed or archived as one file.
"""

from __future__ import annotations

import base64
import html
import os
from contextlib import closing
from pathlib import Path

import cv2
import numpy as np
from jinja2 import Environment, FileSystemLoader, select_autoescape

from artmotion.geometry import fit_size
from artmotion.io import atomic_write, check_writable
from artmotion.tracking.video import colour_of, draw_boxes

MAX_KEY_FRAMES = 8
#: the report's images are at most this wide (and three times this tall)
DISPLAY_WIDTH = 960


def draw_trajectories(background: np.ndarray, tracks: np.ndarray) -> np.ndarray:
    """Every track's foot point (bottom centre of its box) as a polyline over the scene."""
    out = background.copy()
    for tid in np.unique(tracks[:, 1]).astype(int):
        rows = tracks[tracks[:, 1] == tid]
        rows = rows[np.argsort(rows[:, 0])]
        pts = np.stack([rows[:, 2] + rows[:, 4] / 2, rows[:, 3] + rows[:, 5]], axis=1).round().astype(np.int32)
        color = colour_of(tid)
        cv2.polylines(out, [pts.reshape(-1, 1, 2)], False, color, 2, cv2.LINE_AA)
        cv2.circle(out, tuple(int(v) for v in pts[0]), 4, color, -1)
        cv2.putText(out, str(tid), tuple(int(v) for v in pts[-1]), cv2.FONT_HERSHEY_SIMPLEX, 0.6, color, 2, cv2.LINE_AA)
    return out


def _data_uri(image: np.ndarray) -> str:
    ok, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 85])
    return "data:image/jpeg;base64," + base64.b64encode(buf.tobytes()).decode("ascii")


def key_frames(length: int, events: list[dict], tracks: np.ndarray, k: int = MAX_KEY_FRAMES) -> list[int]:
    """Frames worth showing: the events' frames first, then evenly spaced frames with tracks."""
    chosen: list[int] = []
    for ev in sorted(events, key=lambda e: e["frame"]):
        f = int(ev["frame"])
        if all(abs(f - c) > max(2, length // (4 * k)) for c in chosen):
            chosen.append(f)
    if len(chosen) > k:
        chosen = [chosen[i] for i in np.linspace(0, len(chosen) - 1, k).round().astype(int)]
    busy = np.unique(tracks[:, 0]).astype(int) if len(tracks) else np.arange(1, length + 1)
    for f in busy[np.linspace(0, len(busy) - 1, min(k, len(busy))).round().astype(int)] if len(busy) else []:
        if len(chosen) >= k:
            break
        if all(abs(int(f) - c) > 2 for c in chosen):
            chosen.append(int(f))
    return sorted(chosen)


def _timeline_svg(manifest: dict, length: int) -> str:
    """Track lifespans as bars and events as marks, frame on x; hover shows the sentence."""
    tracks = manifest["track_summary"]
    row_h, left, width = 18, 70, 900
    height = row_h * (len(tracks) + 1) + 30
    xs = lambda f: left + (width - left - 10) * (f - 1) / max(length - 1, 1)  # noqa: E731
    rows = {t["id"]: i for i, t in enumerate(tracks)}
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" class="timeline">']
    for t in tracks:
        y = 10 + rows[t["id"]] * row_h
        b, g, r = colour_of(t["id"])
        parts.append(f'<text x="4" y="{y + 12}" font-size="12">track {t["id"]}</text>')
        parts.append(
            f'<rect x="{xs(t["first_frame"]):.1f}" y="{y + 3}" width="{max(xs(t["last_frame"]) - xs(t["first_frame"]), 2):.1f}"'
            f' height="{row_h - 6}" fill="rgb({r},{g},{b})" opacity="0.7"><title>track {t["id"]}: frames'
            f' {t["first_frame"]}–{t["last_frame"]}</title></rect>'
        )
    glyph = {"enter": "▶", "exit": "■", "merge": "◆", "split": "◇"}
    for ev in manifest["events"]:
        for tid in ev["tracks"]:
            if tid in rows:
                y = 10 + rows[tid] * row_h
                label = html.escape(f'{ev["type"]} at frame {ev["frame"]}' + (f' ({ev["side"]})' if ev.get("side") else ""))
                parts.append(f'<text x="{xs(ev["frame"]) - 5:.1f}" y="{y + 13}" font-size="12" '
                             f'class="ev ev-{html.escape(ev["type"])}">'
                             f'{glyph.get(ev["type"], "●")}<title>{label}</title></text>')
    y = height - 8
    for f in np.linspace(1, length, 6).round().astype(int):
        parts.append(f'<text x="{xs(f) - 8:.1f}" y="{y}" font-size="11">{f}</text>')
    parts.append("</svg>")
    return "".join(parts)


def write_report(path: str | os.PathLike, seq, tracks: np.ndarray, manifest: dict) -> Path:
    """Render ``report.html`` for one run (``seq`` from :func:`artmotion.io.sequence.open_sequence`).
    Every image is made at the size it is shown (at most :data:`DISPLAY_WIDTH` wide and three times
    that tall), the frames decoded at a reduced size where they are larger: at the largest frames
    artmotion reads (2^27 pixels) the key frames and the background's 25 samples at full or half
    size took 12 GB."""
    check_writable(path, inputs=seq.inputs())  # (before the work; the input video was replaced by the page)
    length = int(seq.length)
    keys = set(key_frames(length, manifest["events"], tracks))
    samples = set(np.linspace(1, length, min(length, 25)).round().astype(int).tolist())
    scale, (dw, dh) = fit_size(int(seq.width), int(seq.height), DISPLAY_WIDTH, 3 * DISPLAY_WIDTH)
    half = (max(1, dw // 2), max(1, dh // 2))
    shown = tracks.copy()
    shown[:, 2:6] *= scale                  # the boxes in the report's pixels
    reduce = max(k for k in (1, 2, 4, 8) if k * scale <= 1.0)
    key_images, background_samples = {}, []
    with closing(seq.frames(reduce=reduce)) as frames:
        for fno, frame in frames:
            if fno not in keys and fno not in samples:
                continue
            small = frame if frame.shape[:2] == (dh, dw) else cv2.resize(frame, (dw, dh), interpolation=cv2.INTER_AREA)
            if fno in keys:
                key_images[fno] = draw_boxes(small.copy(), shown[shown[:, 0] == fno])
            if fno in samples:      # (at half size: the median over 25 frames is most of the report's time)
                background_samples.append(cv2.resize(small, half, interpolation=cv2.INTER_AREA))
    if background_samples:  # the median of frames spread over time removes moving people
        bg = np.median(np.stack(background_samples), axis=0).astype(np.uint8)
        bg = cv2.resize(bg, (dw, dh), interpolation=cv2.INTER_LINEAR)
    else:
        bg = np.zeros((dh, dw, 3), np.uint8)
    events_by_frame: dict[int, list[str]] = {}
    for s in manifest["sentences"]:
        events_by_frame.setdefault(int(s.get("frame_start") or 0), []).append(s["sentence"])
    fps = float(seq.fps or 0) or None
    sentences = [
        dict(s, time=(f'{(s["frame_start"] - 1) / fps:.1f}–{(s["frame_end"] - 1) / fps:.1f} s'
                      if fps and s.get("frame_start") and s.get("frame_end") else ""))
        for s in sorted(manifest["sentences"], key=lambda s: (s.get("frame_start") or 0, s["sentence"]))
    ]
    env = Environment(loader=FileSystemLoader(Path(__file__).parent / "templates"),
                      autoescape=select_autoescape(["html", "j2"]))
    page = env.get_template("report.html.j2").render(
        name=manifest["name"],
        manifest=manifest,
        length=length,
        n_tracks=len(manifest["track_summary"]),
        trajectories=_data_uri(draw_trajectories(bg, shown)),
        key_frames=[{"frame": f, "uri": _data_uri(img),
                     "sentences": [s for f0, ss in events_by_frame.items() if abs(f0 - f) <= 2 for s in ss]}
                    for f, img in sorted(key_images.items())],
        timeline=_timeline_svg(manifest, length),
        sentences=sentences,
        metrics=manifest.get("metrics"),
    )
    with atomic_write(path) as fh:
        fh.write(page)
    return Path(path)
