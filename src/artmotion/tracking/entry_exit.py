"""Entry and exit (thesis Sec. 2.5.4): when an entity comes into view and when it leaves.

* A track starts from a high-score detection that no live track explains and is *confirmed*
  after further detections (a single detection is too often a false alarm).
* A track that has lost its detection ends when it leaves the image, when it has been lost too
  long, or — the thesis' test, optional — when the appearance cue confirms the exit: the RGB
  histogram of its box on the current frame has drifted from its model more than the same box on
  the frame of its last detection and more than the last detected box on the current frame
  (``score2 > score1`` and ``score2 > score3``), or beyond ``exit_kl``.
* The ``enter``/``exit`` events of the output say where (``side``) a person came into view or
  left it: no ``enter`` for people already there when the sequence starts and no ``exit`` for
  people still there when it ends. A person whose last box is before the last frame gets an
  ``exit`` there even if the tracker still held the track, lost, when the sequence ended: the
  output shows nobody after that box (``side`` ``inside`` where that was in the image).
"""

from __future__ import annotations

import math

import numpy as np

from artmotion.geometry import box_center, box_overlap
from artmotion.tracking.appearance import kl_divergence, rgb_histogram

__all__ = ["appearance_exit", "outside", "side_of", "track_ends", "track_events"]


def side_of(box, width: int, height: int, margin: float = 0.3) -> str:
    """Where a box touches the image: ``left``/``right``/``top``/``bottom`` or ``inside``.

    A side counts when the box is within ``margin`` of its own width (height) from it.
    """
    x, y, w, h = box
    d = {"left": x / w, "right": (width - (x + w)) / w, "top": y / h, "bottom": (height - (y + h)) / h}
    k = min(d, key=lambda s: d[s])
    return k if d[k] <= margin else "inside"


def outside(box, width: int, height: int) -> bool:
    """Less than half of the box is inside the image."""
    return box_overlap(box, (0.0, 0.0, width, height)) < 0.5


def appearance_exit(track, frame, box, exit_kl: float, parts: int = 1) -> bool:
    """The appearance test of Sec. 2.5.4 for a track without detection (see the module docstring)."""
    if track.hist is None or track.hist_frame is None:
        return False
    h_now = rgb_histogram(frame.small, box, frame.scale, parts=parts)
    score2 = kl_divergence(track.hist, h_now)
    if not math.isfinite(score2) or score2 > exit_kl:
        return True
    hf = track.hist_frame
    score1 = kl_divergence(track.hist, rgb_histogram(hf.small, box, hf.scale, parts=parts))
    score3 = kl_divergence(rgb_histogram(frame.small, track.hist_box, frame.scale, parts=parts), h_now)
    return score2 > score1 and score2 > score3


def track_ends(t, frame, cfg, width: int, height: int, frames) -> bool:
    """Whether track ``t``, without a detection on ``frame``, ends now (``frames(seconds)``
    converts the config's durations): a tentative track after ``tentative_misses`` misses; a
    confirmed one when it leaves the image, when it has been lost ``max_lost`` seconds (a group
    member: ``max_group``), or when the appearance test says it left (``exit_test``)."""
    if t.state == "tentative":
        return t.misses > cfg.tentative_misses
    if outside(t.box, width, height):
        return True
    if t.group is not None:
        return t.misses > frames(cfg.max_group)
    if t.misses > frames(cfg.max_lost):
        return True
    return bool(cfg.exit_test and appearance_exit(t, frame, t.box, cfg.exit_kl, cfg.app_parts))


def track_events(res: np.ndarray, new: dict, began: dict, first: int, length: int,
                 width: int, height: int) -> list[dict]:
    """``enter``/``exit`` events of the output tracks.

    ``res``: output rows; ``new``: tracker id -> output id (of the output track's first tracklet);
    ``began``: that id -> ``(frame, box)`` where the person was first detected; ``first``/``length``: the sequence's
    first and last frame. A track whose person was already there when the sequence started (first
    detected, or first reported, on the first frame) gets no ``enter``; online, where a track is
    reported only from its confirmation, the ``enter`` is at the first reported frame with the side
    and position of the first detection. A track whose last box is on the last frame gets no
    ``exit``; any other gets one at its last box, whether or not the tracker still held it, lost,
    at the end (the output shows nobody after that box: a clip that ended within ``max_lost`` of
    a person's last detection had said nothing of them).
    """
    events = []
    for old, nid in new.items():
        r = res[res[:, 1] == nid]
        f0, f1 = int(r[:, 0].min()), int(r[:, 0].max())
        b0, b1 = r[r[:, 0] == f0][0, 2:6], r[r[:, 0] == f1][0, 2:6]
        if old in began and began[old][0] < f0:
            b0 = np.clip(began[old][1], [-np.inf, -np.inf, 1, 1], np.inf)
        c0, c1 = box_center(b0), box_center(b1)
        if min(f0, began.get(old, (f0,))[0]) > first:
            events.append({"type": "enter", "frame": f0, "tracks": [nid], "side": side_of(b0, width, height),
                           "x": round(float(c0[0]), 1), "y": round(float(c0[1]), 1)})
        if f1 < length:
            events.append({"type": "exit", "frame": f1, "tracks": [nid], "side": side_of(b1, width, height),
                           "x": round(float(c1[0]), 1), "y": round(float(c1[1]), 1)})
    return events
