"""Multiple object tracking with group nodes (thesis Sec. 2.5): online pass, offline pass, events.

:class:`MultiObjectTracker` is the :class:`~artmotion.tracking.online.OnlineTracker` (one frame
at a time: camera motion, prediction by the Product of Tracking Experts, association, groups,
births and deaths) plus :meth:`~MultiObjectTracker.finish`, which closes the sequence:

* offline (default): every confirmed track is smoothed and its gaps filled (Sec. 2.5.3,
  :mod:`~artmotion.tracking.offline`), tracklets are optionally stitched, short tracks that
  appear and vanish inside the image are optionally dropped;
* ``online=True``: only what was reported at each frame;

then the rows are renumbered and the events built: ``enter``/``exit`` (Sec. 2.5.4,
:mod:`~artmotion.tracking.entry_exit`) and ``merge``/``split`` of the group nodes (Sec. 2.5.2,
:mod:`~artmotion.tracking.groups`, with hysteresis). Where each stage lives:

=====================================  =======================================
thesis                                 module
=====================================  =======================================
2.4 experts, 2.4.1-2.4.5               ``experts.py`` (fusion: ``pote.py``)
2.5.1 state, Eq. 2.10                  ``state.py``
Eq. 2.4 association                    ``association.py``
2.5.2 occlusion and groups             ``groups.py``
2.5.3 interpolation                    ``offline.py``
2.5.4 entry/exit                       ``entry_exit.py``
camera motion                          ``camera.py``
one frame / the whole sequence         ``online.py`` / this module
=====================================  =======================================
"""

from __future__ import annotations

import numpy as np

from artmotion.errors import check_bool, check_range
from artmotion.geometry import clip_box
from artmotion.io.mot import MAX_FRAME
from artmotion.tracking.config import TrackerConfig
from artmotion.tracking.entry_exit import side_of, track_events
from artmotion.tracking.groups import Group, collapse_group_flicker, group_events
from artmotion.tracking.offline import duplicates, stitch, track_pieces
from artmotion.tracking.online import KINDS, OnlineTracker, Track
from artmotion.tracking.state import DETECTED, TENTATIVE

__all__ = ["Group", "KINDS", "MultiObjectTracker", "Track", "TrackerConfig", "collapse_group_flicker", "side_of"]


