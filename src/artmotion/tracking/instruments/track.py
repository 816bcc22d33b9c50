"""Instruments tracked through a laparoscopic video: ``artmotion tool track`` (thesis Sec. 2.6.1).

Each instrument head is an entity of a Product of Tracking Experts (Sec. 2.4, Eq. 2.1-2.3) whose
experts are, frame by frame:

* **motion continuity**: a constant-velocity Kalman filter on the head's position, whose
  prediction is first carried by the camera's own motion (a similarity from background corners,
  :func:`~artmotion.tracking.camera.estimate_motion`, with the heads left out);
* **KLT**: corners around the head followed by pyramidal Lucas-Kanade, checked forward-backward;
  their median displacement moves the head;
* **dense flow** (optional, off by default: it did not raise the held-out scores, docs/surgical.md):
  OpenCV's DIS optical flow (medium preset: the fast one reads a small part's motion short), its
  median over the inner half of the head's window moves the head;
* **the detector** (:class:`~artmotion.tracking.instruments.detector.ToolDetector`), when one of
  its detections is assigned to the head (Hungarian assignment within a gate).

Their Gaussians are multiplied (:func:`~artmotion.tracking.pote.fuse`). The shaft angle and the
head's size come from the detector (the image), smoothed; while no detection supports a head the
angle turns with the camera. A head is reported while detections support it or for at most
``coast`` frames without; it is dropped after ``max_miss`` frames. Identities persist: a head is
born from a detection that no head explains (score at least ``birth``), and is confirmed by a
detection on a second frame; then its earlier frames are reported too (as a person's track is
from its first detection): :func:`track_tools` holds a frame back while a tentative head may still
add its row to it. A head seen on one frame only is not reported.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from artmotion.errors import InputError, check_bool, check_range
from artmotion.io.media import check_frame
from artmotion.io.mot import MAX_COORD
from artmotion.tracking.association import INF, assign
from artmotion.tracking.camera import estimate_motion
from artmotion.tracking.experts import Gaussian
from artmotion.tracking.instruments.detector import finite_rows, scale_to
from artmotion.tracking.pote import fuse

__all__ = ["ToolTracker", "track_tools", "track_sequence", "to_mot"]

#: detections on this many frames confirm a head (a tentative head's rows wait for it)
CONFIRM_HITS = 2
#: a frame whose brightest pixel is below this (of 255) is nearly black
DARK = 32
_LK = {"winSize": (15, 15), "maxLevel": 3, "criteria": (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.03)}


@dataclass
class _Head:
    id: int
    x: np.ndarray  # [px, py, vx, vy]
    P: np.ndarray
    size: float
    angle: float
    score: float
    hits: int = 1
    miss: int = 0
    early: list[tuple[int, list[float]]] = field(default_factory=list)  # (frame, row) while tentative


def _window(h: _Head, r: float, shape: tuple[int, ...]) -> tuple[int, int, int, int] | None:
    """The window ``x0, y0, x1, y1`` of half-size ``r`` around head ``h`` inside an image of
    ``shape``; None when less than 6 px of it is inside."""
    x, y = h.x[:2]
    r = int(r)
    x0, y0, x1, y1 = int(max(0, x - r)), int(max(0, y - r)), int(min(shape[1], x + r)), int(min(shape[0], y + r))
    return (x0, y0, x1, y1) if x1 - x0 >= 6 and y1 - y0 >= 6 else None


def _moved(h: _Head, d: np.ndarray, px: float = 1.0) -> Gaussian:
    """The image-motion expert's opinion from displacements ``d`` ``(n, 2)`` seen in the head's
    window: their median moves the head, their median spread (+1 px) and 2 px make its std (``px``:
    pixels per pixel of the training frames)."""
    med = np.median(d, axis=0)
    spread = float(np.median(np.linalg.norm(d - med, axis=1))) + px
    return Gaussian(h.x[:2] + med, np.eye(2) * (spread**2 + 4.0 * px * px))


def _check_detections(detections, what: str) -> np.ndarray:
    """``detections`` as a ``(k, 5)`` array of finite x, y, size, angle, score — a positive size, a
    place within :data:`~artmotion.io.mot.MAX_COORD` pixels, a score in [0, 1] — else an
    :class:`InputError` (a negative size and a score of 7 were tracked and written out)."""
    D = finite_rows(detections, 5, what, "x, y, size, angle, score")
    if (D[:, 2] <= 0).any() or (np.abs(D[:, :3]) > MAX_COORD).any() or ((D[:, 4] < 0) | (D[:, 4] > 1)).any():
        raise InputError(f"{what}: each head needs a positive size, a place within {MAX_COORD:g} px and a score "
                         "in [0, 1]")
    return D


class ToolTracker:
    """Frame-by-frame tracker of instrument heads; :meth:`update` returns the reported rows
    ``(k, 6)``: track, x, y, size, angle, score, of confirmed heads (detections on ``CONFIRM_HITS`` frames).
    A head confirmed by this frame's detection adds the rows of its earlier, tentative frames to
    ``late`` (``(frame index, row)``, frames counted from 0 in ``frame``); ``settled``: the frames
    before it get no more late rows. ``capped``: frames on which the detector's cap of heads a
    frame (``max_heads_``) left out a detection that could have started a head (``birth``).

    Pixel settings (``detect_std``, ``accel``, ``gate``, ``merge``, the experts' windows) are in pixels
    of the detector's training frames; a video of another size scales them by its size (as the
    detector scales the frames, :func:`~artmotion.tracking.instruments.detector.scale_to`).

    ``detect_std``: the detector's position error (px); ``accel``: the heads' acceleration noise
    (px / frame^2); ``gate``: largest distance (px) of a detection to a head's prediction;
    ``birth``: least score of a detection that starts a head; ``coast``/``max_miss``: frames a head
    is reported / kept without a detection; ``merge``: two heads closer than this (px) are one (the
    better established stays), and no head starts that close to another; ``klt``/``camera``: the KLT
    expert and the camera's motion (off only to measure what they bring); ``flow``: the dense-flow
    (DIS) expert.
    """

    def __init__(self, detector, detect_std: float = 4.0, accel: float = 4.0, gate: float = 40.0,
                 birth: float = 0.4, coast: int = 0, max_miss: int = 15, klt: bool = True, merge: float = 15.0,
                 camera: bool = True, flow: bool = False):
        for name, flag in (("klt", klt), ("camera", camera), ("flow", flow)):
            check_bool(name, flag)
        for name, value in (("detect_std", detect_std), ("accel", accel), ("gate", gate), ("merge", merge)):
            check_range(name, value, 0.0, 1e6, lo_open=True)
        check_range("birth", birth, 0.0, 1.0)
        check_range("coast", coast, 0, 10**6, integer=True)
        check_range("max_miss", max_miss, 0, 10**6, integer=True)
        if not callable(getattr(detector, "detect", None)):
            raise InputError(f"detector must have a detect(frame) method (a ToolDetector), got {type(detector).__name__}")
        self.detector = detector
        self.detect_std = detect_std
        self.accel = accel
        self.gate = gate
        self.birth = birth
        self.coast = coast
        self.max_miss = max_miss
        self.klt = klt
        self.merge = merge
        self.camera = camera
        self.flow = flow
        self._dis: Any = None  # cv2.DISOpticalFlow, made on first use
        self._px = 1.0  # pixels of this video per pixel of the detector's training frames (first frame)
        self.heads: list[_Head] = []
        self.frame = -1
        self.late: list[tuple[int, list[float]]] = []
        self.capped = 0
        self._next_id = 0
        self._prev: np.ndarray | None = None
        self._bg: np.ndarray | None = None
        #: the first frame's brightest value (of 255) and whether it is grey (None before it)
        self.first_max: int | None = None
        self.first_grey: bool | None = None

    # -- experts
    def _camera(self, grey: np.ndarray) -> np.ndarray | None:
        if self._prev is None or not self.camera:
            return None
        boxes = np.array([[h.x[0] - h.size, h.x[1] - h.size, 2 * h.size, 2 * h.size] for h in self.heads]).reshape(-1, 4)
        A, self._bg = estimate_motion(self._prev, grey, exclude=boxes, points=self._bg)
        return A

    def _predict(self, A: np.ndarray | None):
        F = np.eye(4)
        F[0, 2] = F[1, 3] = 1.0
        q = (self.accel * self._px) ** 2
        Q = q * np.array([[0.25, 0, 0.5, 0], [0, 0.25, 0, 0.5], [0.5, 0, 1, 0], [0, 0.5, 0, 1]])
        for h in self.heads:
            if A is not None:  # the camera carries the head: position by A, velocity by its linear part
                M = A[:, :2]
                h.x[:2] = M @ h.x[:2] + A[:, 2]
                h.x[2:] = M @ h.x[2:]
                T = np.zeros((4, 4))
                T[:2, :2] = T[2:, 2:] = M
                h.P = T @ h.P @ T.T
                h.angle = (h.angle + math.atan2(A[1, 0], A[0, 0])) % (2 * math.pi)
            h.x = F @ h.x
            h.P = F @ h.P @ F.T + Q

    def _klt(self, grey: np.ndarray) -> list[Gaussian | None]:
        out: list[Gaussian | None] = [None] * len(self.heads)
        if not self.klt or self._prev is None:
            return out
        seeds = []  # (head, corners in its window): every head's corners go through one LK call each way
        for i, h in enumerate(self.heads):  # before the prediction: the head where it was last frame
            win = _window(h, max(8 * self._px, 0.5 * h.size), grey.shape)
            if win is None:
                continue
            x0, y0, x1, y1 = win
            pts = cv2.goodFeaturesToTrack(self._prev[y0:y1, x0:x1], 20, 0.01, 3, blockSize=3)
            if pts is not None and len(pts) >= 4:
                seeds.append((i, (pts + np.array([x0, y0], np.float32)).astype(np.float32)))
        if not seeds:
            return out
        p0 = np.concatenate([p for _, p in seeds])
        p1, st, _ = cv2.calcOpticalFlowPyrLK(self._prev, grey, p0, None, **_LK)  # type: ignore[call-overload]
        if p1 is None:
            return out
        pb, stb, _ = cv2.calcOpticalFlowPyrLK(grey, self._prev, p1, None, **_LK)  # type: ignore[call-overload]
        good = (st.ravel() == 1) & (stb.ravel() == 1) & (np.linalg.norm((pb - p0).reshape(-1, 2), axis=1) < 1.0)
        moved = (p1 - p0).reshape(-1, 2)
        start = 0
        for i, pts in seeds:
            ok, d = good[start:start + len(pts)], moved[start:start + len(pts)]
            start += len(pts)
            if ok.sum() >= 4:
                out[i] = _moved(self.heads[i], d[ok], self._px)
        return out

    def _flow(self, grey: np.ndarray) -> list[Gaussian | None]:
        out: list[Gaussian | None] = [None] * len(self.heads)
        if not self.flow or self._prev is None or not self.heads:
            return out
        if self._dis is None:
            # the stubs lack OpenCV's module-level alias of DISOpticalFlow.create
            self._dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)  # type: ignore[attr-defined]
        flow = self._dis.calc(self._prev, grey, None)
        for i, h in enumerate(self.heads):  # the head where it was last frame, as for KLT
            win = _window(h, max(4 * self._px, 0.25 * h.size), grey.shape)  # the inner half: the head, not the tissue
            if win is not None:
                x0, y0, x1, y1 = win
                out[i] = _moved(h, flow[y0:y1, x0:x1].reshape(-1, 2), self._px)
        return out

    # -- one frame
    def update(self, frame: np.ndarray, detections: np.ndarray | None = None) -> np.ndarray:
        """Track into BGR ``frame``; ``detections`` ``(k, 5)`` (x, y, size, angle, score) or None to run
        the detector. Returns the reported heads ``(k, 6)``: track, x, y, size, angle, score."""
        check_frame(frame)
        if self._prev is not None and frame.shape[:2] != self._prev.shape:
            (h, w), (H, W) = self._prev.shape, frame.shape[:2]
            raise InputError(f"a frame of {W}x{H} after frames of {w}x{h}: a tracker follows one video, of one frame size")
        given = None if detections is None else _check_detections(detections, "detections")
        grey = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        if self._prev is None:  # the pixel settings are in the training frames' pixels: this video's scale
            from artmotion.tracking.instruments.detector import is_grey

            trained = getattr(self.detector, "frame_shape_", None)
            self._px = 1.0 if trained is None else 1.0 / scale_to(trained, grey.shape[:2])
            self.first_max, self.first_grey = int(frame.max()), is_grey(frame)
        D = _check_detections(self.detector.detect(frame), "the detector's detections") if given is None else given
        cut = getattr(self.detector, "left_out_", None) if given is None else None
        if cut is not None and len(cut) and cut[0] >= self.birth:
            self.capped += 1
        self.frame += 1
        self.late = []
        A = self._camera(grey)
        klt = self._klt(grey)
        dense = self._flow(grey)
        self._predict(A)
        # assignment of detections to heads (distance to the prediction fused with KLT and flow)
        pri = []
        for h, g, f in zip(self.heads, klt, dense):
            motion = Gaussian(h.x[:2].copy(), h.P[:2, :2].copy())
            pri.append(fuse([motion, g, f]) or motion)
        assigned: dict[int, int] = {}
        if self.heads and len(D):
            C = np.linalg.norm(np.array([p.mean for p in pri])[:, None, :] - D[None, :, :2], axis=2)
            assigned = dict(assign(np.where(C <= self.gate * self._px, C, INF)))
        used = set(assigned.values())
        keep = []
        for i, (h, p) in enumerate(zip(self.heads, pri)):
            det = None
            if i in assigned:
                d = D[assigned[i]]
                det = Gaussian(d[:2].copy(), np.eye(2) * (self.detect_std * self._px) ** 2)
            est = fuse([p, det])  # the product of the motion, KLT, flow and detector experts (Eq. 2.3)
            assert est is not None
            # Kalman update of the motion filter with the fused position as its measurement
            R = est.cov + 1e-6 * np.eye(2)
            S = h.P[:2, :2] + R
            K = h.P[:, :2] @ np.linalg.inv(S)
            h.x = h.x + K @ (est.mean - h.x[:2])
            h.P = h.P - K @ h.P[:2, :]
            if det is not None:
                d = D[assigned[i]]
                h.size = 0.7 * h.size + 0.3 * float(d[2])
                da = math.remainder(float(d[3]) - h.angle, 2 * math.pi)
                h.angle = (h.angle + 0.6 * da) % (2 * math.pi)
                h.score = float(d[4])
                h.hits += 1
                h.miss = 0
            else:
                h.miss += 1
                h.score *= 0.8
            if h.miss <= self.max_miss:
                keep.append(h)
        # one instrument, one head: of two heads on the same spot the better established stays
        keep.sort(key=lambda h: (-h.hits, h.id))
        self.heads = []
        for h in keep:
            if all(math.hypot(*(h.x[:2] - o.x[:2])) > self.merge * self._px for o in self.heads):
                self.heads.append(h)
        rows = []
        for h in sorted(self.heads, key=lambda h: h.id):
            row = [h.id, h.x[0], h.x[1], h.size, h.angle, h.score]
            if h.hits < CONFIRM_HITS:  # tentative: its row waits for its confirmation
                if h.miss <= self.coast:
                    h.early.append((self.frame, row))
                continue
            self.late += h.early
            h.early = []
            if h.miss <= self.coast:
                rows.append(row)
        for j, d in enumerate(D):
            # a detection no head explains starts one, unless it lies on a head (a second response)
            if j not in used and d[4] >= self.birth and all(math.hypot(*(d[:2] - h.x[:2])) > self.merge * self._px
                                                             for h in self.heads):
                P = np.diag([self.detect_std**2, self.detect_std**2, 100.0, 100.0]) * self._px**2
                self.heads.append(_Head(self._next_id, np.array([d[0], d[1], 0.0, 0.0]), P, float(d[2]), float(d[3]),
                                        float(d[4]), early=[(self.frame, [self._next_id, *map(float, d)])]))
                self._next_id += 1
        self._prev = grey
        return np.array(rows, dtype=float).reshape(-1, 6)

    @property
    def settled(self) -> int:
        """The first frame (index) a tentative head may still add a late row to (every frame before
        it is final); the next frame's when there is none."""
        return min((h.early[0][0] for h in self.heads if h.early), default=self.frame + 1)


