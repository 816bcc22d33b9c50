"""Articulation from plain video (``artmotion articulation video``): which part moves, and how.

Stages, each a function of this package:

1. :func:`~.tracks.point_tracks` — long KLT point tracks with forward-backward checks;
2. :func:`~.segment.noise_level`, :func:`~.segment.camera_motion` — the tracks' own noise, and the
   camera's motion taken out;
3. :func:`~.segment.moving_tracks`, :func:`~.segment.rigid_parts` — tracks that belong to the
   scene and later move, grouped into rigid parts (hands and arms enter moving and are left out);
4. :func:`~.joint.classify_part` — each part's motion lifted to 3-D under weak perspective, every
   point's lifted track classified by the same online model choice as trajectories from logs, and
   the points' posteriors pooled.

:func:`analyze_video` runs them all and returns the JSON answer of the command.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from artmotion.articulation.video.joint import MAX_FOCAL
from artmotion.articulation.video.segment import Part
from artmotion.articulation.video.tracks import PointTracks
from artmotion.errors import InputError, check_range, check_seed

if TYPE_CHECKING:
    from artmotion.io.sequence import Sequence

__all__ = ["VideoArticulation", "analyze_video", "analyze_tracks", "draw_parts", "parts_strip", "snapshot_frames"]

#: most moving parts the part search looks for: the range the command line (``articulation
#: video``) takes (the largest focal length is :data:`~.joint.MAX_FOCAL`)
MAX_PARTS = 20


def _check_options(focal, max_parts, seed) -> None:
    """The options of :func:`analyze_video` in the command line's ranges, else an :class:`InputError`."""
    if focal is not None:
        check_range("focal", focal, 0.0, MAX_FOCAL, lo_open=True)
    check_range("max_parts", max_parts, 1, MAX_PARTS, integer=True)
    check_seed(seed, "seed")


@dataclass
class VideoArticulation:
    """The answer for one video; :meth:`to_dict` is the command's JSON. ``snapshots``: frames
    (index -> BGR image) kept for :func:`parts_strip`."""

    camera: str
    parts: list[dict]
    tracks: PointTracks
    found: list[Part] = field(default_factory=list)
    noise: float = 0.0
    snapshots: dict[int, np.ndarray] = field(default_factory=dict)
    #: why no part could be found, when none could be whatever moved ("" otherwise)
    note: str = ""
    #: False when the input did not say its frame rate and 25 frames/s were assumed
    fps_known: bool = True
    #: what the input's orientation tag asks a viewer to do with the frames (``""``: nothing), e.g.
    #: ``"turn 90°"``: the frames are read as stored, and positions are in stored pixels
    orientation: str = ""
    #: 16-bit image files: ``(bits, largest value)`` (:attr:`~artmotion.io.sequence.Sequence.depth`)
    depth: tuple[int, int | None] | None = None

    @property
    def model(self) -> str:
        """The joint of the part that moves most; ``static`` when no part moves."""
        return self.parts[0]["model"] if self.parts else "static"

    @property
    def confidence(self) -> float:
        """Its probability; 0.5 when no part moves (nothing was seen to move, which says little
        about a joint)."""
        return self.parts[0]["confidence"] if self.parts else 0.5

    def to_dict(self) -> dict:
        return {"model": self.model, "confidence": self.confidence, "parts": self.parts, "camera": self.camera,
                "frames": self.tracks.frames, "fps": self.tracks.fps, "noise_px": self.noise, "note": self.note or None,
                "orientation": self.orientation or None}


def analyze_tracks(tracks: PointTracks, focal: float | None = None, max_parts: int = 3, seed: int = 0) -> VideoArticulation:
    """Stages 2-4 on point tracks (see the module doc): a :class:`PointTracks` of two frames or more."""
    _check_options(focal, max_parts, seed)
    if not isinstance(tracks, PointTracks):
        raise InputError(f"tracks must be a PointTracks, got {type(tracks).__name__}")
    if tracks.frames < 2:
        raise InputError(f"tracks of {tracks.frames} frame{'s' if tracks.frames != 1 else ''}: motion needs at least two")
    from artmotion.articulation.video.joint import classify_part
    from artmotion.articulation.video.segment import REST, camera_motion, moving_tracks, noise_level, rest_frames, rigid_parts

    sigma = noise_level(tracks)
    moving, tracks = camera_motion(tracks, sigma)
    found = rigid_parts(tracks, moving_tracks(tracks, sigma), sigma, max_parts=max_parts, seed=seed)
    parts = [classify_part(tracks, p, focal=focal) for p in found]
    note = ""
    k = rest_frames(tracks.fps)
    if not parts and tracks.frames <= 2 * k:
        note = (f"too short to tell: a moving part is looked for among points that rest for their first {REST:g} s "
                f"({k} frames at {tracks.fps:g} frames/s) and are followed twice as long; the video has "
                f"{tracks.frames} frames")
    elif not parts and tracks.xy.shape[1] == 0:
        note = "nothing to follow: no corner in the frames is trackable (no texture)"
    return VideoArticulation("moving" if moving else "static", parts, tracks, found, sigma, note=note)


def snapshot_frames(frames: int, count: int) -> list[int]:
    """``count`` frame indices spread evenly over ``frames`` frames, first and last included."""
    return sorted({int(round(x)) for x in np.linspace(0, frames - 1, count)}) if count and frames else []


