"""The tracking API: :func:`track` a sequence, :func:`run_tracker` on frames already decoded."""

from __future__ import annotations

import numbers
import time
from collections.abc import Mapping
from contextlib import closing
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from artmotion.errors import InputError, check_bool, check_range
from artmotion.io.atomic import check_apart, check_writable
from artmotion.io.sequence import Sequence, open_sequence
from artmotion.tracking.config import DETECT_EVERY, TrackerConfig, check_detect_every
from artmotion.tracking.experts import check_experts
from artmotion.tracking.mot import MultiObjectTracker
from artmotion.tracking.online import OnlineTracker

__all__ = ["DEFAULT_EXPERTS", "Sequence", "TrackResult", "open_sequence", "run_tracker", "track"]

DEFAULT_EXPERTS = ("det", "motion")
#: what the detections' source says of an empty detections file (:attr:`TrackResult.detector`)
NO_DETECTIONS = " (no detections in it: nothing tracked)"


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
        return len(set(self.tracks[:, 1].tolist()))


def too_short(num_tracks: int, frames: int, confirm: int | None = None, what: str = "a track") -> str:
    """Why there is no track when the input is shorter than the detections that confirm one (``""``
    otherwise): a summary's "0 tracks" then says so instead of nothing. ``confirm``: the frames of
    detections that confirm ``what`` (the people tracker's ``confirm_hits`` unless given)."""
    confirm = TrackerConfig().confirm_hits if confirm is None else confirm
    if num_tracks or frames >= confirm:
        return ""
    return f"{what} is confirmed by detections on {confirm} frames, and the input has {frames}"


def _work_reduce(width: int, height: int) -> int:
    """How many times smaller (1, 2, 4 or 8) the images the tracker looks at are than the frames:
    the largest power of two that keeps at least 240 pixels on the short side."""
    k = 1
    while k < 8 and min(width, height) / (2 * k) >= 240:
        k *= 2
    return k


def _check_experts(experts) -> tuple:
    """The tracker's experts (:func:`~artmotion.tracking.experts.check_experts`, ``det`` among them)."""
    return check_experts(experts, need_det=True)


def run_tracker(tracker: MultiObjectTracker, frames, detections: dict, reduce: int = 1, decode: int = 1,
                detector=None, on_frame=None, detect_every: int = 1) -> int:
    """Feed ``frames`` (``(number, BGR image)`` pairs, decoded ``decode`` times smaller than the
    sequence) to ``tracker`` one by one; the experts look at images ``reduce`` times smaller.
    Detections come from ``detections`` (frame -> ``(N, 5)`` array) or, when ``detector`` is
    given, from running it on every ``detect_every``-th frame and on the last (the experts and the
    motion model carry the tracks in between), one frame ahead on a worker thread (OpenCV
    releases Python's lock while it detects, so detection overlaps decoding and tracking). Returns the number of
    the last frame.

    Frame numbers must be whole numbers >= 1 that increase, images ``(height, width, 3)`` BGR
    uint8 of the tracker's size (``decode`` times smaller), detections finite boxes of positive
    size: else an :class:`~artmotion.errors.InputError` naming the frame."""
    from artmotion.tracking.experts import Frame

    if not isinstance(tracker, OnlineTracker):
        raise InputError(f"run_tracker needs a MultiObjectTracker, got {type(tracker).__name__}")
    reduce = check_range("reduce", reduce, 1, 100, integer=True)
    decode = check_range("decode", decode, 1, 100, integer=True)
    detect_every = check_detect_every(detect_every)
    if detector is None and not isinstance(detections, Mapping):
        raise InputError("detections must be a mapping of frame numbers to (N, 5) arrays x, y, w, h, score "
                         f"(a dict), got {type(detections).__name__}")
    if detector is not None and not callable(detector):
        raise InputError(f"detector must be callable (image -> (N, 5) detections), got {type(detector).__name__}")
    if detector is None:
        bad = next((k for k in detections if isinstance(k, bool) or not isinstance(k, numbers.Integral)), None)
        if bad is not None:     # (a key "1" or 1.5 was never looked up: no box anywhere, no error)
            raise InputError(f"detections: frame numbers must be whole numbers (int keys), got {bad!r}")
    shared: dict = {}
    n = 0
    for n, img, d in _with_detections(frames, detections, detector, detect_every):
        tracker.step(Frame(n, img, d, scale=1.0 / reduce, shared=shared, image_scale=1.0 / decode))
        n = tracker.last_frame      # the frame number as the tracker took it (3.0 is frame 3)
        if on_frame is not None:
            on_frame(1)
    return n


def _with_detections(frames, detections: dict, detector, every: int = 1):
    """``(number, image, detections)`` for each frame, ``None`` for detections on the frames other
    than every ``every``-th (not detected): from ``detections`` (a frame it does not list has
    none), or from a ``detector`` run one frame ahead on a worker thread, on the last frame too."""
    if detector is None:
        last = None
        for k, (n, img) in enumerate(_pairs(frames)):
            if last is not None:
                yield last
            last = (n, img, detections.get(n, _NONE) if k % every == 0 else None)
        if last is not None:
            yield last[0], last[1], detections.get(last[0], _NONE)
        return
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1, thread_name_prefix="artmotion-detect") as pool:
        pending = None
        for k, (n, img) in enumerate(_pairs(frames)):
            job = pool.submit(detector, img) if k % every == 0 else None
            if pending is not None:
                yield _done(*pending)
            pending = (n, img, job)
        if pending is not None:
            n, img, job = pending
            # the last frame is always detected: nothing after it would confirm the boxes the
            # motion model carries there (they were cut), and a clip of at most ``every`` frames
            # would have one frame of detections, too few to confirm a track
            yield _done(n, img, job if job is not None else pool.submit(detector, img))


