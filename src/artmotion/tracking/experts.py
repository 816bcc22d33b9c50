"""Tracking experts of the Product of Tracking Experts (thesis Sec. 2.4).

Every expert maps ``(frame, previous frame, entity)`` to a Gaussian belief over the entity's box
centre — a :class:`Gaussian` with ``mean`` (2,) and ``cov`` (2, 2) in full-image pixels — or
``None`` when it has no opinion. Experts that only produce a box are turned into a Gaussian with
Eq. 2.9 (:func:`box_gaussian`: centre as mean, ``diag(w, h) / 6`` as covariance).

Experts are pluggable: subclass :class:`Expert`, give it a ``name`` and decorate it with
:func:`register_expert`; :func:`make_experts` builds them by name. Nothing else needs to change.

A :class:`Frame` carries what experts share in one time step (the image, a downscaled grey image,
dense flow and foreground mask computed lazily and once, the detections of the frame) so that
experts over many entities cost little.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar

import cv2
import numpy as np

from artmotion.errors import InputError, check_range, float_array
from artmotion.filters import KalmanFilter, constant_velocity
from artmotion.geometry import box_area, box_center, intersection, iou

__all__ = [
    "BlobExpert",
    "DetectionExpert",
    "EXPERTS",
    "Entity",
    "Expert",
    "FlowExpert",
    "Frame",
    "Gaussian",
    "KLTExpert",
    "MotionExpert",
    "belief_problem",
    "box_gaussian",
    "check_detections",
    "check_experts",
    "make_experts",
    "register_expert",
]


@dataclass
class Gaussian:
    """A Gaussian belief over a 2-D box centre (pixels)."""

    mean: np.ndarray
    cov: np.ndarray

    def __post_init__(self):
        try:
            self.mean = np.asarray(self.mean, dtype=float).reshape(2)
            self.cov = np.asarray(self.cov, dtype=float).reshape(2, 2)
        except (TypeError, ValueError):
            raise InputError(f"a Gaussian over a box centre needs a mean of 2 numbers and a 2x2 covariance, got "
                             f"mean {self.mean!r}, cov {self.cov!r}") from None


def box_gaussian(box, scale: float = 1.0) -> Gaussian:
    """Eq. 2.9: a box ``[x, y, w, h]`` as ``N(centre, diag(w, h) / 6)`` (times ``scale``); one box
    (shape ``(4,)``, or a stack of one)."""
    box = np.asarray(box, dtype=float)
    if box.shape != (4,):
        if box.shape != (1, 4):
            raise InputError(f"box_gaussian takes one box x, y, w, h (shape (4,)), got shape {box.shape}")
        box = box[0]
    if not (box[2] > 0 and box[3] > 0):      # (NaN too) a box of no size would be a certain belief
        raise InputError(f"box_gaussian needs a box of positive width and height, got {box[2]:g}x{box[3]:g}")
    if not math.isfinite(box[0] + box[1] + box[2] + box[3]):     # (a NaN or infinite mean: no belief)
        raise InputError(f"box_gaussian needs a finite box, got {box.tolist()}")
    if scale != 1.0:                          # (0, negative or NaN: no covariance; the trackers' own calls give none)
        check_range("scale", scale, 0.0, 1e12, lo_open=True)
    return Gaussian(box_center(box), np.diag([max(box[2], 1e-3), max(box[3], 1e-3)]) / 6.0 * scale)


#: how far (relative to the trace) a belief's covariance may be from symmetric: float32 rounding
#: of a covariance computed as ``J P J^T`` stays far below it, a covariance that is not one does not
BELIEF_SYMMETRY = 1e-5


def asymmetric(c: np.ndarray) -> bool:
    """Whether the 2x2 covariance ``c`` is further from symmetric than :data:`BELIEF_SYMMETRY`."""
    return abs(c[0, 1] - c[1, 0]) > BELIEF_SYMMETRY * (c[0, 0] + c[1, 1])


def belief_problem(g) -> str | None:
    """What is wrong with ``g`` as an expert's belief (``None``: nothing): not a
    :class:`Gaussian`, a mean that is not finite, a covariance that is not finite and positive
    definite (a zero covariance would be a certain expert, a negative one nonsense)."""
    if not isinstance(g, Gaussian):
        return f"a {type(g).__name__}, not a Gaussian or None"
    if not np.isfinite(g.mean).all():
        return f"a mean that is not finite ({g.mean[0]:g}, {g.mean[1]:g})"
    c = g.cov
    det = c[0, 0] * c[1, 1] - c[0, 1] * c[1, 0]
    if not (0.0 < det < np.inf and c[0, 0] > 0 and np.isfinite(c).all()):
        return ("a covariance that is not finite and positive definite "
                f"[[{c[0, 0]:g}, {c[0, 1]:g}], [{c[1, 0]:g}, {c[1, 1]:g}]]")
    if asymmetric(c):
        return f"a covariance that is not symmetric (off-diagonal entries {c[0, 1]:.7g} and {c[1, 0]:.7g})"
    return None


# --------------------------------------------------------------------------------------------
# Shared per-frame data
# --------------------------------------------------------------------------------------------

def check_detections(detections, number=None) -> np.ndarray:
    """A frame's detections as an ``(N, 5)`` float array ``x, y, w, h, score`` (an empty array:
    none); else an :class:`~artmotion.errors.InputError` naming frame ``number``: another shape
    (``(N, 6)`` or MOTChallenge rows ``(N, 10)`` would be read as other boxes), NaN or infinite
    values, a box of no size."""
    d = float_array(detections, f"frame {number}: detections")
    if d.ndim != 2 or d.shape[1] != 5:
        if d.size:
            hint = " (MOTChallenge rows? take columns 2 to 6: x, y, w, h, score)" if d.shape[-1:] == (10,) else ""
            raise InputError(f"frame {number}: detections must be an (N, 5) array x, y, w, h, score, got shape "
                             f"{d.shape}{hint}")
        return d.reshape(0, 5)
    if len(d) and not (np.isfinite(d).all() and (d[:, 2:4] > 0).all()):
        bad = int(np.flatnonzero(~(np.isfinite(d).all(axis=1) & (d[:, 2:4] > 0).all(axis=1)))[0])
        x, y, w, h, s = d[bad].tolist()
        why = ("a NaN or infinite value" if not np.isfinite(d[bad]).all()
               else "a box of no size (width and height must be positive)")
        raise InputError(f"frame {number}: detections row {bad} has {why}: x={x:g} y={y:g} w={w:g} h={h:g} "
                         f"score={s:g}")
    return d


class Frame:
    """One time step as the experts see it.

    ``image`` is the BGR frame (uint8; a grey one, ``(H, W)`` or ``(H, W, 1)``, is made BGR),
    ``number`` its 1-based index, ``detections`` an ``(N, 5)`` array
    ``x, y, w, h, score``. Derived images are computed once, on demand, at ``scale`` (a
    downscaled copy keeps dense flow, KLT and background subtraction cheap); results are always
    returned in full-image pixels. ``image_scale``: the size of ``image`` relative to the full
    frame (a frame decoded at reduced size, :meth:`Sequence.frames`), whose size is
    ``width`` × ``height``.
    """

    def __init__(self, number: int, image: np.ndarray, detections=None, scale: float = 1.0,
                 shared: dict | None = None, image_scale: float = 1.0):
        if (isinstance(image, np.ndarray) and image.dtype == np.uint8 and image.size
                and (image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 1))):
            image = cv2.cvtColor(image.reshape(image.shape[:2]), cv2.COLOR_GRAY2BGR)   # (a grey camera's frames)
        if (not isinstance(image, np.ndarray) or image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8
                or not image.size):
            what = (f"{image.dtype} array of shape {image.shape}" if isinstance(image, np.ndarray)
                    else type(image).__name__)
            raise InputError(f"frame {number}: the image must be a BGR (or grey) uint8 array of shape (height, "
                             f"width, 3), got {what}")
        if not (0.0 < scale < np.inf and 0.0 < image_scale < np.inf):
            raise InputError(f"frame {number}: scale and image_scale must be positive, got {scale!r} and {image_scale!r}")
        self.number = number
        self.image: np.ndarray | None = image
        self.image_scale = float(image_scale)
        self.height, self.width = (int(round(v / self.image_scale)) for v in image.shape[:2])
        self.scale = float(scale)
        #: whether the detector ran on this frame (``detections=None``: it did not, e.g. when it
        #: runs on every k-th frame only; the tracker then predicts and counts no misses)
        self.detected = detections is not None
        self.detections = np.zeros((0, 5)) if detections is None else check_detections(detections, number)
        #: state shared across frames (background model, flow engine), owned by the tracker
        self.shared = {} if shared is None else shared
        self._cache: dict = {}

    def cached(self, key: str, fn: Callable[[], object]):
        if key not in self._cache:
            self._cache[key] = fn()
        return self._cache[key]

    def drop_image(self) -> None:
        """Forget the full-resolution image (keeps the small derived ones)."""
        self.image = None

    @property
    def small(self) -> np.ndarray:
        """Downscaled BGR image."""
        def make():
            assert self.image is not None  # the tracker drops the image only after caching ``small``
            f = self.scale / self.image_scale
            if abs(f - 1.0) < 1e-9:
                return self.image
            return cv2.resize(self.image, None, fx=f, fy=f, interpolation=cv2.INTER_AREA)
        return self.cached("small", make)

    @property
    def grey(self) -> np.ndarray:
        """Downscaled grey image."""
        return self.cached("grey", lambda: cv2.cvtColor(self.small, cv2.COLOR_BGR2GRAY))

    def to_small(self, box) -> np.ndarray:
        return np.asarray(box, dtype=float) * self.scale

    def to_full(self, box) -> np.ndarray:
        return np.asarray(box, dtype=float) / self.scale


@dataclass
class Entity:
    """What an expert knows about a tracked entity at time ``t - 1``.

    ``box`` is the entity's box on the previous frame, ``kf`` its constant-velocity Kalman filter
    on the box centre (state ``[x, vx, y, vy]``), ``centres`` its recent fused centres (for the
    acceleration estimate of Eq. 2.10), ``detection`` the detection ``[x, y, w, h, score]``
    assigned to it on the current frame (or ``None``) and ``scratch`` a place where experts may
    keep per-entity state (e.g. KLT points).
    """

    box: np.ndarray
    kf: KalmanFilter | None = None
    centres: list = field(default_factory=list)
    detection: np.ndarray | None = None
    scratch: dict = field(default_factory=dict)


# --------------------------------------------------------------------------------------------
# Registry
# --------------------------------------------------------------------------------------------

EXPERTS: dict[str, type[Expert]] = {}


class UnknownExpert(InputError, KeyError):
    """A name no expert is registered under: bad input (and, as it always was, a ``KeyError``)."""

    __str__ = BaseException.__str__     # KeyError's own would quote the message


def check_experts(names, need_det: bool = False) -> tuple[str, ...]:
    """Names of registered experts as a tuple: a string is split at its commas (``"det,klt"``);
    an unknown name, a name listed twice or (``need_det``: for a tracker) no names or no ``det``
    is an :class:`~artmotion.errors.InputError`."""
    if isinstance(names, str):
        names = [e.strip() for e in names.split(",") if e.strip()]
    try:
        names = tuple(names)
    except TypeError:
        raise InputError(f"experts must be names of experts (e.g. 'det,motion'), got {type(names).__name__}") from None
    if need_det and not names:
        raise InputError("no experts given")
    for e in names:
        if not isinstance(e, str) or e not in EXPERTS:
            raise UnknownExpert(f"unknown expert {e!r} (choose from {', '.join(sorted(EXPERTS))})")
    if len(set(names)) != len(names):
        raise InputError("an expert is listed twice")
    if need_det and "det" not in names:
        raise InputError("the 'det' expert is needed: tracks start from detections (thesis Sec. 2.5.1)")
    return names


def register_expert(cls: type[Expert]) -> type[Expert]:
    """Class decorator: make an expert available by its ``name`` to :func:`make_experts`."""
    if not getattr(cls, "name", None):
        raise ValueError("an expert needs a name")
    EXPERTS[cls.name] = cls
    return cls


def make_experts(names, **options) -> list[Expert]:
    """Instantiate experts by name (:func:`check_experts`: a string is split at its commas);
    ``options`` maps a name to keyword arguments for it."""
    return [EXPERTS[n](**options.get(n, {})) for n in check_experts(names)]


class Expert:
    """Base class: ``propose(frame, prev, entity) -> Gaussian | None``.

    ``image_based`` experts look at pixels; ``uses_detections`` marks the detector expert (the
    tracker knows that a track without it is coasting on the other experts).
    """

    name: ClassVar[str] = ""
    #: experts of one family see the same evidence (e.g. KLT and dense flow both measure the
    #: image motion), so their errors are correlated; PoTE tempers them (see ``PoTE.opinions``)
    family: ClassVar[str] = ""
    image_based: ClassVar[bool] = True
    uses_detections: ClassVar[bool] = False

    def propose(self, frame: Frame, prev: Frame | None, entity: Entity) -> Gaussian | None:
        raise NotImplementedError

    def propose_many(self, frame: Frame, prev: Frame | None, entities: list) -> list:
        """Opinions on several entities at once (experts may batch the work; default: a loop)."""
        return [self.propose(frame, prev, e) for e in entities]

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


# --------------------------------------------------------------------------------------------
# 2.4.1 Object detection
# --------------------------------------------------------------------------------------------


@register_expert
class DetectionExpert(Expert):
    """Detector expert with the indicator function of Eq. 2.4.

    A detection counts only if its score is at least ``threshold`` and it intersects the entity's
    previous box; among those the highest score wins, and it becomes a Gaussian by Eq. 2.9. When
    the tracker has already assigned a detection to the entity (one-to-one data association, the
    "additional ways of selecting a bounding box" of Sec. 2.4.1) that one is used.
    The covariance is Eq. 2.9.
    """

    name = "det"
    image_based = False
    uses_detections = True

    def __init__(self, threshold: float = 0.0):
        self.threshold = threshold

    def select(self, frame: Frame, entity: Entity) -> np.ndarray | None:
        if entity.detection is not None:
            return np.asarray(entity.detection, dtype=float)
        d = frame.detections
        if not len(d):
            return None
        ok = (d[:, 4] >= self.threshold) & (intersection(d[:, :4], entity.box[None, :]) > 0)
        if not ok.any():
            return None
        cand = d[ok]
        return cand[int(np.argmax(cand[:, 4]))]

    def propose(self, frame, prev, entity):
        det = self.select(frame, entity)
        if det is None:
            return None
        return box_gaussian(det[:4])


# --------------------------------------------------------------------------------------------
# 2.4.2 Point features (KLT)
# --------------------------------------------------------------------------------------------

_LK: dict[str, Any] = dict(winSize=(9, 9), maxLevel=2, criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.03))


def _inner(box, shrink: float) -> np.ndarray:
    x, y, w, h = box
    return np.array([x + w * shrink, y + h * shrink, w * (1 - 2 * shrink), h * (1 - 2 * shrink)])


def _roi(box, w_img: int, h_img: int) -> tuple[int, int, int, int] | None:
    x0 = int(max(0, np.floor(box[0])))
    y0 = int(max(0, np.floor(box[1])))
    x1 = int(min(w_img, np.ceil(box[0] + box[2])))
    y1 = int(min(h_img, np.ceil(box[1] + box[3])))
    if x1 - x0 < 3 or y1 - y0 < 3:
        return None
    return x0, y0, x1, y1


@register_expert
class KLTExpert(Expert):
    """KLT point features inside the box vote for its top-left corner (Eq. 2.5-2.6).

    Good features (Shi-Tomasi corners) are found inside the previous box (shrunk slightly to
    avoid the background), tracked into the current frame with pyramidal Lucas-Kanade, and
    checked forward-backward. Each feature keeps its offset to the box corner (Eq. 2.5) and votes
    for the new corner (Eq. 2.6); the weights are the normalised inverse LK residuals (better
    matched features count more; the drift bound of App. A.1 holds for any normalised weights).
    Width and height stay those of the previous box. The covariance is Eq. 2.9 plus the weighted
    spread of the votes divided by the number of votes. All entities' features of a frame go
    through one forward and one backward LK call (:meth:`propose_many`).
    """

    name = "klt"
    family = "image-motion"

    def __init__(self, max_corners: int = 24, min_points: int = 4, shrink: float = 0.15, fb_max: float = 1.0,
                 on_foreground: bool = False):
        self.on_foreground = on_foreground
        self.max_corners = max_corners
        self.min_points = min_points
        self.shrink = shrink
        self.fb_max = fb_max

    def points(self, prev: Frame, box) -> np.ndarray | None:
        g = prev.grey
        sbox = _inner(prev.to_small(box), self.shrink)
        roi = _roi(sbox, g.shape[1], g.shape[0])
        if roi is None:
            return None
        x0, y0, x1, y1 = roi
        mask = None
        if self.on_foreground and "fg" in prev._cache:
            # the entity's own pixels are the moving ones: corners on the static background
            # inside the box would vote for standing still
            m = prev._cache["fg"][y0:y1, x0:x1]
            if np.count_nonzero(m) >= 0.15 * m.size:
                mask = m
        pts = cv2.goodFeaturesToTrack(g[y0:y1, x0:x1], self.max_corners, 0.01, 2, blockSize=3, mask=mask)
        if (pts is None or len(pts) < self.min_points) and mask is not None:
            pts = cv2.goodFeaturesToTrack(g[y0:y1, x0:x1], self.max_corners, 0.01, 2, blockSize=3)
        if pts is None or len(pts) < self.min_points:
            return None
        return pts.reshape(-1, 2).astype(np.float32) + np.array([x0, y0], dtype=np.float32)

    def propose(self, frame, prev, entity):
        return self.propose_many(frame, prev, [entity])[0]

    def propose_many(self, frame, prev, entities):
        """All entities' features go through one forward and one backward LK call."""
        out = [None] * len(entities)
        if prev is None or not entities:
            return out
        pts = [self.points(prev, np.asarray(e.box, dtype=float)) for e in entities]
        idx = [i for i, p in enumerate(pts) if p is not None]
        if not idx:
            return out
        allp = np.concatenate([pts[i] for i in idx]).astype(np.float32)
        # the stubs want nextPts, which OpenCV accepts as None (no initial guess)
        p1, st, err = cv2.calcOpticalFlowPyrLK(prev.grey, frame.grey, allp.reshape(-1, 1, 2), None,  # type: ignore[call-overload]
                                               **_LK)
        if p1 is None:
            return out
        p0r, st2, _ = cv2.calcOpticalFlowPyrLK(frame.grey, prev.grey, p1, None, **_LK)  # type: ignore[call-overload]
        fb = np.linalg.norm(p0r.reshape(-1, 2) - allp, axis=1)
        good = (st.ravel() == 1) & (st2.ravel() == 1) & (fb < self.fb_max)
        p1 = p1.reshape(-1, 2)
        err = err.ravel()
        start = 0
        for i in idx:
            p = pts[i]
            assert p is not None  # ``idx``: the entities with points
            n = len(p)
            sl = slice(start, start + n)
            start += n
            g = good[sl]
            if g.sum() < self.min_points:
                continue
            out[i] = self._vote(frame, entities[i], allp[sl][g], p1[sl][g], err[sl][g])
        return out

    def _vote(self, frame, entity, p0, p1, err):
        box = np.asarray(entity.box, dtype=float)
        s = frame.scale
        corner = box[:2] * s
        G = corner[None, :] - p0                      # Eq. 2.5 (offset of the corner)
        votes = G + p1                                # Eq. 2.6 (corner voted by each feature)
        # robust: drop votes far from the median displacement
        med = np.median(votes, axis=0)
        dev = np.linalg.norm(votes - med, axis=1)
        mad = np.median(dev) + 0.5
        keep = dev <= 3.0 * mad
        if keep.sum() < self.min_points:
            return None
        votes, err = votes[keep], err[keep]
        w = 1.0 / (err + 1e-3)
        w = w / w.sum()                               # normalised weights, sum to 1
        new_corner = (w[:, None] * votes).sum(0) / s
        d = votes / s - new_corner
        spread = (w[:, None, None] * (d[:, :, None] * d[:, None, :])).sum(0) / max(len(votes), 1)
        g = box_gaussian(np.r_[new_corner, box[2:4]])
        entity.scratch["klt_points"] = int(len(votes))
        return Gaussian(g.mean, g.cov + spread)