class MultiObjectTracker(OnlineTracker):
    """The tracker; :meth:`step` per frame, then :meth:`finish` for the result."""

    def __init__(self, fps: float, width: int, height: int, experts=("det", "motion"),
                 config: TrackerConfig | None = None, online: bool = False):
        online = check_bool("online", online)
        super().__init__(fps, width, height, experts=experts, config=config)
        self.online = online
        self.relabel: dict[int, int] = {}
        self.piece_span: dict[int, tuple[int, int]] = {}
        self.row_kinds = np.zeros(0, dtype=int)

    def _root(self, i: int) -> int:
        while i in self.relabel:
            i = self.relabel[i]
        return i

    def _ended(self, t: Track) -> None:
        # the offline output of a finished track is computed at once, then its history let go
        if not self.online and t.confirmed_at is not None:
            cfg = self.cfg
            t.piece = track_pieces(t, self.dt, cfg.smooth, self._frames(cfg.max_interp) if cfg.max_interp > 0 else 0,
                                   self._frames(cfg.tail) if cfg.tail > 0 else 0)
        super()._ended(t)

    def finish(self, length: int | None = None) -> tuple[np.ndarray, list[dict]]:
        """Close the sequence; return ``(rows, events)`` (rows: N x 10 MOT array, ids renumbered).
        ``length``: the sequence's number of frames (default: the last frame stepped), at least
        that last frame."""
        if length is None:
            length = self.last_frame
        else:
            length = check_range("length", length, max(self.last_frame, 1), MAX_FRAME, integer=True)
        for t in self.tracks:
            if t.first_box is None:
                self._ended(t)
        if self.online:
            rows = self.online_rows()
            keep = {t.id for t in self.all_tracks if t.state in ("confirmed", "dead")}
        else:
            rows, keep = self._offline_rows()
        return self._finalise(rows, keep, length)

    def _offline_rows(self) -> tuple[np.ndarray, set]:
        cfg = self.cfg
        pieces = {t.id: t.piece for t in self.all_tracks if t.piece}
        hists = {t.id: t.hist for t in self.all_tracks}
        pieces, self.relabel, self.piece_span = stitch(pieces, hists, cfg, self.fps, self.camera_path)
        pieces = {i: rec for i, rec in pieces.items() if not self._flash(rec) and self._confident(rec)}
        pieces = duplicates(pieces, cfg.duplicate_share, cfg.duplicate_drift)
        out = [[f, tid, *box, score if score > 0 else 0.5, kind]
               for tid, rec in pieces.items() for f, (box, kind, score) in rec.items()]
        return np.array(out, dtype=float).reshape(-1, 8), set(pieces)

    def _confident(self, rec: dict) -> bool:
        """The track's detections score ``min_track_score`` on average (a false alarm that
        persisted long enough to be confirmed is rarely confident throughout)."""
        if self.cfg.min_track_score <= 0:
            return True
        s = [v[2] for v in rec.values() if v[1] in (DETECTED, TENTATIVE)]
        return bool(s) and float(np.mean(s)) >= self.cfg.min_track_score

    def _flash(self, rec: dict) -> bool:
        """A false alarm by the entry/exit logic (Sec. 2.5.4): lasts under ``min_life`` seconds and
        both appears and vanishes inside the image (not at a border, not at the sequence's ends)."""
        if self.cfg.min_life <= 0:
            return False
        f0, f1 = min(rec), max(rec)
        if f1 - f0 + 1 >= self._frames(self.cfg.min_life):
            return False
        if f0 <= (self.first_frame or 1) or f1 >= self.last_frame:
            return False
        return all(side_of(rec[f][0], self.width, self.height) == "inside" for f in (f0, f1))

    def _finalise(self, rows: np.ndarray, keep_ids: set, length: int):
        if not len(rows):
            return np.zeros((0, 10)), []
        rows = rows[np.isin(rows[:, 1], list(keep_ids))] if keep_ids else rows[:0]
        # drop boxes that left the image (less than a pixel of them inside it)
        inside = clip_box(rows[:, 2:6], self.width, self.height)
        rows = rows[(inside[:, 2] > 1) & (inside[:, 3] > 1)]
        if not len(rows):
            return np.zeros((0, 10)), []
        # renumber ids by first appearance
        first: dict[int, float] = {}
        for f, i in rows[:, :2]:
            first[int(i)] = min(first.get(int(i), f), f)
        order = sorted(first, key=lambda i: (first[i], i))
        new = {old: k + 1 for k, old in enumerate(order)}
        res = np.full((len(rows), 10), -1.0)
        res[:, :7] = rows[:, :7]
        res[:, 1] = [new[int(i)] for i in rows[:, 1]]
        o = np.lexsort((res[:, 1], res[:, 0]))
        res = res[o]
        #: what produced each row (an index into KINDS), for diagnostics
        self.row_kinds = rows[o, 7].astype(int)
        events = self._events(res, new, length)
        return res, events

    def _events(self, res: np.ndarray, new: dict, length: int) -> list[dict]:
        began: dict[int, tuple] = {}
        for t in self.all_tracks:
            r = self._root(t.id)
            if r not in began or t.first < began[r][0]:
                began[r] = (t.first, t.first_box)
        first = self.first_frame if self.first_frame is not None else 1
        events = track_events(res, new, began, first, length, self.width, self.height)
        if self.cfg.groups:
            ge = group_events(res, new, self.group_log, self._root, self.piece_span, self.online, self.last_frame)
            if self.cfg.split_hold > 0:
                ge = collapse_group_flicker(ge, self._frames(self.cfg.split_hold))
            events += ge
        order_key = {"exit": 0, "split": 1, "merge": 2, "enter": 3}
        events.sort(key=lambda e: (e["frame"], order_key.get(e["type"], 4), e["tracks"]))
        return events

