"""The offline pass (thesis Sec. 2.5.3): trajectories through the gaps, once the sequence is over.

Online, a track's box on a frame is what its filter knew then. Offline, every frame of a track
can use the whole track: the **Rauch–Tung–Striebel smoother** runs each track's Kalman filter
(:mod:`~artmotion.tracking.state`) backwards over the history the online pass kept (predicted and
filtered states, camera warps). Between two detections the smoothed state is the constant-velocity
interpolation of Sec. 2.5.3 (Fig. 2.6) — through a group node, a missed detection or an occlusion
— weighted by how certain each end is; on detected frames it removes the detector's per-frame
jitter without lagging. Gaps longer than ``max_interp`` seconds are not filled (the person may
have gone anywhere).

**Stitching** (optional) joins a tracklet that ends and one that starts within ``max_gap``
seconds when the constant-velocity extrapolation meets the new start, the sizes agree and the
colour histograms are close (Sec. 2.5.3-2.5.4); a gap of at most ``max_interp`` seconds is
interpolated linearly, a longer one only joins the identities (as inside a track).

**Duplicates** (:func:`duplicates`): one person detected twice — an upper-body box inside the
full-body box, or the same person at two scales — becomes two tracks, one box inside the other,
moving together. A track whose box lies inside a larger track's on a share of its frames
(``duplicate_share``) and keeps its place there (its centre relative to the container, in
container heights, varies by less than ``duplicate_drift``) is the same object: the detector's
weaker hypothesis (the lower mean detection score over the shared frames, a frame without
detection counting 0) is dropped on the shared frames (an inner track nested on most of its
frames, whole). A person walking behind another moves relative to them, so is kept.
"""

from __future__ import annotations

import numpy as np

from artmotion.geometry import box_center, box_from_center
from artmotion.tracking.appearance import kl_divergence
from artmotion.tracking.state import DETECTED, GROUP, INTERPOLATED, TENTATIVE, boxes_to_z, z_to_boxes

__all__ = ["duplicates", "rts_smooth", "stitch", "track_pieces"]


def _transition(dt: float) -> np.ndarray:
    F = np.eye(8)
    F[np.arange(4), np.arange(4) + 4] = dt
    return F


def rts_smooth(xp, Pp, xf, Pf, warps, dt: float) -> np.ndarray:
    """Rauch–Tung–Striebel smoothed states ``(K, 8)`` of one track's filter history.

    ``xp, Pp``: predicted state and covariance on each frame (the first is the initial state),
    ``xf, Pf``: filtered ones, ``warps``: the 8×8 camera transform applied before each prediction
    (``None``: none). The transition into frame ``k`` is ``F T_k``.
    """
    xp, Pp, xf, Pf = (np.asarray(a, dtype=float) for a in (xp, Pp, xf, Pf))
    K = len(xf)
    xs = xf.copy()
    if K < 2:
        return xs
    F = _transition(dt)
    Fk = np.broadcast_to(F, (K - 1, 8, 8)).copy()
    for k, T in enumerate(warps[1:]):
        if T is not None:
            Fk[k] = F @ T
    # C_k = Pf_k F_{k+1}' Pp_{k+1}^-1, all at once; then the backward recursion on the means
    G = np.einsum("kij,kjl->kil", Fk, Pf[:-1])                     # F_{k+1} Pf_k
    Pp1 = Pp[1:] + 1e-9 * np.eye(8)
    C = np.linalg.solve(Pp1, G).transpose(0, 2, 1)
    for k in range(K - 2, -1, -1):
        xs[k] = xf[k] + C[k] @ (xs[k + 1] - xp[k + 1])
    return xs


def _boxes(x: np.ndarray) -> np.ndarray:
    z = x[:, :4].copy()
    z[:, 2:4] = np.maximum(z[:, 2:4], 1.0)
    return z_to_boxes(z)


def track_pieces(track, dt: float, smooth: bool, max_interp: int, tail: int) -> dict:
    """A track's output: ``{frame: [box, kind, score]}``.

    Frames with a detection (before and after confirmation), gaps between detections of at most
    ``max_interp`` frames (smoothed, or linearly interpolated without ``smooth``), and up to
    ``tail`` frames after the last detection.
    """
    kinds = np.asarray(track.kinds)
    detected = np.flatnonzero((kinds == DETECTED) | (kinds == TENTATIVE))
    if not len(detected):
        return {}
    last = int(detected[-1])
    frames = track.frames
    if smooth:
        end = min(len(frames), last + 1 + tail)
        xs = rts_smooth(track.xp[:end], track.Pp[:end], track.xf[:end], track.Pf[:end], track.warps[:end], dt)
        boxes = _boxes(xs)
    else:
        boxes = _boxes(np.asarray(track.xf))
    out = {}
    for i in detected:
        out[frames[i]] = [boxes[i], int(kinds[i]), track.scores[i]]
    for a, b in zip(detected[:-1], detected[1:]):
        if b - a <= 1 or b - a - 1 > max_interp:
            continue
        for k in range(a + 1, b):
            if smooth:
                box = boxes[k]
            else:
                u = (k - a) / (b - a)
                box = (1 - u) * boxes[a] + u * boxes[b]
            out[frames[k]] = [box, int(kinds[k]) if kinds[k] == GROUP else INTERPOLATED, 0.0]
    for k in range(last + 1, min(len(frames), last + 1 + tail)):
        out[frames[k]] = [boxes[k], int(kinds[k]), 0.0]
    return out