def analyze_video(source: str | os.PathLike | Sequence, focal: float | None = None, max_parts: int = 3, seed: int = 0,
                  on_frame: Callable[[int, int], None] | None = None, snapshots: int = 0,
                  fps: float | None = None, bits: int | None = None) -> VideoArticulation:
    """Open ``source`` (a video file or a folder of frames) and find its moving parts' joints.
    ``on_frame(done, total)`` reports progress while tracking; ``snapshots`` frames spread over
    the video (the last one read included) are kept in the result, for :func:`parts_strip`:
    a whole number >= 0 (0: none), at most :data:`~artmotion.io.mot.MAX_FRAME`. ``fps``: the
    frame rate, when the input does not say it (a folder of frames; else 25 is assumed) or says
    it wrong: the time a part must rest first, and the motion models, are in seconds. ``bits``: the
    bits 16-bit image frames hold, when frames spread over them said it wrong
    (:meth:`~artmotion.io.sequence.Sequence.set_bits`). The frames are read as stored, whatever the
    input's orientation tag asks (said in ``orientation``)."""
    from artmotion.articulation.video.tracks import point_tracks
    from artmotion.io.mot import MAX_FRAME
    from artmotion.io.sequence import open_sequence

    _check_options(focal, max_parts, seed)
    snapshots = check_range("snapshots", snapshots, 0, MAX_FRAME, integer=True)
    seq = open_sequence(source)
    seq.set_fps(fps, "fps")
    seq.set_bits(bits, "bits")
    total = len(seq)
    want = set(snapshot_frames(total, snapshots))
    kept: dict[int, np.ndarray] = {}

    def frames():
        last = None
        for num, img in seq.frames():
            if num - 1 in want:
                kept[num - 1] = img
            last = (num - 1, img)
            yield img
        if want and last is not None:  # the last frame read is the last snapshot (a length may be an estimate)
            kept.pop(total - 1, None)
            kept[last[0]] = last[1]

    try:
        tracks = point_tracks(frames(), seq.fps, on_frame=None if on_frame is None else (lambda n: on_frame(n, total)))
    except InputError as exc:
        if exc.path is not None:
            raise
        raise InputError(exc.reason, path=seq.path) from None     # (no frames)
    if tracks.frames < 2:
        raise InputError(f"{tracks.frames} frame: motion needs at least two", path=seq.path)
    res = analyze_tracks(tracks, focal=focal, max_parts=max_parts, seed=seed)
    res.snapshots = kept
    res.fps_known = seq.fps_known
    res.orientation = seq.orientation
    res.depth = seq.depth
    return res


def parts_strip(result: VideoArticulation) -> np.ndarray:
    """The result's snapshots side by side, each with :func:`draw_parts` up to its frame."""
    if not result.snapshots:
        raise InputError("no snapshots: analyze_video(..., snapshots=4) keeps them")
    return np.hstack([draw_parts(img, result, frame=k) for k, img in sorted(result.snapshots.items())])


def draw_parts(image: np.ndarray, result: VideoArticulation, frame: int | None = None) -> np.ndarray:
    """``image`` (BGR uint8, or grey uint8) with each part's tracks (up to ``frame``) in its own
    colour and its fitted axis or line drawn, labelled with the model."""
    import cv2

    image = np.asarray(image)
    if image.dtype != np.uint8 or not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 3)):
        raise InputError(f"draw_parts draws on a BGR (or grey) uint8 image, got {image.dtype} of shape {image.shape}")
    out = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR) if image.ndim == 2 else image.copy()
    colours = [(60, 200, 60), (60, 60, 230), (230, 120, 40), (200, 60, 200), (40, 200, 220)]
    xy = result.tracks.xy if frame is None else result.tracks.xy[: frame + 1]
    for k, (part, d) in enumerate(zip(result.found, result.parts)):
        c = colours[k % len(colours)]
        for i in part.tracks:
            q = xy[:, i]
            q = q[~np.isnan(q[:, 0])]
            if len(q) > 1:
                cv2.polylines(out, [np.round(q).astype(np.int32).reshape(-1, 1, 2)], False, c, 1, cv2.LINE_AA)
        ax = d.get("axis")
        if ax:
            p = np.asarray(ax["point"], float)
            v = np.asarray(ax["direction"][:2], float)
            if d["model"] == "revolute" and ax.get("towards_camera"):
                cv2.circle(out, tuple(int(round(x)) for x in p), 8, c, 2, cv2.LINE_AA)
            elif np.linalg.norm(v) > 1e-6 and np.all(np.abs(p) < 1e5):
                v = v / np.linalg.norm(v) * 0.5 * math.hypot(*out.shape[:2][::-1])
                a, b = (p - v).round().astype(int), (p + v).round().astype(int)
                cv2.line(out, (int(a[0]), int(a[1])), (int(b[0]), int(b[1])), c, 2, cv2.LINE_AA)
        q0 = xy[:, part.tracks].reshape(-1, 2)
        q0 = q0[~np.isnan(q0[:, 0])]
        if len(q0):
            x, y = np.median(q0, axis=0).astype(int)
            label = f"{k + 1}: {d['model']} {d['confidence']:.2f}"
            cv2.putText(out, label, (int(x), int(y)), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 3, cv2.LINE_AA)
            cv2.putText(out, label, (int(x), int(y)), cv2.FONT_HERSHEY_SIMPLEX, 0.6, c, 1, cv2.LINE_AA)
    return out