def track_tools(frames: Iterable[tuple], detector, tracker: ToolTracker | None = None,
                **options) -> Iterator[tuple[int, np.ndarray]]:
    """Track the instruments of ``(frame number, BGR image)`` pairs (or ``(frame number, BGR image,
    detections)``: the detector's output given, as a benchmark reuses it); yields ``(frame number,
    rows)`` with rows ``(k, 6)``: track, x, y, size, angle, score (see :class:`ToolTracker`), each
    frame once no tentative head can add its row to it any more (with the rows of the heads
    confirmed later). ``tracker``: the :class:`ToolTracker` to use (to read its counts after), else
    one of ``detector`` and ``options``."""
    tracker = ToolTracker(detector, **options) if tracker is None else tracker
    pending: dict[int, tuple[int, list]] = {}  # frame index -> (frame number, rows), in order

    def done(k: int) -> tuple[int, np.ndarray]:
        no, rows = pending.pop(k)
        out = np.array(rows, dtype=float).reshape(-1, 6)
        return no, out[np.argsort(out[:, 0], kind="stable")]

    for item in frames:
        no, img = item[0], item[1]
        rows = tracker.update(img, item[2] if len(item) > 2 else None)
        pending[tracker.frame] = (no, rows.tolist())
        for k, row in tracker.late:
            pending[k][1].append(row)
        while pending and next(iter(pending)) < tracker.settled:
            yield done(next(iter(pending)))
    while pending:
        yield done(next(iter(pending)))


def track_sequence(seq, detector, progress: bool = False, tracker: ToolTracker | None = None,
                   **options) -> Iterator[tuple[int, np.ndarray]]:
    """:func:`track_tools` over an opened :class:`~artmotion.io.sequence.Sequence` (1-based
    frame numbers), with a progress bar when ``progress``."""
    frames = seq.frames()
    if progress:
        from tqdm import tqdm

        frames = tqdm(frames, total=len(seq), unit="frame", leave=False)
    yield from track_tools(frames, detector, tracker, **options)


def to_mot(pred: Iterable[tuple[int, np.ndarray]]) -> np.ndarray:
    """MOTChallenge rows ``(n, 10)`` of tracked heads: ids from 1, a square of the head's size
    around it, the score as confidence (for the tracks' sentences, report and index)."""
    rows = [[f, r[0] + 1, r[1] - r[3] / 2, r[2] - r[3] / 2, r[3], r[3], r[5], -1, -1, -1] for f, R in pred for r in R]
    return np.array(rows, dtype=float).reshape(-1, 10)
