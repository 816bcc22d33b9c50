"""Occlusion detection and group nodes (thesis Sec. 2.5.2, Eq. 2.11-2.13, Fig. 2.4-2.5).

An occlusion is detected when a confirmed track loses its detection while it overlaps another
confirmed track (Pascal overlap, Eq. 2.11): both become members of a group node whose extent is
the union of the members' boxes (Eq. 2.13); a track mostly inside an existing group (Eq. 2.12)
joins it. While hidden in a group a member is predicted by its motion model alone (the image
shows whoever is in front) and is kept longer than a lost track alone (``max_group``). The group
lasts while a member is hidden in it; when every member is detected again the group splits, and
the identities can be re-solved by the KL divergence of RGB histograms (Hungarian, Sec. 2.5.2).

The group membership on every frame is logged; :func:`group_events` turns the log into the
``merge``/``split`` events of the output tracks and :func:`collapse_group_flicker` removes
splits that did not hold (hysteresis).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from artmotion.geometry import box_center, box_overlap, intersection, iou_matrix, union_box
from artmotion.tracking.appearance import kl_divergence
from artmotion.tracking.association import assign

__all__ = ["Group", "collapse_group_flicker", "group_events", "resolve_split", "update_groups"]


@dataclass
class Group:
    """A group node: its members (tracks) and the frame it formed."""

    id: int
    members: list = field(default_factory=list)
    start: int = 0

    def box(self) -> np.ndarray:
        """Eq. 2.13: the group spans its members."""
        return union_box([m.box for m in self.members])


def occlusions(hidden: list, visible: list, merge_iou: float) -> list[tuple]:
    """Pairs ``(hidden track, other track)`` overlapping by at least ``merge_iou`` (Eq. 2.11)."""
    if not hidden or not visible:
        return []
    M = iou_matrix(np.array([t.box for t in hidden]), np.array([t.box for t in visible]))
    out = []
    for i, t in enumerate(hidden):
        for k, o in enumerate(visible):
            if o is not t and M[i, k] >= merge_iou:
                out.append((t, o))
    return out


def joins(track, group: Group, ratio: float) -> bool:
    """Eq. 2.12: the share of the track's box inside the group's box is at least ``ratio``."""
    return box_overlap(track.box, group.box()) >= ratio


def update_groups(groups: list, tracks: list, matched: dict, n: int, cfg, next_id: int) -> int:
    """One frame of the group nodes (Sec. 2.5.2); returns the next free group id.

    ``tracks``: the tracks of this frame, ``matched``: index of a track -> its detection. A group
    lasts while one of its members is hidden inside it: a detected member stays as long as its box
    still overlaps a hidden member's (the detection shows the group's front), and leaves once it
    does not; when every member is detected again the group splits. A group left with fewer than
    two members dissolves. A confirmed track that lost its detection joins a group it lies mostly
    inside (Eq. 2.12) or forms one with a confirmed track it overlaps (Eq. 2.11).
    """
    index = {id(t): i for i, t in enumerate(tracks)}
    for g in list(groups):
        hidden = [m for m in g.members if index.get(id(m)) not in matched]
        for m in [m for m in g.members if index.get(id(m)) in matched]:
            if not hidden or float(np.max(intersection(np.array([h.box for h in hidden]), m.box))) <= 0:
                g.members.remove(m)
                m.group = None
        if len(g.members) < 2:
            for m in g.members:
                m.group = None
            groups.remove(g)
    conf = [t for t in tracks if t.state == "confirmed"]
    hidden = [t for i, t in enumerate(tracks) if i not in matched and t.state == "confirmed" and t.group is None]
    for t in list(hidden):
        g = next((g for g in groups if joins(t, g, cfg.join_ratio)), None)
        if g is not None:
            t.group = g
            g.members.append(t)
            hidden.remove(t)
    for t, o in occlusions(hidden, conf, cfg.merge_iou):
        if t.group is not None:
            continue
        if o.group is not None:
            t.group = o.group
            o.group.members.append(t)
            continue
        g = Group(next_id, [t, o], n)
        next_id += 1
        t.group = o.group = g
        groups.append(g)
    return next_id


def resolve_split(groups: list, tracks: list, pred: np.ndarray, dets: np.ndarray, matched: dict, det_hist) -> None:
    """When every member of a group is detected again (as many detections as members), their
    identities are re-solved by the KL divergence of RGB histograms plus ``1 - IoU`` with each
    member's prediction (Hungarian), Sec. 2.5.2. ``matched`` (track index -> detection index) is
    changed in place; ``det_hist(j)`` is the histogram of detection ``j``."""
    index = {id(t): i for i, t in enumerate(tracks)}
    for g in groups:
        rows = [index[id(m)] for m in g.members if id(m) in index]
        if len(rows) < 2 or len(rows) != len(g.members) or any(i not in matched for i in rows):
            continue
        if not any(tracks[i].misses > 0 for i in rows):
            continue
        cols = [matched[i] for i in rows]
        C = np.zeros((len(rows), len(cols)))
        M = iou_matrix(pred[rows], dets[cols, :4])
        for a, i in enumerate(rows):
            for b, j in enumerate(cols):
                C[a, b] = min(kl_divergence(tracks[i].hist, det_hist(j)), 10.0) + (1.0 - M[a, b])
        for a, b in assign(C):
            matched[rows[a]] = cols[b]


def group_events(res: np.ndarray, new: dict, group_log: dict, root, piece_span: dict, online: bool,
                 last_frame: int) -> list[dict]:
    """``merge``/``split`` events of the output tracks, from the groups' membership frame by frame.

    ``res``: output rows; ``new``: tracker id -> output id; ``group_log``: frame -> {group id:
    member tracker ids}; ``root``: tracker id -> the tracker id of the output track it ended up
    in (stitching); ``piece_span``: tracker id -> frames it gives the output (offline).

    A tracker track counts as a member on a frame only if the output shows it there under its
    output id (offline, stitched tracklets each own their part of the track). The events replay as
    a state machine: an output group starts (``merge``) when it has two such members; when someone
    joins, a ``merge`` lists all members; when someone leaves and two or more remain, a ``split``
    lists the members before and a ``merge`` (same group id) those who stay together; it ends
    (``split``) when fewer than two remain. A group still together on the sequence's last frame
    gets no ``split``; no track is in two groups at once.
    """
    present = {(int(f), int(i)) for f, i in res[:, :2]}
    boxes = {(int(r[0]), int(r[1])): r[2:6] for r in res}

    def members(n: int, raw: tuple) -> tuple:
        out = set()
        for i in raw:
            r = root(i)
            if r not in new or (n, new[r]) not in present:
                continue
            span = piece_span.get(i)
            if not online and span is not None and not span[0] <= n <= span[1]:
                continue
            out.add(new[r])
        return tuple(sorted(out)) if len(out) >= 2 else ()

    def event(kind: str, n: int, g: int, ids: tuple, at: int) -> dict:
        c = box_center(union_box([boxes[(at, i)] for i in ids]))
        return {"type": kind, "frame": int(n), "tracks": [int(i) for i in ids], "group": int(g),
                "x": round(float(c[0]), 1), "y": round(float(c[1]), 1)}

    events: list[dict] = []
    state: dict = {}   # group id -> (members, frame seen)
    for n in range(min(group_log, default=0), last_frame + 1):
        now = {g: members(n, raw) for g, raw in group_log.get(n, {}).items()}
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


def collapse_group_flicker(events: list[dict], hold: int) -> list[dict]:
    """One real interaction gives one ``merge`` and one ``split`` (hysteresis on group events).

    A ``split`` followed within ``hold`` frames by a ``merge`` of the same members (or of a group
    containing them all) did not hold: both are dropped and the new group continues the old one
    (its id is replaced by the old group's, in every later event). ``events`` are merge/split
    dicts with ``tracks`` and ``group``; returns them in chronological order.
    """
    order_key = {"split": 0, "merge": 1}
    evs = sorted(events, key=lambda e: (e["frame"], order_key.get(e["type"], 2), e["tracks"]))
    # a group's id in the input -> the id of the group it continues in the output: one lookup,
    # not a chain (an id may be used again for another group; chasing renames through such ids
    # once ran in a cycle for ever)
    rename: dict[int, int] = {}
    pending: list[tuple[int, dict]] = []   # (index in out, split event) waiting for a re-merge
    out: list[dict | None] = []
    for ev in evs:
        ev = dict(ev)
        raw = ev.get("group")
        if raw is not None:
            ev["group"] = rename.get(raw, raw)
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
                if raw is not None and "group" in s and ev["group"] != s["group"]:
                    rename[raw] = ev["group"] = s["group"]
                if set(ev["tracks"]) == set(s["tracks"]):
                    continue                       # ... and the re-merge continues the same group
                # someone else joined while the group re-formed: a merge into the old group
        out.append(ev)
        if ev["type"] == "split":
            pending.append((len(out) - 1, ev))
    return [e for e in out if e is not None]
