"""The online multi-object tracker (thesis Sec. 2.5), one frame at a time.

Per frame (:meth:`OnlineTracker.step`):

1. **camera motion** (:mod:`~artmotion.tracking.camera`) is taken out of every track's state;
2. **prediction**: every track's Kalman filter (:mod:`~artmotion.tracking.state`, Eq. 2.10)
   predicts its box; the image experts (KLT, dense flow, background blobs — Sec. 2.4.2-2.4.5)
   add their opinion on the centre of the tracks that lost their detection (or of all tracks),
   fused with the motion prior as a product of Gaussians (PoTE, Eq. 2.3: the Kalman update with
   the experts' product as the measurement);
3. **association** (:mod:`~artmotion.tracking.association`, Eq. 2.4): high-score detections to
   confirmed and lost tracks, then low-score detections to the tracks seen on the previous frame,
   then the remaining high-score detections to tentative tracks;
4. **update**: a matched track's filter takes the detection (the detector expert);
5. **groups** (:mod:`~artmotion.tracking.groups`, Sec. 2.5.2): a confirmed track that lost its
   detection while overlapping another forms a group node with it;
6. **births and deaths** (:mod:`~artmotion.tracking.entry_exit`, Sec. 2.5.4).

Every track keeps its filter's history (predicted and filtered state on each frame), which the
offline pass (:mod:`~artmotion.tracking.offline`) smooths. :meth:`OnlineTracker.online_rows`
gives what an online tracker reports: the boxes of confirmed tracks on the frames they were
detected (plus ``online_coast`` seconds of coasting).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from artmotion.errors import InputError, check_range
from artmotion.geometry import iou_matrix, max_iou
from artmotion.io.media import MAX_FPS, MIN_FPS
from artmotion.io.mot import MAX_FRAME
from artmotion.tracking.appearance import kl_matrix, rgb_histogram
from artmotion.tracking.association import INF, assign, iou_cost
from artmotion.tracking.camera import CameraMotion, CameraPath
from artmotion.tracking.config import TrackerConfig
from artmotion.tracking.entry_exit import track_ends
from artmotion.tracking.experts import Entity, Frame, check_experts
from artmotion.tracking.groups import Group, resolve_split, update_groups
from artmotion.tracking.pote import PoTE
from artmotion.tracking.state import (
    DETECTED,
    GROUP,
    KINDS,
    LOST,
    TENTATIVE,
    KalmanBank,
    NoiseEstimator,
    boxes_to_z,
    warp_matrix,
    z_to_boxes,
)

__all__ = ["KINDS", "MAX_SIDE", "OnlineTracker", "Track"]

#: the largest width or height of a frame, in pixels (as for a sequence's seqinfo.ini)
MAX_SIDE = 100_000


def _clean_views(tracks: list, matched: dict[int, int], dets: np.ndarray, old: np.ndarray, pred: np.ndarray,
                 was_confirmed: np.ndarray) -> list[int]:
    """The matched tracks (indices into ``tracks``, ascending) whose detection no other confirmed
    track overlaps (IoU < 0.1): a clean view of the person for the appearance model. Each is
    judged as the frame's update passes over the tracks in order: the tracks before it that lost
    their detection are at their predicted boxes (``pred``), the others at their boxes before the
    update (``old``), and the tracks before it confirmed by this frame's detection count as
    confirmed."""
    rows = np.array(sorted(matched))
    unmatched = np.ones(len(tracks), dtype=bool)
    unmatched[rows] = False
    confirmed = np.array([t.state == "confirmed" for t in tracks], dtype=bool)
    clean = []
    for a in range(0, len(rows), 256):         # bounded memory in a crowd
        r = rows[a:a + 256]
        D = dets[[matched[int(i)] for i in r], :4]
        before = np.arange(len(tracks))[None, :] < r[:, None]
        M = np.where(unmatched & before, iou_matrix(D, pred), iou_matrix(D, old))
        others = np.where(before, confirmed, was_confirmed)
        others[np.arange(len(r)), r] = False
        clean += r[np.where(others, M, 0.0).max(axis=1, initial=0.0) < 0.1].tolist()
    return clean


@dataclass
class Track:
    """One tracked entity and its history (for the offline pass)."""

    id: int
    slot: int
    entity: Entity
    first: int
    state: str = "tentative"          #: tentative, confirmed, dead
    hits: int = 1
    misses: int = 0
    last_det: int = 0
    confirmed_at: int | None = None
    hist: np.ndarray | None = None    #: RGB histogram model (Sec. 2.5.2)
    hist_frame: Frame | None = None   #: frame of the last clean detection (exit test)
    hist_box: np.ndarray | None = None
    group: Group | None = None
    # history: one entry per frame from birth to death
    frames: list = field(default_factory=list)
    xp: list = field(default_factory=list)     #: predicted state (after the camera warp)
    Pp: list = field(default_factory=list)
    xf: list = field(default_factory=list)     #: filtered state
    Pf: list = field(default_factory=list)
    warps: list = field(default_factory=list)  #: 8x8 camera transform before the prediction, or None
    kinds: list = field(default_factory=list)
    scores: list = field(default_factory=list)
    first_box: np.ndarray | None = None        #: box of the first detection (once the history is gone)
    piece: dict | None = None                  #: the offline output of the track, once it ended

    @property
    def box(self) -> np.ndarray:
        return self.entity.box


def release_history(t: Track) -> None:
    """Forget a track's per-frame filter history (memory stays flat in the sequence length)."""
    t.first_box = z_to_boxes(t.xf[0][:4])[0] if t.xf else t.entity.box.copy()
    t.xp, t.Pp, t.xf, t.Pf, t.warps = [], [], [], [], []
    t.frames, t.kinds, t.scores = [], [], []