def _end_state(rec: dict, at_start: bool, k: int, camera=None):
    """Frame, position, velocity (px/frame) and size at one end of a tracklet, from its detections
    (in the first frame's pixels when ``camera``, a :class:`~artmotion.tracking.camera.CameraPath`,
    has motion)."""
    fs = sorted(f for f in rec if rec[f][1] in (DETECTED, TENTATIVE)) or sorted(rec)
    fs = fs[:k] if at_start else fs[-k:]
    boxes = np.array([rec[f][0] for f in fs], dtype=float)
    if camera:
        boxes = np.vstack([camera.to_ref(f, b) for f, b in zip(fs, boxes)])
    z = boxes_to_z(boxes)                      # centres and sizes
    i_end = 0 if at_start else len(fs) - 1
    v = (z[-1, :2] - z[0, :2]) / (fs[-1] - fs[0]) if len(fs) >= 2 and fs[-1] > fs[0] else np.zeros(2)
    return fs[i_end], z[i_end, :2], v, np.median(z[:, 2:4], axis=0)


def _interpolate(rec: dict, a: int, b: int, camera=None) -> None:
    """Fill the frames between ``a`` and ``b`` linearly (in the first frame's pixels when the
    camera moved: a still person stays on the background they stand on)."""
    ba, bb = np.asarray(rec[a][0], dtype=float), np.asarray(rec[b][0], dtype=float)
    if camera:
        ba, bb = camera.to_ref(a, ba)[0], camera.to_ref(b, bb)[0]
    ca, cb = box_center(ba), box_center(bb)
    sa, sb = ba[2:4], bb[2:4]
    for f in range(a + 1, b):
        u = (f - a) / (b - a)
        box = box_from_center((1 - u) * ca + u * cb, (1 - u) * sa + u * sb)
        if camera:
            box = camera.from_ref(f, box)[0]
        rec[f] = [box, INTERPOLATED, 0.0]


def stitch(pieces: dict, hists: dict, cfg, fps: float, camera=None) -> tuple[dict, dict, dict]:
    """Join tracklets of one person across a gap (motion and appearance agree), Sec. 2.5.3-2.5.4.

    Returns ``(pieces, relabel, span)``: the joined pieces, ``relabel`` (tracker id of a joined
    tracklet -> id of the tracklet it continues) and ``span`` (tracker id -> frames it gives the
    output). A tracklet ending at frame ``a`` and one starting at ``b > a`` within ``max_gap``
    seconds are the same person when the constant-velocity extrapolation meets the new start
    within a distance that grows with the gap, the box sizes agree and the RGB histograms are
    close (KL divergence). With ``camera`` (:class:`~artmotion.tracking.camera.CameraPath`) the
    extrapolation and the filled gap are in the first frame's pixels: the camera's own motion over
    the gap is taken out, as in the online prediction.
    """
    span = {i: (min(r), max(r)) for i, r in pieces.items() if r}
    relabel: dict[int, int] = {}
    if not cfg.stitch or len(pieces) < 2:
        return pieces, relabel, span
    k = max(2, int(round(0.5 * fps)))
    max_gap = max(1, int(round(cfg.max_gap * fps)))
    max_fill = int(round(cfg.max_interp * fps)) if cfg.max_interp > 0 else 0
    starts = {j: _end_state(r, True, k, camera) for j, r in pieces.items()}
    cand = []
    for i, ri in pieces.items():
        fa, ca, va, sa = _end_state(ri, False, k, camera)
        for j in pieces:
            if i == j or span[j][0] <= span[i][1]:
                continue
            fb, cb, _, sb = starts[j]
            gap = fb - fa
            if gap < 1 or gap > max_gap or not 0.67 < sb[1] / sa[1] < 1.5:
                continue
            h = 0.5 * (sa[1] + sb[1])
            tol = h * (cfg.stitch_dist + cfg.stitch_speed * gap / fps)
            d = float(np.linalg.norm(ca + va * gap - cb))
            kl = kl_divergence(hists.get(i), hists.get(j))
            if d > tol or not kl <= cfg.stitch_kl:
                continue
            cand.append((d / tol + kl / cfg.stitch_kl, i, j))
    cand.sort()
    nxt: dict[int, int] = {}
    prv: dict[int, int] = {}
    for _, i, j in cand:
        if i in nxt or j in prv:
            continue
        q = j
        while q in nxt:
            q = nxt[q]
        if q == i:
            continue
        nxt[i], prv[j] = j, i
    out = {}
    for i in pieces:
        if i in prv:
            continue
        rec = dict(pieces[i])
        q = i
        while q in nxt:
            j = nxt[q]
            fa = _end_state(rec, False, k)[0]
            fb = _end_state(pieces[j], True, k)[0]
            rec = {f: v for f, v in rec.items() if f <= fa}
            rec.update({f: v for f, v in pieces[j].items() if f >= fb})
            span[q] = (span[q][0], fb - 1)
            span[j] = (fb, span[j][1])
            if fb - fa - 1 <= max_fill:
                _interpolate(rec, fa, fb, camera)
            relabel[j] = i
            q = j
        out[i] = rec
    return out, relabel, span