# --------------------------------------------------------------------------------------------
# 2.4.3 Background subtraction
# --------------------------------------------------------------------------------------------


def foreground(frame: Frame, prev: Frame | None = None) -> np.ndarray:
    """The frame's foreground mask (uint8 0/255, downscaled), from the shared MOG2 model.

    The model is updated once per frame, in frame order, whoever asks first. Background
    subtraction assumes a still camera: while the tracker judges the camera to move
    (``frame.shared["camera_moving"]``) the mask is empty (no opinion) and the model is dropped,
    to be learnt afresh once the camera is still.
    """
    def make():
        if frame.shared.get("camera_moving"):
            frame.shared.pop("bg", None)
            return np.zeros(frame.small.shape[:2], np.uint8)
        bg = frame.shared.get("bg")
        if bg is None:
            bg = cv2.createBackgroundSubtractorMOG2(history=200, varThreshold=16, detectShadows=True)
            frame.shared["bg"] = bg
        small = frame.small
        # the background model runs at half the working scale (4x cheaper); blobs of people
        # survive that easily
        tiny = cv2.resize(small, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
        m = bg.apply(tiny)
        m = np.where(m == 255, 255, 0).astype(np.uint8)   # shadows (127) are background
        m = cv2.resize(m, (small.shape[1], small.shape[0]), interpolation=cv2.INTER_NEAREST)
        m = cv2.morphologyEx(m, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
        return cv2.dilate(m, np.ones((3, 3), np.uint8))
    return frame.cached("fg", make)


def foreground_fraction(frame: Frame, box) -> float:
    """Fraction of the box covered by foreground pixels."""
    m = foreground(frame)
    roi = _roi(frame.to_small(box), m.shape[1], m.shape[0])
    if roi is None:
        return 0.0
    x0, y0, x1, y1 = roi
    return float(np.count_nonzero(m[y0:y1, x0:x1])) / float((y1 - y0) * (x1 - x0))


def blobs(frame: Frame) -> np.ndarray:
    """Connected components of the foreground as ``(N, 5)`` boxes ``x, y, w, h, area`` (full px)."""
    def make():
        m = foreground(frame)
        m = m[::2, ::2]               # components of the half-resolution mask: 4x cheaper
        s = frame.scale * 0.5
        n, _, stats, _ = cv2.connectedComponentsWithStats(m, connectivity=8)
        if n <= 1:
            return np.zeros((0, 5))
        st = stats[1:].astype(float)
        out = np.empty((len(st), 5))
        out[:, :4] = st[:, :4] / s
        out[:, 4] = st[:, 4] / s ** 2
        return out
    return frame.cached("blobs", make)


@register_expert
class BlobExpert(Expert):
    """Background subtraction (MOG2) and connected components (Sec. 2.4.3).

    Blobs whose area lies between ``ar_min`` and ``ar_max`` times the entity's box area survive
    (Eq. 2.7); the one overlapping the previous box best (Eq. 2.8) is the expert's box, with the
    blob's centre; its covariance is Eq. 2.9 plus the squared discrepancy between the blob's and
    the entity's sizes (Sec. 2.7.1). No qualifying blob gives no opinion (the motion expert
    already covers a stationary entity).
    """

    name = "blob"

    def __init__(self, ar_min: float = 0.25, ar_max: float = 2.0, min_iou: float = 0.2):
        self.ar_min = ar_min
        self.ar_max = ar_max
        self.min_iou = min_iou

    def propose(self, frame, prev, entity):
        b = blobs(frame)
        if not len(b):
            return None
        box = np.asarray(entity.box, dtype=float)
        area = box_area(box)
        ok = (b[:, 4] > self.ar_min * area) & (b[:, 4] < self.ar_max * area)   # Eq. 2.7
        if not ok.any():
            return None
        cand = b[ok, :4]
        ov = iou(cand, box[None, :])                                            # Eq. 2.8
        k = int(np.argmax(ov))
        if ov[k] < self.min_iou:
            return None
        blob = cand[k]
        # a blob much wider or taller than the entity is several people or a shadow: no opinion
        if blob[2] > 1.6 * box[2] or blob[3] > 1.6 * box[3]:
            return None
        # Sec. 2.7.1: an expert's variance grows with the discrepancy of its box from the entity's
        g = box_gaussian(blob)
        return Gaussian(g.mean, g.cov + np.diag((blob[2:4] - box[2:4]) ** 2))


# --------------------------------------------------------------------------------------------
# 2.4.4 Motion continuity
# --------------------------------------------------------------------------------------------


def acceleration_variance(centres, dt: float, floor) -> np.ndarray:
    """Per-axis variance of the acceleration from second finite differences (Eq. 2.10's Σ_a)."""
    floor = np.broadcast_to(np.asarray(floor, dtype=float), (2,))
    c = np.asarray(centres, dtype=float).reshape(-1, 2)
    if len(c) < 4:
        return floor.copy()
    a = (c[2:] - 2 * c[1:-1] + c[:-2]) / dt ** 2
    return np.maximum(np.mean(a ** 2, axis=0), floor)


def new_motion_filter(centre, size, dt: float, pos_std: float | None = None) -> KalmanFilter:
    """A constant-velocity Kalman filter (Eq. 2.10) at ``centre`` with zero velocity."""
    F, Q, H = constant_velocity(dt, 1.0, dims=2)
    w, h = size
    x = np.array([centre[0], 0.0, centre[1], 0.0])
    vstd = 0.5 * h  # up to ~a body height per second, unknown direction
    P = np.diag([w / 6.0, vstd ** 2, h / 6.0, vstd ** 2])
    return KalmanFilter(x, P, F, Q, H, np.diag([w / 6.0, h / 6.0]))


@register_expert
class MotionExpert(Expert):
    """Constant-velocity motion model (Eq. 2.10) as an expert.

    The acceleration noise ``Σ_a`` is the mean squared second finite difference of the fused
    centres over the last ``window`` seconds, floored at ``accel_floor`` box heights per s².
    The expert's Gaussian is the Kalman prediction ``N(H x, H P Hᵀ)``; it predicts on a copy, so
    the tracker decides when to commit (``predict_entity``).
    """

    name = "motion"
    image_based = False

    def __init__(self, window: float = 1.0, accel_floor: float = 0.5):
        self.window = window
        self.accel_floor = accel_floor

    def process_noise(self, entity: Entity) -> np.ndarray:
        """``Q`` of Eq. 2.10 (``B Σ_a Bᵀ`` per axis) with ``Σ_a`` from finite differences."""
        kf = entity.kf
        assert kf is not None  # only entities with a Kalman filter are predicted (``propose`` checks)
        dt = kf.F[0, 1]
        n = max(4, int(round(self.window / dt)) + 2)
        h = entity.box[3]
        var = acceleration_variance(entity.centres[-n:], dt, (self.accel_floor * h) ** 2)
        # same as artmotion.filters.constant_velocity(dt, var)[1], without the generic machinery
        b = np.array([0.5 * dt * dt, dt])
        bb = np.outer(b, b)
        Q = np.zeros((4, 4))
        Q[:2, :2] = bb * var[0]
        Q[2:, 2:] = bb * var[1]
        return Q

    def predict_entity(self, entity: Entity) -> Gaussian:
        kf = entity.kf
        assert kf is not None  # only entities with a Kalman filter are predicted (``propose`` checks)
        kf.predict(Q=self.process_noise(entity))
        return Gaussian(kf.H @ kf.x, kf.H @ kf.P @ kf.H.T)

    def propose(self, frame, prev, entity):
        if entity.kf is None:
            return None
        kf = entity.kf
        F = kf.F
        Q = self.process_noise(entity)
        x = F @ kf.x
        P = F @ kf.P @ F.T + Q
        return Gaussian(kf.H @ x, kf.H @ P @ kf.H.T)


# --------------------------------------------------------------------------------------------
# 2.4.5 Dense optical flow
# --------------------------------------------------------------------------------------------


def dense_flow(frame: Frame, prev: Frame) -> np.ndarray:
    """Dense optical flow prev -> frame (DIS, downscaled; in small-image pixels), cached."""
    def make():
        dis = frame.shared.get("dis")
        if dis is None:
            # the stubs lack OpenCV's module-level alias of DISOpticalFlow.create
            dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST)  # type: ignore[attr-defined]
            frame.shared["dis"] = dis
        return dis.calc(prev.grey, frame.grey, None)
    return frame.cached(f"flow{prev.number}", make)


@register_expert
class FlowExpert(Expert):
    """Mean dense optical flow (DIS) of the pixels in the box moves the box (Sec. 2.4.5).

    The mean is taken over the foreground pixels (background subtraction) of the inner part of
    the box, leaving out vectors beyond two standard deviations. Covariance: Eq. 2.9 plus the
    variance of the mean flow.
    """

    name = "flow"
    family = "image-motion"

    def __init__(self, shrink: float = 0.15):
        self.shrink = shrink

    def propose(self, frame, prev, entity):
        if prev is None:
            return None
        flow = dense_flow(frame, prev)
        box = np.asarray(entity.box, dtype=float)
        roi = _roi(_inner(frame.to_small(box), self.shrink), flow.shape[1], flow.shape[0])
        if roi is None:
            return None
        x0, y0, x1, y1 = roi
        f = flow[y0:y1:2, x0:x1:2].reshape(-1, 2)     # every other pixel is plenty for a mean
        if len(f) < 4:
            return None
        # the entity's pixels are the foreground ones (background subtraction); the static
        # background inside the box would otherwise pull the mean towards zero
        fg = foreground(prev)[y0:y1:2, x0:x1:2].reshape(-1) > 0
        if fg.sum() >= max(4, 0.1 * len(f)):
            f = f[fg]
        # one robust pass: drop vectors beyond two standard deviations of the mean
        d = ((f - f.mean(axis=0)) ** 2).sum(axis=1)
        f = f[d <= 4.0 * d.mean() + 1e-6]
        m = f.mean(axis=0) / frame.scale
        var = f.var(axis=0) / frame.scale ** 2 / len(f)
        g = box_gaussian(np.r_[box[:2] + m, box[2:4]])
        return Gaussian(g.mean, g.cov + np.diag(var))


def detections_support(frame: Frame, dets: np.ndarray) -> np.ndarray:
    """Foreground fraction of each detection box (background-motion support)."""
    return np.array([foreground_fraction(frame, d[:4]) for d in check_detections(dets, frame.number)])