def _pairs(frames):
    """``frames`` as ``(number, image)`` pairs; else an :class:`~artmotion.errors.InputError`."""
    try:
        it = iter(frames)
    except TypeError:
        raise InputError(f"frames must be an iterable of (number, image) pairs, got {type(frames).__name__}") from None
    for item in it:
        try:
            n, img = item
        except (TypeError, ValueError):
            raise InputError(f"frames must be (number, image) pairs, got {type(item).__name__}") from None
        yield n, img


def _done(n: int, img: np.ndarray, job):
    return n, img, None if job is None else job.result()


_NONE = np.zeros((0, 5))


def track(source, det=None, experts=DEFAULT_EXPERTS, online: bool = False, progress: bool = False,
          video=None, config: TrackerConfig | None = None, fps: float | None = None,
          detector="auto", detect_every: int = DETECT_EVERY, bits: int | None = None) -> TrackResult:
    """Track people in ``source`` (MOTChallenge folder, video file or image folder).

    ``det``: a MOTChallenge detection file; by default the sequence's ``det/det.txt``, else the
    ``detector`` runs: a built-in one by name (:func:`~artmotion.tracking.detectors.make_detector`:
    ``auto``, ``ssdlite`` or ``hog``) or a :class:`~artmotion.tracking.detectors.Detector` of your
    own, which runs even where the sequence has a ``det/det.txt`` (with ``det`` too: an
    :class:`~artmotion.errors.InputError`). ``detect_every``: run that detector on every k-th
    frame (and the last) only, the motion model (and the image experts) carrying the boxes in
    between. ``experts``: names of the tracking experts
    (registered in :data:`EXPERTS`). ``online``: only causal results (no back-tracking, group
    interpolation or tentative beginnings). ``progress``: a progress bar on stderr.
    ``video``: also write an annotated mp4 there. ``fps``: the frame rate, when the input does not
    say it (a folder of images; else 25 is assumed) or says it wrong. ``bits``: the bits that 16-bit
    image files hold, when frames spread over them said it wrong (:meth:`Sequence.set_bits`).
    """
    from artmotion.tracking.detect import read_detections
    from artmotion.tracking.detectors import MIN_DETECTOR_SIDE, Detector, check_detector, make_detector

    experts = _check_experts(experts)
    check_bool("online", online)
    check_bool("progress", progress)
    if isinstance(detector, str):
        check_detector(detector)
    elif not isinstance(detector, Detector):
        raise InputError(f"detector must be a name (auto, ssdlite, hog) or a Detector, got {type(detector).__name__}")
    elif det is not None:
        raise InputError("give detections (det) or a detector of your own, not both")
    check_detect_every(detect_every)
    if video is not None:
        from artmotion.io.media import cv2_name

        cv2_name(video)         # (before the work: OpenCV writes the video)
    seq = open_sequence(source)
    seq.set_fps(fps, "frame rate")
    seq.set_bits(bits, "bits")
    # (a detector of the caller's own is what they asked for: it wins over the sequence's det.txt)
    det_path = Path(det) if det is not None else seq.det_path if isinstance(detector, str) else None
    if video is not None:   # (before the work: the annotated video replaced the input video or gt.txt)
        check_writable(video, inputs=(*seq.inputs(), det_path))
        check_apart(video, (seq.video_home,))   # (a second video in it would make the sequence unreadable)
    model = None
    if det_path is not None:
        dets, probabilities = read_detections(det_path)
        # (an empty file: a scene with nobody in it, or a mistake; said where the detections are named)
        source_name = str(det_path) + ("" if probabilities else " (scores not in [0, 1]: ranked)") \
            + ("" if dets else NO_DETECTIONS)
        if dets and max(dets) > seq.length and seq.images is not None:
            raise InputError(f"detections for frame {max(dets)} but the sequence has {seq.length} frames",
                             path=det_path)
    else:
        if isinstance(detector, str) and min(seq.width, seq.height) < MIN_DETECTOR_SIDE:    # (before the work)
            raise InputError(f"frames of {seq.width}x{seq.height} pixels are too small for the built-in detector "
                             f"(at least {MIN_DETECTOR_SIDE} a side): give detections (--det)", path=seq.path)
        model = make_detector(detector) if isinstance(detector, str) else detector
        dets, source_name = {}, model.name
    tracker = MultiObjectTracker(seq.fps, seq.width, seq.height, experts=experts, config=config, online=online)
    reduce = _work_reduce(seq.width, seq.height)
    # the tracker only looks at the reduced images; a detector needs the whole frame
    decode = 1 if model is not None else reduce
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=seq.length, unit="frame", desc=seq.name, leave=False)
    t0 = time.perf_counter()
    try:
        with closing(seq.frames(reduce=decode)) as frames:
            n = run_tracker(tracker, frames, dets, reduce=reduce, decode=decode, detector=model,
                            detect_every=detect_every if model is not None else 1,
                            on_frame=bar.update if bar is not None else None)
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
        with closing(seq.frames()) as frames:
            write_annotated(video, frames, rows, seq.fps, (seq.width, seq.height), events=events)
    return TrackResult(rows, events, fps=n / seconds if seconds > 0 else float("inf"), frames=n,
                       seconds=seconds, sequence=seq, detector=source_name, experts=experts)
