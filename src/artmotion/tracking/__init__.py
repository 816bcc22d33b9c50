"""artmotion.tracking: people tracking through occlusions (thesis Ch. 2).

``track(source)`` runs the Product of Tracking Experts (Sec. 2.4) inside the group-node
multi-object tracker (Sec. 2.5) and returns the tracks (MOTChallenge rows) and events.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from artmotion.errors import InputError
from artmotion.tracking.experts import EXPERTS, Expert, Gaussian, box_gaussian, register_expert
from artmotion.tracking.mot import MultiObjectTracker, TrackerConfig
from artmotion.tracking.pote import PoTE, fuse
from artmotion.tracking.sequence import Sequence, open_sequence
from artmotion.tracking.metrics import evaluate

__all__ = [
    "DEFAULT_EXPERTS",
    "EXPERTS",
    "Expert",
    "Gaussian",
    "PoTE",
    "Sequence",
    "TrackResult",
    "TrackerConfig",
    "box_gaussian",
    "evaluate",
    "fuse",
    "open_sequence",
    "register_expert",
    "track",
]

DEFAULT_EXPERTS = ("det", "klt", "blob", "motion", "flow")


@dataclass
class TrackResult:
    """What :func:`track` returns.

    ``tracks``: ``(N, 10)`` MOTChallenge rows ``frame, id, x, y, w, h, conf, -1, -1, -1``;
    ``events``: event dicts (docs/interfaces.md); ``fps``: processing speed (frames per second of
    the whole run); ``frames``: frames processed; ``seconds``: wall time; ``sequence``: the
    :class:`Sequence`; ``detector``: where detections came from.
    """

    tracks: np.ndarray
    events: list
    fps: float
    frames: int = 0
    seconds: float = 0.0
    sequence: Sequence | None = None
    detector: str = ""
    experts: tuple = field(default_factory=tuple)

    @property
    def num_tracks(self) -> int:
        return int(len(np.unique(self.tracks[:, 1]))) if len(self.tracks) else 0


def _work_scale(width: int, height: int) -> float:
    """Scale of the images the experts look at: about 288 pixels on the short side."""
    return min(1.0, 288.0 / float(min(width, height)))


def _check_experts(experts) -> tuple:
    if isinstance(experts, str):
        experts = [e.strip() for e in experts.split(",") if e.strip()]
    experts = tuple(experts)
    if not experts:
        raise InputError("no experts given")
    for e in experts:
        if e not in EXPERTS:
            raise InputError(f"unknown expert {e!r} (choose from {', '.join(sorted(EXPERTS))})")
    if len(set(experts)) != len(experts):
        raise InputError("an expert is listed twice")
    if "det" not in experts:
        raise InputError("the 'det' expert is needed: tracks start from detections (thesis Sec. 2.5.1)")
    return experts


def track(source, det=None, experts=DEFAULT_EXPERTS, online: bool = False, progress: bool = False,
          video=None, config: TrackerConfig | None = None) -> TrackResult:
    """Track people in ``source`` (MOTChallenge folder, video file or image folder).

    ``det``: a MOTChallenge detection file; by default the sequence's ``det/det.txt``, else the
    built-in HOG people detector runs on every frame. ``experts``: names of the tracking experts
    (registered in :data:`EXPERTS`). ``online``: only causal results (no back-tracking, group
    interpolation or tentative beginnings). ``progress``: a progress bar on stderr.
    ``video``: also write an annotated mp4 there.
    """
    from artmotion.tracking.detect import HOGPeopleDetector, load_detections
    from artmotion.tracking.experts import Frame

    experts = _check_experts(experts)
    seq = open_sequence(source)
    det_path = Path(det) if det is not None else seq.det_path
    detector = None
    if det_path is not None:
        dets, source_name = load_detections(det_path), str(det_path)
        if dets and max(dets) > seq.length and seq.images is not None:
            raise InputError(f"detections for frame {max(dets)} but the sequence has {seq.length} frames",
                             path=det_path)
    else:
        detector, dets, source_name = HOGPeopleDetector(), {}, "hog"
    tracker = MultiObjectTracker(seq.fps, seq.width, seq.height, experts=experts, config=config, online=online)
    scale = _work_scale(seq.width, seq.height)
    shared: dict = {}
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=seq.length, unit="frame", desc=seq.name, leave=False)
    t0 = time.perf_counter()
    n = 0
    try:
        for n, img in seq.frames():
            d = detector(img) if detector is not None else dets.get(n)
            tracker.step(Frame(n, img, d, scale=scale, shared=shared))
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    if n == 0:
        raise InputError("no frames", path=seq.path)
    if dets and max(dets) > n:
        raise InputError(f"detections for frame {max(dets)} but the sequence has {n} frames", path=det_path)
    rows, events = tracker.finish(n)
    seconds = time.perf_counter() - t0
    if video is not None:
        from artmotion.tracking.video import write_annotated
        write_annotated(video, seq.frames(), rows, seq.fps, (seq.width, seq.height), events=events)
    return TrackResult(rows, events, fps=n / seconds if seconds > 0 else float("inf"), frames=n,
                       seconds=seconds, sequence=seq, detector=source_name, experts=experts)
