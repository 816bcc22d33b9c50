"""Data association: which detection belongs to which track (thesis Sec. 2.4.1, Eq. 2.4).

Eq. 2.4 admits a detection for an entity when its score passes a threshold and it intersects the
entity's box; with many entities the choice must also be one-to-one, so the tracker solves it as
an assignment problem (Hungarian algorithm) on ``1 - IoU`` between the predicted boxes and the
detections, optionally plus the KL divergence of their colour histograms (Sec. 2.5.2's
appearance model), with the intersection condition as a gate (IoU at least ``gate``). (A likelihood cost under the Kalman
prediction with a χ² gate was tried and dropped: detection errors are heavy-tailed — a box cut by
an occluder — so 7-15 % of true matches fall outside a 99 % gate; docs/tracking.md.)
Detections come in two strengths, as in ByteTrack: high-score detections are associated first,
with every track; low-score ones only with tracks that were seen on the previous frame, where a
weak detection is almost certainly the same person (occluded, blurred) and not a false alarm.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from artmotion.geometry import iou_matrix

__all__ = ["INF", "assign", "iou_cost"]

#: cost of a forbidden pair
INF = 1e6


def iou_cost(pred: np.ndarray, dets: np.ndarray, gate: float) -> tuple[np.ndarray, np.ndarray]:
    """``(cost, iou)``: ``1 - IoU`` between predicted boxes and detection boxes, :data:`INF`
    where the IoU is below ``gate`` (the intersection condition of Eq. 2.4)."""
    M = iou_matrix(pred, dets)
    return np.where(M >= gate, 1.0 - M, INF), M


def assign(cost: np.ndarray) -> list[tuple[int, int]]:
    """One-to-one assignment minimising ``cost``; pairs at :data:`INF` are never returned.

    The same answer as SciPy's ``linear_sum_assignment`` on the matrix (as many allowed pairs as
    possible, then the least cost), found cheaply for the small problems of one frame: when every
    row's cheapest allowed column is a different one, that is the optimum; otherwise the rows and
    columns fall into independent groups (people competing for the same detections), each solved
    exactly by :func:`hungarian`. SciPy (0.4 s to import) is used only for a group larger than
    16 × 16, which only crowds give.
    """
    if cost.size == 0:
        return []
    allowed = cost < INF
    rows = np.flatnonzero(allowed.any(axis=1))
    if not len(rows):
        return []
    best = np.argmin(np.where(allowed, cost, np.inf), axis=1)[rows]
    if len(set(best.tolist())) == len(rows):     # (np.unique would import numpy.ma: start-up)
        return [(int(i), int(j)) for i, j in zip(rows, best)]
    out = []
    for r, c in _groups(allowed):
        sub = cost[np.ix_(r, c)]
        pairs: Iterable[tuple[int, int]]
        if len(r) == 1:          # one track: its cheapest detection (what the Hungarian finds)
            pairs = [(0, int(np.argmin(sub[0])))]
        elif len(c) == 1:        # one detection: its cheapest track
            pairs = [(int(np.argmin(sub[:, 0])), 0)]
        elif max(sub.shape) > 16:
            from scipy.optimize import linear_sum_assignment

            pairs = zip(*linear_sum_assignment(sub))
        else:
            pairs = hungarian(sub)
        out += [(int(r[i]), int(c[j])) for i, j in pairs if sub[i, j] < INF]
    return sorted(out)


def _groups(allowed: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Connected components (row indices, column indices) of the bipartite graph of allowed pairs
    (union-find over the pairs; rows are nodes ``0..n-1``, columns ``n..n+m-1``)."""
    n, m = allowed.shape
    parent = list(range(n + m))

    def root(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for i, j in zip(*np.nonzero(allowed)):
        a, b = root(int(i)), root(n + int(j))
        if a != b:
            parent[max(a, b)] = min(a, b)
    members: dict[int, tuple[list[int], list[int]]] = {}
    for i in np.flatnonzero(allowed.any(axis=1)).tolist():
        members.setdefault(root(i), ([], []))[0].append(i)
    for j in np.flatnonzero(allowed.any(axis=0)).tolist():
        members[root(n + j)][1].append(j)
    return [(np.array(r), np.array(c)) for r, c in members.values()]


def hungarian(cost: np.ndarray) -> list[tuple[int, int]]:
    """Minimum-cost assignment of a small ``(n, m)`` matrix (every row of the smaller side
    assigned): the Hungarian algorithm with row and column potentials and shortest augmenting
    paths (Kuhn-Munkres, O(n² m)), the inner loop vectorised over the columns."""
    a = np.asarray(cost, dtype=float)
    flip = a.shape[0] > a.shape[1]
    if flip:
        a = a.T
    n, m = a.shape
    u = np.zeros(n + 1)
    v = np.zeros(m + 1)
    p = np.zeros(m + 1, dtype=int)          # p[j]: the row (1-based) assigned to column j, 0: none
    way = np.zeros(m + 1, dtype=int)
    for i in range(1, n + 1):
        p[0] = i
        j0 = 0
        minv = np.full(m + 1, np.inf)
        used = np.zeros(m + 1, dtype=bool)
        while True:
            used[j0] = True
            i0 = p[j0]
            free = ~used
            free[0] = False
            red = a[i0 - 1] - u[i0] - v[1:]       # reduced costs from row i0, columns 1..m
            better = free[1:] & (red < minv[1:])
            minv[1:][better] = red[better]
            way[1:][better] = j0
            cand = np.where(free, minv, np.inf)
            j1 = int(np.argmin(cand))
            delta = cand[j1]
            u[p[used]] += delta
            v[used] -= delta
            minv[free] -= delta
            j0 = j1
            if p[j0] == 0:
                break
        while j0:
            j1 = way[j0]
            p[j0] = p[j1]
            j0 = j1
    pairs = [(int(p[j]) - 1, j - 1) for j in range(1, m + 1) if p[j]]
    return sorted((j, i) for i, j in pairs) if flip else sorted(pairs)
