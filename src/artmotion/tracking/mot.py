"""Multiple object tracking with group nodes (thesis Sec. 2.5).

Online pass (:class:`MultiObjectTracker`, one frame at a time):

* every live track is predicted by the image experts and the motion expert (PoTE, Eq. 2.3);
* detections are assigned one-to-one to the predicted boxes (high scores first, then low scores
  — the indicator of Eq. 2.4 with a global assignment); an assigned detection joins the product
  as the detector expert; a track without one *coasts* on the other experts, which bridges
  missed detections;
* tracks start from high-score detections (low-score ones only with background-motion support)
  and stay *tentative* until confirmed by further detections;
* two tracks overlapping (Eq. 2.11) while one of them loses its detection merge into a group
  node spanning its members (Eq. 2.12-2.13); members keep being predicted by their motion model;
  the group splits when as many detections intersect it as it has members, and identities are
  resolved by the KL divergence of RGB histograms (Sec. 2.5.2);
* a newly confirmed track is back-tracked with the image experts into the frames before its
  first detection (Fig. 2.9), from a short buffer of past frames.

Offline pass (:meth:`MultiObjectTracker.finish`): constant-velocity interpolation of the members'
trajectories inside each group (Sec. 2.5.3), the tentative beginnings of confirmed tracks,
back-tracked beginnings, coasted gaps (with the drift found at re-acquisition spread back over
them), stitching of tracklets that motion and appearance join across a gap, optionally
coasted tails up to the exit decided by the motion and histogram cues (Sec. 2.5.4), removal of
short tracks that appear and vanish inside the image, and smoothing of the output boxes (track-level
sizes, centres from a local straight-line fit). Events: enter/exit (none for people present at
the sequence's start/end) and merge/split with hysteresis (:func:`collapse_group_flicker`).
``online=True`` keeps only what was known at each frame. See docs/tracking.md.
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from artmotion.geometry import box_center, box_from_center, clip_box, iou, iou_matrix, overlap_ratio, union_box
from artmotion.tracking.appearance import kl_divergence, rgb_histogram
from artmotion.tracking.experts import (
    Entity,
    Frame,
    Gaussian,
    MotionExpert,
    detections_support,
    foreground,
    foreground_fraction,
    new_motion_filter,
)
from artmotion.tracking.pote import PoTE, fuse

#: origin of an output box: a detection-supported frame, a frame coasted on the image experts,
#: a group member, tentative beginning, back-tracked frame
KINDS = ("det", "coast", "group", "tentative", "back", "interp")

__all__ = ["Group", "MultiObjectTracker", "Track", "TrackerConfig", "collapse_group_flicker", "side_of"]


@dataclass
class TrackerConfig:
    """Settings (the same for every sequence; times are in seconds, sizes relative to boxes)."""

    high: float = 0.9          #: detection score that starts a track (Sec. 2.4.1's tau_thresh)
    low: float = 0.5           #: lowest detection score used at all
    low_fg: float = 0.25       #: foreground fraction a low-score detection needs to start a track
    match_iou: float = 0.3     #: IoU gate between a predicted box and a detection
    coast_match_iou: float = 0.3  #: the same for a coasting track
    birth_iou: float = 0.3     #: no new track on a detection overlapping a live track this much
    confirm_hits: int = 4      #: detections needed to confirm a tentative track
    tentative_misses: int = 1  #: misses a tentative track survives
    max_hold: float = 10.0     #: ... or up to this long while it is seen standing (Sec. 2.5.4)
    stay_speed: float = 0.2    #: box heights per second below which an entity counts as standing
    stay_kl: float = 0.5       #: KL divergence within which a standing entity is still seen
    max_coast: float = 1.5     #: seconds a track coasts on the image experts without detections
    size_window: float = 0.0   #: seconds of detections whose median size is the box size (0: EMA)
    size_alpha: float = 0.5    #: smoothing of width/height towards assigned detections
    merge_iou: float = 0.3     #: Eq. 2.11 overlap that detects an occlusion
    join_ratio: float = 0.5    #: Eq. 2.12 share of a track inside a group that makes it join
    split_ratio: float = 0.5   #: share of a detection inside a group for it to count for a split
    partial_split: bool = False  #: members may leave a group one by one (Fig. 2.4)
    max_group: float = 3.0     #: seconds a group may last before its members are released
    split_motion: float = 1.0  #: weight of (1 - IoU with the member's prediction) next to KL
    backtrack: float = 1.0     #: seconds a new track may be followed back in time
    back_kl: float = 0.5       #: back-tracking stops where the box's histogram departs this far
    exit_kl: float = 1.0       #: KL divergence at which a coasted box no longer shows the entity
    tail: float = 0.0          #: seconds of coasted tail kept (until an exit is decided)
    min_fg_static: float = 0.08  #: a track this static in the foreground and not moving is dropped
    occlusion_guard: bool = True  #: a coasting track overlapping another is occluded, not gone
    kill_on_exit: bool = True  #: end a coasting track when the exit test fires ...
    exit_votes: int = 2        #: ... on this many consecutive frames
    online_coast: float = 0.3  #: seconds an online result keeps reporting a coasting track
    app_weight: float = 0.1    #: weight of the histograms' KL divergence next to IoU in association
    max_gap: float = 3.0       #: seconds across which tracklets may be stitched offline
    stitch_dist: float = 0.5   #: stitching tolerance: box heights, plus ...
    stitch_speed: float = 0.5  #: ... box heights per second of gap
    stitch_kl: float = 1.5     #: largest KL divergence of the histograms of stitched tracklets
    out_size: float = 1.0      #: offline: a box's size is the median of the track's detection-supported sizes within +- this many seconds
    out_smooth: float = 0.5    #: offline: a box's centre is a local linear fit of the track's centres within +- this many seconds
    min_life: float = 0.5      #: offline: a track shorter than this that appears and vanishes inside the image is dropped
    split_hold: float = 0.3    #: seconds a split must hold; a re-merge of the members within it continues the group


@dataclass
class Track:
    id: int
    entity: Entity
    size: np.ndarray
    first: int
    state: str = "tentative"          # tentative, confirmed, dead
    hits: int = 1
    misses: int = 0
    last_det: int = 0
    hist: np.ndarray | None = None
    hist_frame: "Frame | None" = None   # frame (small image) of the last clean detection
    hist_box: np.ndarray | None = None
    group: "Group | None" = None
    confirmed_at: int | None = None
    boxes: dict = field(default_factory=dict)   # frame -> (box, kind, score)
    back: dict = field(default_factory=dict)    # frame -> box (back-tracked)
    exit_at: int | None = None        # first coasted frame judged as the entity gone
    fg: list = field(default_factory=list)
    hold: int = 0                     # coasted frames where the entity was seen to stay
    gone: int = 0                     # consecutive coasted frames judged as exit
    pred: dict = field(default_factory=dict)   # frame -> centre predicted before a re-acquisition
    sizes: list = field(default_factory=list)  # recent detection sizes

    @property
    def box(self) -> np.ndarray:
        return self.entity.box

    def set_box(self, frame: int, box, kind: str, score: float = 1.0) -> None:
        box = np.asarray(box, dtype=float)
        self.entity.box = box
        self.boxes[frame] = (box.copy(), kind, float(score))


@dataclass
class Group:
    id: int
    members: list
    start: int
    box: np.ndarray


def _detection_hist(frame: Frame, j: int) -> np.ndarray | None:
    """RGB histogram of ``frame.detections[j]``, computed once per frame (association, update, split)."""
    return frame.cached(f"det_hist{j}", lambda: rgb_histogram(frame.small, frame.detections[j, :4], frame.scale))


def side_of(box, width: int, height: int, margin: float = 0.3) -> str:
    """Where a box touches the image: ``left``/``right``/``top``/``bottom`` or ``inside``.

    A side counts when the box is within ``margin`` of its own width (height) from it.
    """
    x, y, w, h = box
    d = {"left": x / w, "right": (width - (x + w)) / w, "top": y / h, "bottom": (height - (y + h)) / h}
    k = min(d, key=d.get)
    return k if d[k] <= margin else "inside"


class MultiObjectTracker:
    """The online tracker; :meth:`step` per frame, then :meth:`finish` for the result."""

    def __init__(self, fps: float, width: int, height: int, experts=("det", "klt", "blob", "motion", "flow"),
                 config: TrackerConfig | None = None, online: bool = False):
        self.cfg = config or TrackerConfig()
        self.fps = float(fps) if fps and fps > 0 else 25.0
        self.dt = 1.0 / self.fps
        self.width, self.height = int(width), int(height)
        self.online = online
        self.pote = PoTE(list(experts))
        self.motion: MotionExpert = next((e for e in self.pote.experts if isinstance(e, MotionExpert)), None)
        self.use_motion = self.motion is not None
        if self.motion is None:
            self.motion = MotionExpert()
        self.tracks: list[Track] = []
        self.all_tracks: list[Track] = []
        self.groups: list[Group] = []
        self.next_id = 1
        self.next_group = 1
        self.prev: Frame | None = None
        n_buf = max(3, int(round(self.cfg.backtrack * self.fps))) + 1
        self.buffer: collections.deque = collections.deque(maxlen=n_buf)
        self.last_frame = 0
        self.first_frame: int | None = None
        self.online_rows: list = []
        self.relabel: dict[int, int] = {}
        self.group_log: dict[int, dict[int, tuple]] = {}   # frame -> {group id: member track ids}
        self.piece_span: dict[int, tuple[int, int]] = {}    # track id -> frames it gives the output

    # ------------------------------------------------------------------ helpers
    def _frames(self, seconds: float) -> int:
        return max(1, int(round(seconds * self.fps)))

    def _new_track(self, frame: Frame, det: np.ndarray) -> Track:
        box = det[:4].copy()
        c = box_center(box)
        ent = Entity(box=box, kf=new_motion_filter(c, box[2:4], self.dt), centres=[c])
        t = Track(self.next_id, ent, box[2:4].copy(), frame.number, last_det=frame.number)
        t.sizes.append(box[2:4].copy())
        self.next_id += 1
        t.set_box(frame.number, box, "det", det[4])
        self._update_hist(t, frame, box, rgb_histogram(frame.small, box, frame.scale))
        t.fg.append(foreground_fraction(frame, box))
        self.tracks.append(t)
        self.all_tracks.append(t)
        return t

    def _update_hist(self, t: Track, frame: Frame, box, h: np.ndarray | None) -> None:
        """Blend ``h``, the RGB histogram of ``box`` on ``frame``, into the track's appearance."""
        if h is None:
            return
        t.hist = h if t.hist is None else 0.7 * t.hist + 0.3 * h
        t.hist_frame = frame
        t.hist_box = np.asarray(box, dtype=float).copy()

    def _commit(self, t: Track, frame: Frame, meas: Gaussian | None) -> np.ndarray:
        """Kalman step of the motion expert with the other experts' product as measurement.

        With the motion prior as one more expert this is exactly Eq. 2.3 for the centre.
        Returns the fused centre.
        """
        Q = self.motion.process_noise(t.entity)
        kf = t.entity.kf
        kf.predict(Q=Q if self.use_motion else Q * 1e6)
        if meas is not None:
            kf.update(meas.mean, R=meas.cov)
        c = kf.H @ kf.x
        t.entity.centres.append(c.copy())
        if len(t.entity.centres) > 64:
            del t.entity.centres[:-64]
        return c

    # ------------------------------------------------------------------ main step
    def step(self, frame: Frame) -> None:
        cfg = self.cfg
        n = frame.number
        self.last_frame = n
        if self.first_frame is None:
            self.first_frame = n
        dets = frame.detections
        dets = dets[dets[:, 4] >= cfg.low] if len(dets) else dets
        frame.detections = dets
        foreground(frame)            # the background model sees every frame, in order
        live = [t for t in self.tracks if t.state != "dead"]
        singles = [t for t in live if t.group is None]

        # 1. prediction of single tracks by image experts + motion (PoTE without detector)
        preds = {}
        for t in singles:
            t.entity.detection = None
        batch = self.pote.estimate_many(frame, self.prev, [t.entity for t in singles], skip={"det", "motion"})
        for t, (img, ops) in zip(singles, batch):
            prior = self.motion.propose(frame, self.prev, t.entity) if self.use_motion else None
            g = fuse([img, prior])
            c = g.mean if g is not None else box_center(t.box)
            preds[t.id] = (img, box_from_center(c, t.size), ops)

        # 2. association: high-score detections first, then low ones (Eq. 2.4 + one-to-one)
        used = np.zeros(len(dets), bool)
        matched: dict[int, int] = {}
        order = sorted(singles, key=lambda t: (t.state != "confirmed", t.misses))
        for lo, hi in ((cfg.high, np.inf), (cfg.low, cfg.high)):
            cand = np.where((~used) & (dets[:, 4] >= lo) & (dets[:, 4] < hi))[0] if len(dets) else []
            tr = [t for t in order if t.id not in matched]
            if not len(cand) or not tr:
                continue
            P = np.array([preds[t.id][1] for t in tr])
            M = iou_matrix(P, dets[cand, :4])
            gate = np.array([cfg.match_iou if t.misses == 0 else cfg.coast_match_iou for t in tr])
            if hi < np.inf:   # low-score detections: only for tracks that are not coasting
                gate = np.where([t.misses == 0 for t in tr], gate, np.inf)
            # IoU with the predicted box (the overlap condition of Eq. 2.4) plus appearance
            cost = -M
            if cfg.app_weight > 0:
                dh = [_detection_hist(frame, j) for j in cand]
                K = np.array([[min(kl_divergence(t.hist, h), 3.0) for h in dh] for t in tr])
                cost = cost + cfg.app_weight * K
                # a coasting track is only re-acquired by a detection that looks like it
                coasting = np.array([t.misses > 0 for t in tr])
                cost = np.where(coasting[:, None] & (K > cfg.exit_kl), 10.0, cost)
            cost = np.where(M >= gate[:, None], cost, 10.0)
            r, c = linear_sum_assignment(cost)
            for i, j in zip(r, c):
                if cost[i, j] < 10.0:
                    matched[tr[i].id] = cand[j]
                    used[cand[j]] = True

        # 3. update matched tracks (detector joins the product) and coast the others
        for t in singles:
            img, pbox, ops = preds[t.id]
            if t.id in matched:
                d = dets[matched[t.id]]
                t.entity.detection = d
                t.pred[n] = box_center(pbox)
                if d[4] >= cfg.high:
                    self.pote.observe(ops, box_center(d[:4]), d[2:4])
                det_g = self.pote.opinions(frame, self.prev, t.entity, skip=set(self.pote.names) - {"det"})
                meas = fuse([img, *det_g.values()])
                c = self._commit(t, frame, meas)
                t.sizes.append(d[2:4].copy())
                if cfg.size_window > 0:
                    # robust size: median of the recent detections (a box spanning two people or
                    # a cut-off one does not distort it)
                    k = max(3, self._frames(cfg.size_window))
                    del t.sizes[:-k]
                    t.size = np.median(np.array(t.sizes), axis=0)
                else:
                    t.size = (1 - cfg.size_alpha) * t.size + cfg.size_alpha * d[2:4]
                box = box_from_center(c, t.size)
                t.hits += 1
                t.misses = 0
                t.last_det = n
                t.set_box(n, box, "det", d[4])
                others = [o.box for o in singles if o is not t]
                if not others or iou_matrix(d[None, :4], np.array(others)).max() < 0.1:   # a clean view
                    self._update_hist(t, frame, d[:4], _detection_hist(frame, matched[t.id]))
                t.exit_at = None
                t.gone = 0
                t.hold = 0
                if t.state == "tentative" and t.hits >= cfg.confirm_hits:
                    t.state = "confirmed"
                    t.confirmed_at = n
                    if not self.online:
                        self._backtrack(t)
            else:
                c = self._commit(t, frame, img)
                box = box_from_center(c, t.size)
                t.misses += 1
                t.set_box(n, box, "coast", 0.0)
                t.entity.detection = None
                limit = cfg.tentative_misses if t.state == "tentative" else self._frames(cfg.max_coast)
                if t.state == "confirmed" and self._stays(t, frame, box):
                    t.hold += 1     # a standing, undetected person: the image still shows it
                if t.misses - t.hold > limit or t.misses > self._frames(cfg.max_hold) or self._outside(box):
                    self._kill(t)
                elif not (cfg.occlusion_guard and self._occluded(t, singles)) and self._gone(t, frame, box):
                    if t.exit_at is None:
                        t.exit_at = n
                    t.gone += 1
                    if cfg.kill_on_exit and t.gone >= cfg.exit_votes:
                        self._kill(t)
                else:
                    t.gone = 0
            t.fg.append(foreground_fraction(frame, t.box))

        # 4. groups: members predicted by motion; split when enough detections intersect
        self._step_groups(frame, dets, used)

        # 5. occlusion detection: overlapping confirmed tracks where one lost its detection
        self._merge(frame, matched)

        # 6. births from unassigned detections
        self._births(frame, dets, used)

        if self.groups:
            self.group_log[n] = {g.id: tuple(m.id for m in g.members) for g in self.groups}
        if self.online:
            self._online_rows(n)
        frame.small, frame.grey    # keep the small images for back-tracking and histograms
        frame.drop_image()
        self.buffer.append(frame)
        self.prev = frame

    # ------------------------------------------------------------------ pieces
    def _outside(self, box) -> bool:
        inside = overlap_ratio(np.asarray(box), np.array([0.0, 0.0, self.width, self.height]))
        return inside < 0.5

    def _stays(self, t: Track, frame: Frame, box) -> bool:
        """Motion and appearance cues (Sec. 2.5.4) agree that a coasting entity is still there.

        The entity is (nearly) stationary, so the detector's silence is no sign of an exit, and
        its box still looks like it (KL divergence of the RGB histograms below ``stay_kl``).
        """
        v = np.hypot(t.entity.kf.x[1], t.entity.kf.x[3])
        if v > self.cfg.stay_speed * t.size[1] or t.hist is None:
            return False
        return kl_divergence(t.hist, rgb_histogram(frame.small, box, frame.scale)) <= self.cfg.stay_kl

    def _occluded(self, t: Track, others: list) -> bool:
        """A coasting track overlapping another (Eq. 2.11) is occluded, not gone: it joins a group."""
        if t.state != "confirmed":
            return False
        boxes = [o.box for o in others if o is not t and o.state == "confirmed"]
        if not boxes:
            return False
        return float(iou_matrix(t.box[None, :], np.array(boxes)).max()) >= self.cfg.merge_iou

    def _gone(self, t: Track, frame: Frame, box) -> bool:
        """Entry/exit test of Sec. 2.5.4 for a coasting track (appearance confirms the motion cue)."""
        if t.hist is None or t.hist_frame is None:
            return False
        h_now = rgb_histogram(frame.small, box, frame.scale)
        score2 = kl_divergence(t.hist, h_now)
        if not math.isfinite(score2):
            return True
        if score2 > self.cfg.exit_kl:
            return True
        # motion cue: near-stationary or at the border are exit candidates
        v = np.array([t.entity.kf.x[1], t.entity.kf.x[3]]) * self.dt
        border = side_of(box, self.width, self.height) != "inside"
        if np.hypot(*v) > 0.05 * t.size[1] and not border:
            return False
        hf = t.hist_frame
        score1 = kl_divergence(t.hist, rgb_histogram(hf.small, box, hf.scale))
        score3 = kl_divergence(rgb_histogram(frame.small, t.hist_box, frame.scale), h_now)
        return score2 > score1 and score2 > score3

    def _kill(self, t: Track) -> None:
        t.state = "dead"
        t.hist_frame = None   # let the frame go
        if t.group is not None:
            t.group.members.remove(t)
            t.group = None
        self.tracks.remove(t)

    def _births(self, frame: Frame, dets: np.ndarray, used: np.ndarray) -> None:
        cfg = self.cfg
        if not len(dets):
            return
        live_boxes = [t.box for t in self.tracks]
        group_boxes = [g.box for g in self.groups]
        free = np.where(~used)[0]
        if not len(free):
            return
        for j in free[np.argsort(-dets[free, 4])]:
            d = dets[j]
            if d[4] < cfg.high:
                if frame.number <= 2:
                    continue   # background model not yet meaningful
                if detections_support(frame, d[None])[0] < cfg.low_fg:
                    continue
            if live_boxes and iou_matrix(d[None, :4], np.array(live_boxes)).max() >= cfg.birth_iou:
                continue
            if group_boxes and overlap_ratio(d[:4][None], np.array(group_boxes)).max() >= cfg.split_ratio:
                continue
            t = self._new_track(frame, d)
            used[j] = True
            live_boxes.append(t.box)

    def _merge(self, frame: Frame, matched: dict) -> None:
        cfg = self.cfg
        n = frame.number
        conf = [t for t in self.tracks if t.state == "confirmed"]
        # join existing groups (Eq. 2.12)
        for g in self.groups:
            for t in conf:
                if t.group is None and t.id not in matched and overlap_ratio(t.box, g.box) >= cfg.join_ratio:
                    t.group = g
                    g.members.append(t)
                    g.box = union_box([m.box for m in g.members])
        singles = [t for t in conf if t.group is None]
        if len(singles) < 2:
            return
        pascal = iou_matrix(np.array([t.box for t in singles]), np.array([t.box for t in singles]))  # Eq. 2.11
        for i, a in enumerate(singles):
            for k in range(i + 1, len(singles)):
                b = singles[k]
                if pascal[i, k] < cfg.merge_iou:
                    continue
                if a.group is not None or b.group is not None:
                    continue
                if a.id in matched and b.id in matched:
                    continue
                g = Group(self.next_group, [a, b], n, union_box([a.box, b.box]))
                self.next_group += 1
                a.group = b.group = g
                self.groups.append(g)
                for m in g.members:
                    if m.boxes[n][1] != "det":
                        m.boxes[n] = (m.box.copy(), "group", 0.0)

    def _step_groups(self, frame: Frame, dets: np.ndarray, used: np.ndarray) -> None:
        cfg = self.cfg
        n = frame.number
        for g in list(self.groups):
            if len(g.members) < 2:
                self._release(g)
                continue
            # members keep being predicted by their motion model (Eq. 2.10), group spans them (2.13)
            for m in g.members:
                if m.boxes.get(n, (None, ""))[1] == "group":
                    continue
                c = self._commit(m, frame, None)
                m.misses += 1
                m.set_box(n, box_from_center(c, m.size), "group", 0.0)
            inside = []
            if len(dets):
                free = np.where(~used)[0]
                if len(free):
                    r = overlap_ratio(dets[free, :4], g.box[None, :])
                    inside = list(free[r >= cfg.split_ratio])
            member_boxes = [m.box for m in g.members]
            g.box = union_box(member_boxes + [dets[j, :4] for j in inside])
            for j in inside:
                used[j] = True     # absorbed by the group: no new track inside it
            if len(inside) >= len(g.members):
                self._split(g, frame, dets, inside)
                continue
            if cfg.partial_split:
                self._partial_split(g, frame, dets, used)
                if len(g.members) < 2:
                    self._release(g)
                    continue
            if n - g.start > self._frames(cfg.max_group) or self._members_apart(g):
                self._release(g)

    def _partial_split(self, g: Group, frame: Frame, dets: np.ndarray, used: np.ndarray) -> None:
        """A member leaves the group with a detection that is unambiguously its own (Fig. 2.4).

        The detection overlaps that member's prediction (IoU at least ``match_iou``), no other
        member's, and looks like it (KL divergence of histograms within ``exit_kl``).
        """
        cfg = self.cfg
        if not len(dets):
            return
        near = np.where(overlap_ratio(dets[:, :4], g.box[None, :]) > 0)[0]
        for j in sorted(near, key=lambda j: -dets[j, 4]):
            if len(g.members) < 2:
                break
            ious = np.array([float(iou(m.box, dets[j, :4])) for m in g.members])
            k = int(np.argmax(ious))
            if ious[k] < cfg.match_iou or np.sort(ious)[-2] >= 0.5 * cfg.match_iou:
                continue
            m = g.members[k]
            if not kl_divergence(m.hist, _detection_hist(frame, j)) <= cfg.exit_kl:
                continue
            g.members.remove(m)
            self._assign_member(m, dets[j], frame.number)
            used[j] = True
            g.box = union_box([o.box for o in g.members])

    def _members_apart(self, g: Group) -> bool:
        boxes = np.array([m.box for m in g.members])
        M = iou_matrix(boxes, boxes)
        np.fill_diagonal(M, 0)
        return M.max() <= 0.0

    def _split(self, g: Group, frame: Frame, dets: np.ndarray, inside: list) -> None:
        """Resolve identities by KL divergence of RGB histograms (counts match), Sec. 2.5.2."""
        cfg = self.cfg
        n = frame.number
        inside = sorted(inside, key=lambda j: -dets[j, 4])
        members = list(g.members)
        C = np.zeros((len(members), len(inside)))
        for i, m in enumerate(members):
            for k, j in enumerate(inside):
                kl = kl_divergence(m.hist, _detection_hist(frame, j))
                C[i, k] = (kl if math.isfinite(kl) else 10.0) + cfg.split_motion * (1 - float(iou(m.box, dets[j, :4])))
        r, c = linear_sum_assignment(C)
        for i, k in zip(r, c):
            self._assign_member(members[i], dets[inside[k]], n)
        for m in members:
            m.group = None
        self.groups.remove(g)

    def _assign_member(self, m: Track, d: np.ndarray, n: int) -> None:
        """A member leaving its group takes detection ``d``; its motion restarts from there."""
        m.entity.kf = new_motion_filter(box_center(d[:4]), d[2:4], self.dt)
        self._carry_velocity(m, d)
        m.size = 0.5 * m.size + 0.5 * d[2:4]
        m.set_box(n, box_from_center(box_center(d[:4]), m.size), "det", d[4])
        m.entity.centres = [box_center(d[:4])]
        m.misses = 0
        m.hold = 0
        m.gone = 0
        m.hits += 1
        m.last_det = n
        m.group = None

    def _carry_velocity(self, m: Track, d) -> None:
        """After a split, the member's velocity is its mean velocity across the occlusion."""
        past = [f for f, (_, kind, _) in m.boxes.items() if kind == "det"]
        if not past:
            return
        f0 = max(past)
        span = self.last_frame - f0
        if span <= 0:
            return
        v = (box_center(d[:4]) - box_center(m.boxes[f0][0])) / (span * self.dt)
        m.entity.kf.x[1], m.entity.kf.x[3] = v

    def _release(self, g: Group) -> None:
        for m in g.members:
            m.group = None
        self.groups.remove(g)

    # ------------------------------------------------------------------ back-tracking (Fig. 2.9)
    def _backtrack(self, t: Track) -> None:
        """Follow a newly confirmed track back in time with the image experts."""
        first = min(t.boxes)
        frames = {f.number: f for f in self.buffer}
        if first - 1 not in frames or first <= 1:
            return
        box = t.boxes[first][0].copy()
        ent = Entity(box=box, kf=None, centres=[])
        skip = {"det", "motion", "blob"}
        others = [o for o in self.all_tracks if o is not t]
        for f in range(first - 1, max(0, first - len(self.buffer)), -1):
            cur, nxt = frames.get(f), frames.get(f + 1)
            if cur is None or nxt is None:
                break
            ent.box = box
            g, ops = self.pote.estimate(cur, nxt, ent, skip=skip)
            if g is None:
                break
            box = box_from_center(g.mean, t.size)
            if self._outside(box):
                break
            h = rgb_histogram(cur.small, box, cur.scale)
            if kl_divergence(t.hist, h) > self.cfg.back_kl:
                break
            # an undetected person is still there only if the background model sees it
            if foreground_fraction(cur, box) < self.cfg.low_fg:
                break
            if any(f in o.boxes and iou(o.boxes[f][0], box) > 0.3 for o in others):
                break
            t.back[f] = box.copy()

    # ------------------------------------------------------------------ output
    def _online_rows(self, n: int) -> None:
        lim = self._frames(self.cfg.online_coast)
        for t in self.tracks:
            if t.state != "confirmed" or n not in t.boxes:
                continue
            box, kind, score = t.boxes[n]
            if kind in ("coast", "group") and t.misses > lim:
                continue   # online, an unseen entity is reported only briefly
            self.online_rows.append([n, t.id, *box, score if kind == "det" else 0.5, KINDS.index(kind)])

    def finish(self, length: int | None = None) -> tuple[np.ndarray, list[dict]]:
        """Close the sequence; return ``(rows, events)`` (rows: N x 10 MOT array, ids renumbered)."""
        length = length or self.last_frame
        if self.online:
            rows = np.array(self.online_rows, dtype=float).reshape(-1, 8)
            keep_ids = {t.id for t in self.all_tracks if t.state in ("confirmed", "dead")}
        else:
            rows, keep_ids = self._offline_rows()
        return self._finalise(rows, keep_ids, length)

    def _offline_rows(self):
        cfg = self.cfg
        tail = self._frames(cfg.tail)
        pieces = {}   # id -> {frame: [box, kind, score]}
        for t in self.all_tracks:
            if t.state not in ("confirmed", "dead") or t.confirmed_at is None:
                continue
            if self._static_false(t):
                continue
            frames = sorted(t.boxes)
            det_frames = [f for f in frames if t.boxes[f][1] == "det"]
            last_det = max(det_frames)
            rec = {}
            for f in frames:
                if f > last_det:
                    break
                box, kind, score = t.boxes[f]
                if kind == "det" and f < t.confirmed_at:
                    kind = "tentative"
                rec[f] = [box, kind, score]
            # 2.5.3: constant-velocity interpolation of group segments
            fs = det_frames
            for a, b in zip(fs[:-1], fs[1:]):
                if b - a > 1 and any(rec[f][1] == "group" for f in range(a + 1, b) if f in rec):
                    self._interpolate(rec, a, b, "group")
            # coasted gaps: the drift found at re-acquisition is spread back over the gap
            for a, b in zip(fs[:-1], fs[1:]):
                if b - a > 1 and b in t.pred and all(rec.get(f, [0, ""])[1] == "coast" for f in range(a + 1, b)):
                    drift = box_center(rec[b][0]) - t.pred[b]
                    for f in range(a + 1, b):
                        u = (f - a) / (b - a)
                        bx = rec[f][0]
                        rec[f] = [box_from_center(box_center(bx) + u * drift, bx[2:4]), "coast", 0.0]
            # 2.5.4: coasted tail until the exit
            for f in frames:
                if f <= last_det or t.boxes[f][1] != "coast":
                    continue
                if f - last_det > tail or (t.exit_at is not None and f >= t.exit_at):
                    break
                rec[f] = [t.boxes[f][0], "coast", 0.0]
            # Fig. 2.9: back-tracked beginning
            for f, bx in t.back.items():
                rec.setdefault(f, [bx, "back", 0.0])
            pieces[t.id] = rec
        self.piece_span = {i: (min(rec), max(rec)) for i, rec in pieces.items() if rec}
        pieces = self._stitch(pieces)
        pieces = {i: rec for i, rec in pieces.items() if not self._flash(rec)}
        if cfg.out_size > 0:
            for rec in pieces.values():
                self._smooth_sizes(rec, self._frames(cfg.out_size))
        if cfg.out_smooth > 0:
            for rec in pieces.values():
                self._smooth_centres(rec, self._frames(cfg.out_smooth))
        out = []
        for tid, rec in pieces.items():
            for f in sorted(rec):
                box, kind, score = rec[f]
                out.append([f, tid, *box, score if score > 0 else 0.5, KINDS.index(kind)])
        return np.array(out, dtype=float).reshape(-1, 8), set(pieces)

    def _flash(self, rec: dict) -> bool:
        """A false alarm by the entry/exit logic (Sec. 2.5.4): lasts under ``min_life`` seconds, and
        both appears and vanishes inside the image (not at a border, not at the sequence's ends)."""
        f0, f1 = min(rec), max(rec)
        if f1 - f0 + 1 >= self._frames(self.cfg.min_life) or self.cfg.min_life <= 0:
            return False
        if f0 <= (self.first_frame or 1) or f1 >= self.last_frame:
            return False
        return all(side_of(rec[f][0], self.width, self.height) == "inside" for f in (f0, f1))

    @staticmethod
    def _smooth_centres(rec: dict, k: int) -> None:
        """Offline smoothing of a track's centres: a straight-line fit over +-``k`` frames.

        The online estimate at a frame knows only the past; offline, each centre is the value at
        that frame of the least-squares line through the track's centres within +-``k`` frames
        (a pedestrian's path is close to straight over a second), which removes the per-frame
        jitter of detections and experts without lagging behind (a fixed-lag smoother).
        """
        fs = np.array(sorted(rec))
        cs = np.array([box_center(rec[f][0]) for f in fs])
        new = {}
        for f in fs:
            near = np.abs(fs - f) <= k
            if near.sum() < 3:
                continue
            A = np.stack([np.ones(near.sum()), fs[near] - f], 1)
            coef, *_ = np.linalg.lstsq(A, cs[near], rcond=None)
            new[f] = coef[0]
        for f, c in new.items():
            rec[f][0] = box_from_center(c, rec[f][0][2:4])

    @staticmethod
    def _smooth_sizes(rec: dict, k: int) -> None:
        """Offline box size: the median size of the track's detections within +-``k`` frames.

        A person's size changes slowly; per-frame detection boxes jitter (and sometimes span a
        neighbour), so each output box keeps its centre and takes the track-level size.
        """
        fs = np.array(sorted(f for f in rec if rec[f][1] in ("det", "tentative")))
        if len(fs) < 3:
            return
        sizes = np.array([rec[f][0][2:4] for f in fs])
        for f in rec:
            near = np.abs(fs - f) <= k
            if near.sum() < 3:
                near = np.argsort(np.abs(fs - f))[:3]
            size = np.median(sizes[near], axis=0)
            rec[f][0] = box_from_center(box_center(rec[f][0]), size)

    @staticmethod
    def _interpolate(rec: dict, a: int, b: int, kind: str) -> None:
        """Constant-velocity interpolation of the boxes strictly between frames ``a`` and ``b``."""
        ca, cb = box_center(rec[a][0]), box_center(rec[b][0])
        sa, sb = rec[a][0][2:4], rec[b][0][2:4]
        for f in range(a + 1, b):
            u = (f - a) / (b - a)
            rec[f] = [box_from_center((1 - u) * ca + u * cb, (1 - u) * sa + u * sb), kind, 0.0]

    def _end_state(self, rec: dict, at_start: bool):
        """Position, velocity (px/frame) and size at one end of a tracklet, from its detections."""
        fs = sorted(f for f in rec if rec[f][1] in ("det", "tentative")) or sorted(rec)
        k = max(2, self._frames(0.5))
        fs = fs[:k] if at_start else fs[-k:]
        cs = np.array([box_center(rec[f][0]) for f in fs])
        f_end = fs[0] if at_start else fs[-1]
        if len(fs) >= 2 and fs[-1] > fs[0]:
            v = (cs[-1] - cs[0]) / (fs[-1] - fs[0])
        else:
            v = np.zeros(2)
        sizes = np.array([rec[f][0][2:4] for f in fs])
        return f_end, box_center(rec[f_end][0]), v, np.median(sizes, axis=0)

    def _stitch(self, pieces: dict) -> dict:
        """Join tracklets of one person across a gap (motion and appearance agree), Sec. 2.5.3-2.5.4.

        A tracklet ending at frame ``a`` and one starting at ``b > a`` within ``max_gap`` seconds are
        the same person when the constant-velocity extrapolation meets the new start within a
        distance that grows with the gap, the box sizes agree and the RGB histograms are close
        (KL divergence). The gap is filled by constant-velocity interpolation.
        """
        cfg = self.cfg
        if cfg.max_gap <= 0 or len(pieces) < 2:
            return pieces
        hist = {t.id: t.hist for t in self.all_tracks}
        max_gap = self._frames(cfg.max_gap)
        ends = {i: (min(r), max(r)) for i, r in pieces.items()}
        starts = {j: self._end_state(rj, at_start=True) for j, rj in pieces.items()}
        cand = []
        for i, ri in pieces.items():
            fa, ca, va, sa = self._end_state(ri, at_start=False)
            for j in pieces:
                if i == j or ends[j][0] <= ends[i][1]:
                    continue
                fb, cb, vb, sb = starts[j]
                gap = fb - fa
                if gap < 1 or gap > max_gap:
                    continue
                if not (0.67 < sb[1] / sa[1] < 1.5):
                    continue
                pred = ca + va * gap
                h = 0.5 * (sa[1] + sb[1])
                tol = h * (cfg.stitch_dist + cfg.stitch_speed * gap / self.fps)
                d = np.linalg.norm(pred - cb)
                if d > tol:
                    continue
                kl = kl_divergence(hist.get(i), hist.get(j))
                if not kl <= cfg.stitch_kl:
                    continue
                cand.append((d / tol + kl / cfg.stitch_kl, i, j, fa, fb))
        cand.sort()
        nxt, prv = {}, {}
        for _, i, j, fa, fb in cand:
            if i in nxt or j in prv:
                continue
            # no cycles: j's chain must not lead back to i
            k = j
            while k in nxt:
                k = nxt[k]
            if k == i:
                continue
            nxt[i], prv[j] = j, i
        out = {}
        for i in pieces:
            if i in prv:
                continue
            rec = dict(pieces[i])
            k = i
            while k in nxt:
                j = nxt[k]
                rj = pieces[j]
                fa = self._end_state(rec, at_start=False)[0]
                fb = self._end_state(rj, at_start=True)[0]
                # drop what overlaps the gap: coasted tail of one, back-tracked start of the other
                rec = {f: v for f, v in rec.items() if f <= fa}
                rec.update({f: v for f, v in rj.items() if f >= fb})
                self.piece_span[k] = (self.piece_span[k][0], fb - 1)   # the gap: still k's person
                self.piece_span[j] = (fb, self.piece_span[j][1])
                self._interpolate(rec, fa, fb, "interp")
                self.relabel[j] = i
                k = j
            out[i] = rec
        return out

    def _static_false(self, t: Track) -> bool:
        """Reject a track that never shows background motion and never moves (a static false alarm)."""
        fg = np.array(t.fg[3:] if len(t.fg) > 3 else t.fg)
        if not len(fg) or fg.mean() >= self.cfg.min_fg_static:
            return False
        cs = np.array([box_center(b) for b, k, _ in t.boxes.values() if k == "det"])
        travel = np.linalg.norm(cs.max(0) - cs.min(0)) if len(cs) else 0.0
        return travel < 0.5 * t.size[1]

    def _root(self, i: int) -> int:
        """The output track a tracker id ended up in (tracklets are stitched into their first piece)."""
        while i in self.relabel:
            i = self.relabel[i]
        return i

    def _track_events(self, res: np.ndarray, new: dict, length: int) -> list[dict]:
        """``enter``/``exit`` events of the output tracks (``new``: tracker id -> output id).

        A sentence "person 3 enters" must mean that the person came into view: a track whose
        person was already there when the sequence started (its first detection, or its
        back-tracked or first reported box, is on the sequence's first frame) gets no ``enter``
        -- online too, where the track is only reported from its confirmation on (there the
        ``enter`` is at the first reported frame, its side and position from the first
        detection, where the person came into view). Likewise no
        ``exit`` for a track still present at the end: its last box is on the last frame, or the
        tracker still holds it (coasting or in a group) when the sequence ends.
        """
        first = self.first_frame if self.first_frame is not None else 1
        began, last = {}, {}
        for t in self.all_tracks:
            r = self._root(t.id)
            f0 = min([t.first, *t.back])
            box0 = t.back[f0] if f0 in t.back else t.boxes[t.first][0]
            if r not in began or f0 < began[r][0]:
                began[r] = (f0, box0)
            if r not in last or t.first > last[r].first:
                last[r] = t     # the tracklet that ends the output track
        alive = {r: t.state != "dead" for r, t in last.items()}
        events = []
        for old, nid in new.items():
            r = res[res[:, 1] == nid]
            f0, f1 = int(r[:, 0].min()), int(r[:, 0].max())
            b0, b1 = r[r[:, 0] == f0][0, 2:6], r[r[:, 0] == f1][0, 2:6]
            if old in began and began[old][0] < f0:
                # online, a track is reported from its confirmation: it came in where it was first seen
                b0 = np.clip(began[old][1], [-np.inf, -np.inf, 1, 1], np.inf)
            c0, c1 = box_center(b0), box_center(b1)
            if min(f0, began.get(old, (f0,))[0]) > first:
                events.append({"type": "enter", "frame": f0, "tracks": [nid],
                               "side": side_of(b0, self.width, self.height),
                               "x": round(float(c0[0]), 1), "y": round(float(c0[1]), 1)})
            if f1 < length and not alive.get(old, False):
                events.append({"type": "exit", "frame": f1, "tracks": [nid],
                               "side": side_of(b1, self.width, self.height),
                               "x": round(float(c1[0]), 1), "y": round(float(c1[1]), 1)})
        return events

    def _group_events(self, res: np.ndarray, new: dict) -> list[dict]:
        """``merge``/``split`` events of the output tracks, from the groups' membership frame by frame.

        A tracker track counts as a member on a frame only if the output shows it there under its
        output id (offline, stitched tracklets each own their part of the track: a tracklet still
        coasting in a group after the next tracklet of the person has started is no longer that
        person; in the interpolated gap before it, it still is). The events replay as a state
        machine: an output group starts (``merge``) when it has two such members; when someone
        joins, a ``merge`` lists all members; when someone leaves and two or more remain, a
        ``split`` lists the members before and a ``merge`` (same group id) those who stay
        together; it ends (``split``) when fewer than two remain. A group still together on the
        sequence's last frame gets no ``split``; no track is in two groups at once.
        """
        present = {(int(f), int(i)) for f, i in res[:, :2]}
        boxes = {(int(r[0]), int(r[1])): r[2:6] for r in res}

        def members(n: int, raw: tuple) -> tuple:
            out = set()
            for i in raw:
                r = self._root(i)
                if r not in new or (n, new[r]) not in present:
                    continue
                span = self.piece_span.get(i)
                if not self.online and span is not None and not span[0] <= n <= span[1]:
                    continue
                out.add(new[r])
            return tuple(sorted(out)) if len(out) >= 2 else ()

        def event(kind: str, n: int, g: int, ids: tuple, at: int) -> dict:
            c = box_center(union_box([boxes[(at, i)] for i in ids]))
            return {"type": kind, "frame": int(n), "tracks": [int(i) for i in ids], "group": int(g),
                    "x": round(float(c[0]), 1), "y": round(float(c[1]), 1)}

        events, state = [], {}   # state: group id -> (members, frame seen)
        for n in range(min(self.group_log, default=0), self.last_frame + 1):
            now = {g: members(n, raw) for g, raw in self.group_log.get(n, {}).items()}
            for g, (ids, at) in list(state.items()):
                cur = now.get(g, ())
                if set(cur) == set(ids):
                    state[g] = (ids, n)
                    continue
                if not cur or not set(cur) >= set(ids):
                    events.append(event("split", n, g, ids, at))
                if cur:
                    events.append(event("merge", n, g, cur, n))
                    state[g] = (cur, n)
                else:
                    del state[g]
            for g, cur in now.items():
                if cur and g not in state:
                    events.append(event("merge", n, g, cur, n))
                    state[g] = (cur, n)
        return events

    def _finalise(self, rows: np.ndarray, keep_ids: set, length: int):
        if not len(rows):
            return np.zeros((0, 10)), []
        rows = rows[np.isin(rows[:, 1], list(keep_ids))] if keep_ids else rows[:0]
        # drop boxes that left the image (less than a pixel of them inside it)
        inside = clip_box(rows[:, 2:6], self.width, self.height)
        rows = rows[(inside[:, 2] > 1) & (inside[:, 3] > 1)]
        # renumber ids by first appearance
        order = sorted(set(rows[:, 1].astype(int)), key=lambda i: (rows[rows[:, 1] == i, 0].min(), i))
        new = {old: k + 1 for k, old in enumerate(order)}
        res = np.full((len(rows), 10), -1.0)
        res[:, :7] = rows[:, :7]
        res[:, 1] = [new[int(i)] for i in rows[:, 1]]
        o = np.lexsort((res[:, 1], res[:, 0]))
        res = res[o]
        #: what produced each row (an index into KINDS), for diagnostics
        self.row_kinds = rows[o, 7].astype(int)
        events = self._track_events(res, new, length)
        group_events = self._group_events(res, new)
        if self.cfg.split_hold > 0:
            group_events = collapse_group_flicker(group_events, self._frames(self.cfg.split_hold))
        events += group_events
        order_key = {"exit": 0, "split": 1, "merge": 2, "enter": 3}
        events.sort(key=lambda e: (e["frame"], order_key.get(e["type"], 4), e["tracks"]))
        return res, events