class OnlineTracker:
    """Causal tracking; :meth:`step` per frame. ``experts``: names of the tracking experts
    (``det`` and ``motion`` are the detector and the Kalman filter; the others are image experts)."""

    def __init__(self, fps: float, width: int, height: int, experts=("det", "motion"),
                 config: TrackerConfig | None = None):
        if config is not None and not isinstance(config, TrackerConfig):
            raise InputError(f"config must be a TrackerConfig, got {type(config).__name__}")
        self.cfg = cfg = (config or TrackerConfig()).check()
        self.fps = float(check_range("frame rate (frames/s)", fps, MIN_FPS, MAX_FPS))
        self.dt = 1.0 / self.fps
        self.width = check_range("width (pixels)", width, 1, MAX_SIDE, integer=True)
        self.height = check_range("height (pixels)", height, 1, MAX_SIDE, integer=True)
        self.experts = check_experts(experts, need_det=True)
        self.use_motion = "motion" in self.experts
        image_experts = [e for e in self.experts if e not in ("det", "motion")]
        self.pote = PoTE(image_experts) if image_experts and cfg.experts_when != "none" else None
        # without the motion expert, the filter forgets its velocity (a random walk of the box)
        self.bank = KalmanBank(accel=cfg.accel if self.use_motion else 1e3, size_accel=cfg.size_accel,
                               meas=cfg.meas, size_meas=cfg.size_meas)
        self.camera = CameraMotion(self.fps) if cfg.camera else None
        self.camera_path = CameraPath()     #: every frame's camera motion, for the offline pass
        self.noise = (NoiseEstimator(self.bank.rel_sd, self.bank.rel_accel, self.dt, horizon=cfg.noise_horizon)
                      if cfg.adapt_noise and self.use_motion else None)
        if self.noise is None and cfg.size_meas == 0 and cfg.size_accel == 0:
            # (TrackerConfig.check refuses this without adapt_noise; the estimate needs the motion expert)
            raise InputError("size_meas and size_accel must not both be 0 without the 'motion' expert: the noise "
                             "is then not estimated, and a size known exactly that never changes cannot be filtered")
        self.tracks: list[Track] = []        #: live tracks
        self.all_tracks: list[Track] = []
        self.groups: list[Group] = []
        self.group_log: dict[int, dict[int, tuple]] = {}   #: frame -> {group id: member track ids}
        self.next_id = 1
        self.next_group = 1
        self.prev: Frame | None = None
        self.first_frame: int | None = None
        self.last_frame = 0
        self._detected_at: int | None = None   # the last frame the detector ran on
        self.online_out: list = []

    def _frames(self, seconds: float) -> int:
        return max(1, int(round(seconds * self.fps)))

    # ------------------------------------------------------------------ tracks
    def _new_track(self, frame: Frame, det: np.ndarray, hist) -> Track:
        box = det[:4].astype(float).copy()
        slot = self.bank.add(box)
        t = Track(self.next_id, slot, Entity(box=box), frame.number, last_det=frame.number)
        self.next_id += 1
        if self.cfg.confirm_hits <= 1:
            self._confirm(t, frame.number)
        kind = DETECTED if t.state == "confirmed" else TENTATIVE
        self._record(t, frame.number, self.bank.x[slot].copy(), self.bank.P[slot].copy(), None, kind, det[4])
        t.xf.append(t.xp[-1])
        t.Pf.append(t.Pp[-1])
        self._update_hist(t, frame, box, hist)
        self.tracks.append(t)
        self.all_tracks.append(t)
        return t

    @staticmethod
    def _record(t: Track, n: int, xp, Pp, warp, kind: int, score: float) -> None:
        t.frames.append(n)
        t.xp.append(xp)
        t.Pp.append(Pp)
        t.warps.append(warp)
        t.kinds.append(kind)
        t.scores.append(float(score))

    def _confirm(self, t: Track, n: int) -> None:
        t.state = "confirmed"
        t.confirmed_at = n

    def _update_hist(self, t: Track, frame: Frame, box, h) -> None:
        if h is None:
            return
        t.hist = h if t.hist is None else 0.7 * t.hist + 0.3 * h
        t.hist_frame = frame
        t.hist_box = np.asarray(box, dtype=float).copy()

    def _kill(self, t: Track) -> None:
        t.state = "dead" if t.state == "confirmed" or t.confirmed_at is not None else "dropped"
        t.hist_frame = None
        if t.group is not None:
            t.group.members.remove(t)
            t.group = None
        self.bank.remove(t.slot)
        if self.noise is not None:
            self.noise.forget(t.id)
        self.tracks.remove(t)
        if t.state == "dropped":
            self.all_tracks.remove(t)   # never confirmed: nothing of it is reported
        self._ended(t)

    def _ended(self, t: Track) -> None:
        """A track's history is complete (it died, or the sequence ended): the online tracker
        keeps only its first box; subclasses may use the history first (the offline pass)."""
        release_history(t)

    def _det_hist(self, frame: Frame, j: int | np.integer) -> np.ndarray | None:
        """RGB histogram of detection ``j`` of ``frame`` (computed once per frame)."""
        return frame.cached(f"det_hist{j}", lambda: rgb_histogram(frame.small, frame.detections[j, :4], frame.scale,
                                                                   parts=self.cfg.app_parts))

    def _needs_hist(self) -> bool:
        c = self.cfg
        return c.app_weight > 0 or c.reacquire_kl > 0 or c.exit_test or c.split_app or c.stitch

    # ------------------------------------------------------------------ one frame
    def _check_frame(self, frame: Frame) -> None:
        """A frame entering the tracker: a :class:`Frame` numbered by a whole number >= 1 after the
        previous frame's, of the tracker's size (an image decoded ``1 / frame.image_scale`` times
        smaller: that size divided, rounded up or down)."""
        if not isinstance(frame, Frame):
            raise InputError(f"the tracker steps on a Frame, got {type(frame).__name__}")
        n = frame.number
        if type(n) is not int or not 1 <= n <= MAX_FRAME:   # the common case costs a comparison
            n = frame.number = check_range("frame number", n, 1, MAX_FRAME, integer=True)
        if n <= self.last_frame:
            raise InputError(f"frame numbers must increase: frame {n} after frame {self.last_frame}")
        image = frame.image
        if image is None:
            raise InputError(f"frame {n}: the frame has no image (it went through the tracker before)")
        h, w = image.shape[:2]
        k = frame.image_scale
        if abs(h - self.height * k) >= 1 or abs(w - self.width * k) >= 1:
            size = f"{w}x{h}" if k == 1 else f"{w}x{h} ({w / k:g}x{h / k:g} at full size)"
            raise InputError(f"frame {n}: the image is {size}, the tracker's frames are {self.width}x{self.height}")

    def step(self, frame: Frame) -> None:
        self._check_frame(frame)
        cfg = self.cfg
        n = frame.number
        self.last_frame = n
        if self.first_frame is None:
            self.first_frame = n
        # misses count frames of time: on a detected frame, those since the last detected one
        gap = 0
        if frame.detected:
            gap = n - self._detected_at if self._detected_at is not None else 1
            self._detected_at = n
        dets = frame.detections
        if dets is not None and len(dets):
            dets = frame.detections = dets[dets[:, 4] >= cfg.low]
        tracks = list(self.tracks)
        slots = np.array([t.slot for t in tracks], dtype=int)

        # 1. camera motion, then prediction (Eq. 2.10)
        warp = None
        if self.camera is not None:
            A = self.camera.step(lambda: frame.grey, frame.scale,
                                 exclude=[t.box for t in tracks if t.state == "confirmed"])
            if A is not None:
                self.camera_path.add(n, A)
                warp = warp_matrix(A)
                self.bank.warp(slots, A)
            frame.shared["camera_moving"] = self.camera.moving
        self.bank.predict(slots, self.dt)
        for t in tracks:
            self._record(t, n, self.bank.x[t.slot].copy(), self.bank.P[t.slot].copy(), warp, LOST, 0.0)

        # 2. image experts: the product of their Gaussians updates the predicted centre (Eq. 2.3)
        opinions = {}
        if self.pote is not None and self.prev is not None and tracks:
            sel = self._expert_tracks(tracks, every=not frame.detected)
            if sel:
                ops = self.pote.estimate_many(frame, self.prev, [tracks[i].entity for i in sel],
                                              skip={"det", "motion"})
                for i, (g, op) in zip(sel, ops):
                    if g is not None:
                        self._update_centre(tracks[i].slot, g.mean, g.cov)
                        opinions[i] = op

        pred = self.bank.boxes(slots) if len(slots) else np.zeros((0, 4))
        # a frame the detector skipped: the tracks coast on the experts and motion, no misses
        matched = self._associate(frame, tracks, pred, dets) if frame.detected else {}
        if cfg.groups and cfg.split_app and self.groups:
            resolve_split(self.groups, tracks, pred, dets, matched, lambda j: self._det_hist(frame, j))
        # Sec. 2.7.1: each image expert's variance follows its actual error against the detector
        for i, op in opinions.items():
            j = matched.get(i)
            if j is not None and dets[j, 4] >= cfg.high:
                assert self.pote is not None  # only the image experts give opinions
                self.pote.observe(op, dets[j, :2] + 0.5 * dets[j, 2:4], dets[j, 2:4])

        # 3. update matched tracks; the others coast
        if matched:
            mi = sorted(matched)
            mslots = [tracks[i].slot for i in mi]
            mboxes = dets[[matched[i] for i in mi], :4]
            if self.noise is not None:
                self._adapt_noise([tracks[i] for i in mi], n, mboxes)
            self.bank.update(mslots, mboxes)
        if self._needs_hist() and matched:      # for the clean-view test below
            old = np.array([t.box for t in tracks], dtype=float).reshape(-1, 4)
            was_confirmed = np.array([t.state == "confirmed" for t in tracks], dtype=bool)
        for i, t in enumerate(tracks):
            j = matched.get(i)
            if j is None:
                t.misses += gap
                t.entity.box = pred[i]
                continue
            d = dets[j]
            t.hits += 1
            t.misses = 0
            t.last_det = n
            if t.state == "tentative" and t.hits >= cfg.confirm_hits:
                self._confirm(t, n)
            t.kinds[-1] = DETECTED if t.state == "confirmed" else TENTATIVE
            t.scores[-1] = float(d[4])
        if self._needs_hist() and matched:
            # appearance from clean views only (no other confirmed track over the detection)
            for i in _clean_views(tracks, matched, dets, old, pred, was_confirmed):
                t, j = tracks[i], matched[i]
                self._update_hist(t, frame, dets[j, :4], self._det_hist(frame, j))
        if len(slots):
            boxes = self.bank.boxes(slots)
            for i, t in enumerate(tracks):
                if i in matched:
                    t.entity.box = boxes[i]
                t.xf.append(self.bank.x[t.slot].copy())
                t.Pf.append(self.bank.P[t.slot].copy())

        # 4. groups of occluded tracks, then deaths (Sec. 2.5.2, 2.5.4)
        if cfg.groups and frame.detected:
            self.next_group = update_groups(self.groups, tracks, matched, n, cfg, self.next_group)
            for g in self.groups:
                for m in g.members:
                    if m.misses > 0:
                        m.kinds[-1] = GROUP
        for i, t in enumerate(tracks):
            if i not in matched and frame.detected and track_ends(t, frame, cfg, self.width, self.height, self._frames):
                self._kill(t)

        # 5. births from unmatched high-score detections
        if dets is not None and len(dets):
            used = set(matched.values())
            free = [j for j in np.argsort(-dets[:, 4]) if j not in used and dets[j, 4] >= cfg.high]
            live = np.zeros((len(self.tracks) + len(free), 4))      # the live tracks' boxes, births added
            n_live = len(self.tracks)
            for k, t in enumerate(self.tracks):
                live[k] = t.box
            for j in free:
                d = dets[j]
                if max_iou(d[:4], live[:n_live]) >= cfg.birth_iou:
                    continue
                t = self._new_track(frame, d, self._det_hist(frame, j) if self._needs_hist() else None)
                live[n_live] = t.box
                n_live += 1

        if self.groups:
            self.group_log[n] = {g.id: tuple(m.id for m in g.members) for g in self.groups}
        self._online_rows(n)
        if self.pote is not None:
            frame.small, frame.grey    # noqa: B018 - keep the small images (experts, histograms)
        elif self._needs_hist():
            frame.small                # noqa: B018 - keep the small image (histograms)
        frame.drop_image()
        self.prev = frame

    def _expert_tracks(self, tracks: list, every: bool = False) -> list[int]:
        """Indices of the tracks the image experts predict: lost ones (or all, ``experts_when``;
        ``every``: all, on a frame the detector skipped), but none that another track covers: the
        image inside a hidden member's box shows whoever is in front (Sec. 2.5.2), so group
        members and tracks overlapping another track's box (IoU >= 0.1) are left to their motion
        model."""
        cfg = self.cfg
        sel = [i for i, t in enumerate(tracks)
               if (every or cfg.experts_when == "all" or t.misses > 0) and t.group is None]
        if not sel or len(tracks) < 2:
            return sel
        boxes = np.array([t.box for t in tracks])
        M = iou_matrix(boxes[sel], boxes)
        M[np.arange(len(sel)), sel] = 0.0
        return [i for k, i in enumerate(sel) if M[k].max() < 0.1]

    def _adapt_noise(self, tracks: list, n: int, boxes: np.ndarray) -> None:
        """Feed the detections of confirmed tracks to the noise estimator
        (:class:`~artmotion.tracking.state.NoiseEstimator`) and use its estimates."""
        assert self.noise is not None  # called only when there is a noise estimator
        z = boxes_to_z(boxes)
        for t, zk in zip(tracks, z):
            if t.state == "confirmed":
                self.noise.observe(t.id, n, zk)
        self.bank.rel_sd = self.noise.sd()
        self.bank.rel_accel = self.noise.accel_sd()

    def _update_centre(self, slot: int, mean, cov) -> None:
        """Kalman update of the centre alone with an expert product ``N(mean, cov)``."""
        x, P = self.bank.x[slot], self.bank.P[slot]
        S = P[:2, :2] + cov
        K = np.linalg.solve(S, P[:2, :]).T
        self.bank.x[slot] = x + K @ (np.asarray(mean) - x[:2])
        P = P - K @ P[:2, :]
        self.bank.P[slot] = 0.5 * (P + P.T)

    # ------------------------------------------------------------------ association (Eq. 2.4)
    def _associate(self, frame: Frame, tracks: list, pred: np.ndarray, dets) -> dict[int, int]:
        cfg = self.cfg
        matched: dict[int, int] = {}
        if dets is None or not len(dets) or not tracks:
            return matched
        used = np.zeros(len(dets), bool)
        high = dets[:, 4] >= cfg.high
        conf = [i for i, t in enumerate(tracks) if t.state == "confirmed"]
        stages = (
            (conf, high, cfg.match_iou),                                          # high, all confirmed
            ([i for i in conf if tracks[i].misses == 0], ~high, cfg.match_iou),   # low, seen last frame
            ([i for i, t in enumerate(tracks) if t.state == "tentative"], high, cfg.match_iou),
        )
        for rows, which, gate in stages:
            rows = [i for i in rows if i not in matched]
            cols = np.flatnonzero(which & ~used)
            if not rows or not len(cols):
                continue
            cost, _ = iou_cost(pred[rows], dets[cols, :4], gate)
            if cfg.app_weight > 0 or cfg.reacquire_kl > 0:   # appearance matters only where the gate lets a pair
                allowed = cost < INF
                seen = np.flatnonzero(allowed.any(axis=0))
                hs: list = [None] * len(cols)
                for k in seen:
                    hs[k] = self._det_hist(frame, cols[k])
                K = kl_matrix([tracks[i].hist for i in rows], hs, cap=3.0, where=allowed)
                if cfg.app_weight > 0:
                    cost = np.where(cost < INF, cost + cfg.app_weight * K, INF)
                if cfg.reacquire_kl > 0:
                    lost = np.array([tracks[i].misses > 0 for i in rows])
                    cost = np.where(lost[:, None] & (K > cfg.reacquire_kl), INF, cost)
            for r, c in assign(cost):
                matched[rows[r]] = int(cols[c])
                used[cols[c]] = True
        return matched

    # ------------------------------------------------------------------ online output
    def _online_rows(self, n: int) -> None:
        lim = self._frames(self.cfg.online_coast) if self.cfg.online_coast > 0 else 0
        for t in self.tracks:
            if t.state != "confirmed" or not t.frames or t.frames[-1] != n:
                continue
            kind = t.kinds[-1]
            if kind != DETECTED and not (kind in (LOST, GROUP) and t.misses <= lim):
                continue
            self.online_out.append([n, t.id, *t.entity.box, t.scores[-1] if kind == DETECTED else 0.5, kind])

    def online_rows(self) -> np.ndarray:
        """``(N, 8)`` rows ``frame, id, x, y, w, h, score, kind`` reported online."""
        return np.array(self.online_out, dtype=float).reshape(-1, 8)