#: share of a box's area inside another that makes it nested in it
NESTED = 0.8


def _nested_pairs(pieces: dict) -> dict:
    """``{(inner, outer): rows}`` of the frames where ``inner``'s box lies (``NESTED``) inside the
    larger box of ``outer`` (the most-covering one); each row: frame, the inner centre relative to
    the outer one (x, y, in outer heights), the two detection scores (0 where not detected)."""
    by_frame: dict[int, list] = {}
    for tid, rec in pieces.items():
        for f, (box, kind, score) in rec.items():
            det = kind in (DETECTED, TENTATIVE)
            by_frame.setdefault(f, []).append((tid, *box, score if det else 0.0))
    out: dict[tuple[int, int], list] = {}
    for f, items in by_frame.items():
        if len(items) < 2:
            continue
        a = np.asarray(items, dtype=float)
        x, y, w, h = a[:, 1], a[:, 2], a[:, 3], a[:, 4]
        ix = np.minimum(x[:, None] + w[:, None], x + w) - np.maximum(x[:, None], x)
        iy = np.minimum(y[:, None] + h[:, None], y + h) - np.maximum(y[:, None], y)
        area = w * h
        share = np.clip(ix, 0, None) * np.clip(iy, 0, None) / np.maximum(area, 1e-9)[:, None]
        share[area[None, :] <= area[:, None]] = 0.0     # only inside a larger box (and not itself)
        for i in np.flatnonzero(share.max(axis=1) >= NESTED):
            j = int(np.argmax(share[i]))
            rel = ((x[i] + w[i] / 2 - x[j] - w[j] / 2) / h[j], (y[i] + h[i] / 2 - y[j] - h[j] / 2) / h[j])
            out.setdefault((int(a[i, 0]), int(a[j, 0])), []).append((f, *rel, a[i, 5], a[j, 5]))
    return out


def duplicates(pieces: dict, share: float, drift: float) -> dict:
    """``pieces`` without the second track of one object (module doc, "Duplicates"): a track nested
    in the same larger track on at least ``share`` of its frames (and two), with its relative
    centre's standard deviation (both axes, in the container's heights) below ``drift``; of the two,
    the one with the lower mean detection score over those frames loses them — the inner track all
    of its frames when they are most of them (the rest would be fragments). ``share <= 0``: off."""
    if share <= 0 or len(pieces) < 2:
        return pieces
    pairs = _nested_pairs(pieces)
    container: dict[int, int] = {}      # inner track -> the larger track it is most often nested in
    for inner, outer in pairs:
        if inner not in container or len(pairs[(inner, outer)]) > len(pairs[(inner, container[inner])]):
            container[inner] = outer
    gone: set[int] = set()
    lost: dict[int, set] = {}
    for inner, outer in container.items():
        rows = np.asarray(pairs[(inner, outer)])
        if len(rows) < max(2.0, share * len(pieces[inner])):
            continue
        if float(np.sqrt(rows[:, 1:3].var(axis=0).sum())) >= drift:
            continue
        loser = inner if rows[:, 3].mean() <= rows[:, 4].mean() else outer
        if loser == inner and 2 * len(rows) >= len(pieces[inner]):
            gone.add(inner)     # mostly a duplicate: what is left of it would be fragments
        else:
            lost.setdefault(loser, set()).update(int(f) for f in rows[:, 0])
    out = {}
    for tid, rec in pieces.items():
        if tid in gone:
            continue
        if tid in lost:
            rec = {f: v for f, v in rec.items() if f not in lost[tid]}
        if rec:
            out[tid] = rec
    return out