def collapse_group_flicker(events: list[dict], hold: int) -> list[dict]:
    """One real interaction gives one ``merge`` and one ``split`` (hysteresis on group events).

    A ``split`` followed within ``hold`` frames by a ``merge`` of the same members (or of a group
    containing them all) did not hold: both are dropped and the new group continues the old one
    (its id is replaced by the old group's, in every later event). ``events`` are merge/split
    dicts with ``tracks`` and ``group``; returns them in chronological order.
    """
    order_key = {"split": 0, "merge": 1}
    evs = sorted(events, key=lambda e: (e["frame"], order_key.get(e["type"], 2), e["tracks"]))
    rename: dict[int, int] = {}
    pending: list[tuple[int, dict]] = []   # (index in out, split event) waiting for a re-merge
    out: list[dict | None] = []
    for ev in evs:
        ev = dict(ev)
        if "group" in ev:
            g = ev["group"]
            while g in rename:
                g = rename[g]
            ev["group"] = g
        pending = [(k, s) for k, s in pending if ev["frame"] - s["frame"] <= hold]
        if ev["type"] == "merge":
            hit = next(((k, s) for k, s in reversed(pending)
                        if set(s["tracks"]) <= set(ev["tracks"]) and ev["frame"] >= s["frame"]), None)
            if hit is not None:
                k, s = hit
                out[k] = None                      # the split did not hold ...
                pending.remove(hit)
                # ... nor did the smaller group that stayed together at the split
                for q in range(k + 1, len(out)):
                    e = out[q]
                    if e is not None and e["type"] == "merge" and e["frame"] == s["frame"] \
                            and e.get("group") == s.get("group"):
                        out[q] = None
                if "group" in ev and "group" in s and ev["group"] != s["group"]:
                    rename[ev["group"]] = s["group"]
                    ev["group"] = s["group"]
                if set(ev["tracks"]) == set(s["tracks"]):
                    continue                       # ... and the re-merge continues the same group
                # someone else joined while the group re-formed: a merge into the old group
        out.append(ev)
        if ev["type"] == "split":
            pending.append((len(out) - 1, ev))
    return [e for e in out if e is not None]
