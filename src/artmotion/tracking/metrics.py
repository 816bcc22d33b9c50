"""Multi-object tracking scores: CLEAR MOT, identity (IDF1) and HOTA.

Our own implementation of the definitions, following the conventions of TrackEval's
``MotChallenge2DBox`` for the MOT15 benchmark, so that the numbers agree with it:

* boxes are ``x, y, w, h`` (columns 2..5); the similarity is their IoU;
* ground-truth rows whose confidence column (6) truncates to 0 are ignored;
* MOT15 rules (10-column ground truth, no classes): result rows are all kept;
* MOT16/17 rules (9-column ground truth ``frame,id,x,y,w,h,consider,class,visibility``: a file's
  column count decides, an array's class column, or ``rules="mot17"``): only class 1 (pedestrian) with
  consider = 1 is ground truth, and a result box matched (Hungarian on IoU >= 0.5, per frame) to a
  ground-truth box of a distractor class (2 person on vehicle, 7 static person, 8 distractor,
  12 reflection) is removed before scoring -- TrackEval's ``BENCHMARK=MOT17`` preprocessing;
* an id may appear at most once per frame, in the ground truth and in the results.

CLEAR MOT (Bernardin & Stiefelhagen 2008) matches per frame with the Hungarian algorithm on IoU
``>= iou_threshold``, preferring to continue the match of the previous frame; MOTP is the mean IoU
of the matches (in [0, 1], as TrackEval reports it). IDF1 (Ristani et al. 2016) uses one global
min-cost bipartite matching between ground-truth and result identities. HOTA (Luiten et al. 2021)
is averaged over the localisation thresholds ``alpha = 0.05, 0.10, ..., 0.95``.
See docs/metrics.md.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from artmotion.errors import InputError, check_bool, check_range
from artmotion.geometry import iou_matrix
from artmotion.io import read_mot
from artmotion.io.mot import MOT17_CLASSES, MOT17_PEDESTRIAN, check_ids, check_mot_rows, mot_columns

__all__ = ["apply_rules", "check_ids", "check_rules", "columns_of", "evaluate", "evaluate_sequences", "format_table",
           "gt_rules", "HOTA_ALPHAS", "METRIC_ORDER"]

EPS = np.finfo(float).eps

#: The HOTA localisation thresholds (the same floats TrackEval uses).
HOTA_ALPHAS = np.arange(0.05, 0.99, 0.05)
#: Keys in the order the CLI prints them.
METRIC_ORDER = (
    "MOTA", "MOTP", "IDF1", "IDP", "IDR", "HOTA", "DetA", "AssA", "LocA",
    "GT", "MT", "PT", "ML", "FM", "IDS", "FP", "FN", "TP", "GT_DETS", "Precision", "Recall",
)


#: MOT16/17 classes: 1 pedestrian ... 13; a result box on one of these is not a false positive.
MOT17_DISTRACTORS = (2, 7, 8, 12)
RULES = ("auto", "mot15", "mot17")


def gt_rules(gt: np.ndarray, columns: int | None = None) -> str:
    """``"mot17"`` if the ground truth is MOT16/17's, else ``"mot15"``. ``columns``: the columns as
    written (a file's, before :func:`read_mot` pads them): 9 is MOT16/17's, anything else MOT15's,
    so that a class MOT17 does not know is an error, not a silent switch of rules. Without it (a
    padded array), MOT16/17's when column 8 holds classes 1..13 on every row, where MOT15 files
    hold -1 or world coordinates."""
    if columns is not None:
        return "mot17" if columns == 9 else "mot15"
    if not len(gt):
        return "mot15"
    cls = gt[:, 7]
    return "mot17" if bool(np.all(np.isin(cls, list(MOT17_CLASSES)))) and bool(np.all(gt[:, 9] == -1)) else "mot15"


def columns_of(gt) -> int | None:
    """The columns of ground truth ``gt`` as written, for :func:`gt_rules`: a MOTChallenge file's,
    an array's when it has 9 (an array of 10 may be a padded MOT16/17 file: ``None``)."""
    if isinstance(gt, (str, os.PathLike)):
        return mot_columns(gt)
    shape = np.shape(gt)
    return 9 if len(shape) == 2 and shape[1] == 9 else None


def _remove_distractor_matches(gt: np.ndarray, res: np.ndarray) -> np.ndarray:
    """Drop result rows matched (per frame, Hungarian on IoU >= 0.5) to a distractor-class box.

    TrackEval's MOT17 preprocessing: the matching uses every ground-truth box of the frame, also
    those with consider = 0.
    """
    keep = np.ones(len(res), bool)
    g_frames = gt[:, 0].astype(int)
    r_frames = res[:, 0].astype(int)
    for f in np.intersect1d(g_frames, r_frames):
        gi = np.flatnonzero(g_frames == f)
        ri = np.flatnonzero(r_frames == f)
        sim = iou_matrix(gt[gi, 2:6], res[ri, 2:6])
        sim[sim < 0.5 - EPS] = 0
        rows, cols = linear_sum_assignment(-sim)
        ok = sim[rows, cols] > EPS
        rows, cols = rows[ok], cols[ok]
        distractor = np.isin(gt[gi[rows], 7], MOT17_DISTRACTORS)
        keep[ri[cols[distractor]]] = False
    return res[keep]


def apply_rules(gt: np.ndarray, res: np.ndarray, rules: str) -> tuple[np.ndarray, np.ndarray]:
    """Ground truth and results as they are scored under ``rules`` (see the module docstring)."""
    if rules not in RULES:
        raise InputError(f"unknown rules {rules!r} (choose from {', '.join(RULES)})")
    if rules == "auto":
        rules = gt_rules(gt)
    if rules == "mot17":
        if len(res) and len(gt):
            res = _remove_distractor_matches(gt, res)
        gt = gt[gt[:, 7] == MOT17_PEDESTRIAN]
    # Every benchmark: gt rows with confidence 0 ("zero marked", consider = 0) are not evaluated.
    return gt[np.trunc(gt[:, 6]) != 0], res


@dataclass
class _Frames:
    """Per-frame data with ids relabelled to ``0..n-1``."""

    gt_ids: list[np.ndarray]
    tr_ids: list[np.ndarray]
    sims: list[np.ndarray]
    num_gt_ids: int
    num_tr_ids: int
    num_gt_dets: int
    num_tr_dets: int
    num_frames: int


def _load(x, what: str) -> tuple[np.ndarray, str | None]:
    """A ``(N, >=7)`` float array from a path or array, validated; and the path if any."""
    if isinstance(x, (str, os.PathLike)):
        return read_mot(x), os.fspath(x)
    arr = check_mot_rows(x, what)
    if arr.size == 0:
        return np.zeros((0, 10)), None
    # pad like read_mot: conf = 1 (every row counts), the other columns -1
    pad = np.array([1.0, -1.0, -1.0, -1.0])[max(0, arr.shape[1] - 6):]
    if len(pad):
        arr = np.hstack([arr, np.tile(pad, (len(arr), 1))])
    return arr, None


def _prepare(gt: np.ndarray, res: np.ndarray) -> _Frames:
    # Relabel ids to 0..n-1 (sorted, as TrackEval does) and group rows by frame, keeping file order.
    gt_u, gt_lab = np.unique(gt[:, 1], return_inverse=True)
    tr_u, tr_lab = np.unique(res[:, 1], return_inverse=True)
    frames = np.union1d(gt[:, 0], res[:, 0]).astype(int)
    g_order = np.argsort(gt[:, 0], kind="stable")
    r_order = np.argsort(res[:, 0], kind="stable")
    g_bounds = np.searchsorted(gt[g_order, 0], frames, side="left"), np.searchsorted(gt[g_order, 0], frames, side="right")
    r_bounds = np.searchsorted(res[r_order, 0], frames, side="left"), np.searchsorted(res[r_order, 0], frames, side="right")
    gt_ids, tr_ids, sims = [], [], []
    for k in range(len(frames)):
        gi = g_order[g_bounds[0][k] : g_bounds[1][k]]
        ri = r_order[r_bounds[0][k] : r_bounds[1][k]]
        gt_ids.append(gt_lab[gi].astype(int).ravel())
        tr_ids.append(tr_lab[ri].astype(int).ravel())
        sims.append(iou_matrix(gt[gi, 2:6], res[ri, 2:6]))
    last = int(frames.max()) if len(frames) else 0
    return _Frames(gt_ids, tr_ids, sims, len(gt_u), len(tr_u), len(gt), len(res), last)


def _clear(d: _Frames, thr: float) -> dict:
    """CLEAR MOT counts with TrackEval's matching and bookkeeping."""
    G = d.num_gt_ids
    tp = fn = fp = ids = 0
    motp_sum = 0.0
    gt_frames = np.zeros(G)  # frames in which each gt id is present
    gt_matched = np.zeros(G)  # frames in which it is matched
    gt_frag = np.zeros(G)  # number of tracked stretches
    last_id = np.full(G, np.nan)  # tracker id of the last match, any time ago (for IDS)
    prev_id = np.full(G, np.nan)  # tracker id matched in the previous evaluated frame (for continuity)
    for g, t, sim in zip(d.gt_ids, d.tr_ids, d.sims):
        if len(g) == 0:
            fp += len(t)
            continue
        if len(t) == 0:
            fn += len(g)
            gt_frames[g] += 1
            continue
        # Continue last frame's matches first (weight 1000), then maximise the IoU.
        score = 1000.0 * (t[None, :] == prev_id[g][:, None]) + sim
        score[sim < thr - EPS] = 0
        rows, cols = linear_sum_assignment(-score)
        ok = score[rows, cols] > EPS
        rows, cols = rows[ok], cols[ok]
        mg, mt = g[rows], t[cols]
        before = last_id[mg]
        ids += int(np.sum(~np.isnan(before) & (mt != before)))
        gt_frames[g] += 1
        gt_matched[mg] += 1
        was_tracked = ~np.isnan(prev_id)
        last_id[mg] = mt
        prev_id[:] = np.nan
        prev_id[mg] = mt
        gt_frag += ~was_tracked & ~np.isnan(prev_id)
        n = len(rows)
        tp += n
        fn += len(g) - n
        fp += len(t) - n
        motp_sum += float(sim[rows, cols].sum())
    present = gt_frames > 0
    ratio = gt_matched[present] / gt_frames[present]
    mt_ = int(np.sum(ratio > 0.8))
    pt_ = int(np.sum(ratio >= 0.2)) - mt_
    ml_ = G - mt_ - pt_
    frag = int(np.sum(gt_frag[gt_frag > 0] - 1))
    n_gt = max(1, tp + fn)
    # MOTA is undefined without ground truth; report 0 then, as TrackEval does.
    mota = (tp - fp - ids) / n_gt if tp + fn else 0.0
    moda = (tp - fp) / n_gt if tp + fn else 0.0
    return {
        "MOTA": mota,
        "MOTP": motp_sum / max(1, tp),
        "MODA": moda,
        "MT": mt_, "PT": pt_, "ML": ml_, "FM": frag, "IDS": ids,
        "TP": tp, "FP": fp, "FN": fn, "GT": G, "GT_DETS": tp + fn,
        "Precision": tp / max(1, tp + fp), "Recall": tp / n_gt,
    }


def _identity(d: _Frames, thr: float) -> dict:
    """IDF1: the identity matching that maximises the number of frames two identities agree."""
    agree = np.zeros((d.num_gt_ids, d.num_tr_ids))
    for g, t, sim in zip(d.gt_ids, d.tr_ids, d.sims):
        gi, ti = np.nonzero(sim >= thr)
        np.add.at(agree, (g[gi], t[ti]), 1)
    # Min IDFN + IDFP = |gt| + |res| - 2 IDTP: the min-cost bipartite matching maximises IDTP.
    idtp = 0
    if agree.size:
        rows, cols = linear_sum_assignment(-agree)
        idtp = int(round(agree[rows, cols].sum()))
    idfn = d.num_gt_dets - idtp
    idfp = d.num_tr_dets - idtp
    return {
        "IDF1": idtp / max(1.0, idtp + 0.5 * idfp + 0.5 * idfn),
        "IDP": idtp / max(1, idtp + idfp),
        "IDR": idtp / max(1, idtp + idfn),
        "IDTP": idtp, "IDFP": idfp, "IDFN": idfn,
    }


def _hota(d: _Frames) -> dict:
    """HOTA, DetA, AssA, LocA averaged over the alphas (and per alpha under ``*_alpha``)."""
    G, T = d.num_gt_ids, d.num_tr_ids
    A = len(HOTA_ALPHAS)
    gt_count = np.zeros(G)
    tr_count = np.zeros(T)
    soft = np.zeros((G, T))  # soft co-occurrence, each frame's IoU normalised like a Jaccard
    for g, t, sim in zip(d.gt_ids, d.tr_ids, d.sims):
        gt_count[g] += 1
        tr_count[t] += 1
        if sim.size:
            denom = sim.sum(0)[None, :] + sim.sum(1)[:, None] - sim
            j = np.zeros_like(sim)
            mask = denom > EPS
            j[mask] = sim[mask] / denom[mask]
            soft[g[:, None], t[None, :]] += j
    with np.errstate(invalid="ignore", divide="ignore"):
        align = soft / (gt_count[:, None] + tr_count[None, :] - soft)
    tp = np.zeros(A)
    fn = np.zeros(A)
    fp = np.zeros(A)
    loc = np.zeros(A)
    mg_all, mt_all, ms_all = [], [], []
    for g, t, sim in zip(d.gt_ids, d.tr_ids, d.sims):
        if len(g) == 0 or len(t) == 0:
            fp += len(t)
            fn += len(g)
            continue
        rows, cols = linear_sum_assignment(-(align[g[:, None], t[None, :]] * sim))
        s = sim[rows, cols]
        n = (s[None, :] >= HOTA_ALPHAS[:, None] - EPS).sum(1)
        tp += n
        fn += len(g) - n
        fp += len(t) - n
        mg_all.append(g[rows])
        mt_all.append(t[cols])
        ms_all.append(s)
    ass_a, ass_re, ass_pr = np.zeros(A), np.zeros(A), np.zeros(A)
    if mg_all:
        mg, mt, ms = np.concatenate(mg_all), np.concatenate(mt_all), np.concatenate(ms_all)
        for a, alpha in enumerate(HOTA_ALPHAS):
            keep = ms >= alpha - EPS
            loc[a] = ms[keep].sum()
            pair, count = np.unique(mg[keep] * T + mt[keep], return_counts=True)
            pg, pt = pair // T, pair % T
            c = count.astype(float)
            denom = max(1.0, tp[a])
            ass_a[a] = np.sum(c * c / np.maximum(1, gt_count[pg] + tr_count[pt] - c)) / denom
            ass_re[a] = np.sum(c * c / np.maximum(1, gt_count[pg])) / denom
            ass_pr[a] = np.sum(c * c / np.maximum(1, tr_count[pt])) / denom
    det_a = tp / np.maximum(1, tp + fn + fp)
    det_re = tp / np.maximum(1, tp + fn)
    det_pr = tp / np.maximum(1, tp + fp)
    hota = np.sqrt(det_a * ass_a)
    loc_a = np.maximum(1e-10, loc) / np.maximum(1e-10, tp)
    if d.num_gt_dets == 0 or d.num_tr_dets == 0:
        loc_a = np.ones(A)
    return {
        "HOTA": float(hota.mean()), "DetA": float(det_a.mean()), "AssA": float(ass_a.mean()),
        "LocA": float(loc_a.mean()), "DetRe": float(det_re.mean()), "DetPr": float(det_pr.mean()),
        "AssRe": float(ass_re.mean()), "AssPr": float(ass_pr.mean()),
        "HOTA(0)": float(hota[0]),
        "HOTA_alpha": hota.tolist(), "DetA_alpha": det_a.tolist(), "AssA_alpha": ass_a.tolist(),
    }


def _load_pair(gt, res, rules: str, k: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Ground truth and results read, validated and prepared under ``rules``."""
    suffix = f" #{k + 1}" if k is not None else ""
    gt_arr, gt_path = _load(gt, "ground truth" + suffix)
    res_arr, res_path = _load(res, "results" + suffix)
    check_ids(gt_arr, "ground truth", gt_path)
    check_ids(res_arr, "results", res_path)
    rules = check_rules(gt_arr, rules, columns_of(gt), gt_path)
    return apply_rules(gt_arr, res_arr, rules)


def check_rules(gt: np.ndarray, rules: str, columns: int | None = None, path: str | os.PathLike | None = None) -> str:
    """The rules ``gt`` is scored by (``"auto"`` resolved by :func:`gt_rules` with the ``columns``
    as written); under MOT16/17's, an :class:`InputError` naming ``path`` for a class they do not
    know (as TrackEval: an error, not a silent non-pedestrian) or no class column."""
    if rules not in RULES:
        raise InputError(f"unknown rules {rules!r} (choose from {', '.join(RULES)})")
    if rules == "auto":
        rules = gt_rules(gt, columns)
    if rules == "mot17" and len(gt):
        bad = ~np.isin(gt[:, 7], list(MOT17_CLASSES))
        if bad.all() and np.all(gt[:, 7] == -1):
            raise InputError("no class column: MOT16/17 ground truth has 9 columns "
                             "(frame,id,x,y,w,h,consider,class,visibility)", path=path)
        if bad.any():
            raise InputError(f"class {gt[bad, 7][0]:g} (frame {int(gt[bad, 0][0])}) is not a MOT16/17 class "
                             f"({min(MOT17_CLASSES)}-{max(MOT17_CLASSES)})", path=path)
        bad = (gt[:, 8] < 0) | (gt[:, 8] > 1)
        if bad.any():
            raise InputError(f"visibility {gt[bad, 8][0]:g} (frame {int(gt[bad, 0][0])}) is not a share in [0, 1]",
                             path=path)
        bad = (gt[:, 6] != 0) & (gt[:, 6] != 1)
        if bad.any():
            raise InputError(f"consider flag {gt[bad, 6][0]:g} (frame {int(gt[bad, 0][0])}) is neither 0 nor 1",
                             path=path)
    return rules


def _scores(gt: np.ndarray, res: np.ndarray, thr: float, per_alpha: bool) -> dict:
    d = _prepare(gt, res)
    out = {}
    out.update(_clear(d, thr))
    out.update(_identity(d, thr))
    out.update(_hota(d))
    out["Frames"] = d.num_frames
    return {k: (v if isinstance(v, list) else (int(v) if isinstance(v, (int, np.integer)) else float(v)))
            for k, v in out.items() if per_alpha or not k.endswith("_alpha")}


def _threshold(iou_threshold) -> float:
    return float(check_range("iou_threshold", iou_threshold, 0.0, 1.0, lo_open=True))


def evaluate(gt, res, iou_threshold: float = 0.5, per_alpha: bool = False, rules: str = "auto") -> dict:
    """Score tracking results ``res`` against ground truth ``gt`` (one sequence).

    Both are MOTChallenge arrays ``(N, >=6)`` — ``frame, id, x, y, w, h[, conf, ...]`` — or paths
    of MOTChallenge text files. ``iou_threshold`` is the IoU a match needs for CLEAR MOT and IDF1
    (HOTA sweeps its own thresholds). ``rules``: ``"mot15"``, ``"mot17"`` (class filter and
    distractor removal, see the module docstring) or ``"auto"`` (MOT17 rules for ground truth with
    MOT16/17's class column, :func:`gt_rules`).

    Returns a dict of plain Python numbers: ``MOTA, MOTP, MODA, IDF1, IDP, IDR, IDTP, IDFP, IDFN,
    HOTA, HOTA(0), DetA, AssA, LocA, DetRe, DetPr, AssRe, AssPr, MT, PT, ML, FM, IDS, FP, FN, TP``,
    ``GT`` (ground-truth tracks), ``GT_DETS`` (ground-truth boxes evaluated), ``Precision, Recall,
    Frames`` (the last frame number); with ``per_alpha`` also the lists ``HOTA_alpha, DetA_alpha,
    AssA_alpha`` over :data:`HOTA_ALPHAS`. Every other value is a plain ``int`` or ``float``.
    Raises :class:`~artmotion.errors.InputError` for unreadable or inconsistent input.
    """
    thr = _threshold(iou_threshold)
    per_alpha = check_bool("per_alpha", per_alpha)
    return _scores(*_load_pair(gt, res, rules), thr, per_alpha)


def evaluate_sequences(pairs, iou_threshold: float = 0.5, per_alpha: bool = False, rules: str = "auto") -> dict:
    """Scores over several sequences, ``pairs`` of ``(gt, res)`` (arrays or paths).

    The sequences are concatenated with disjoint frames and ids and scored as one, which sums the
    CLEAR and identity counts and weights HOTA's association by its true positives: the same as
    TrackEval's combined (``COMBINED_SEQ``) result. ``rules`` apply to each sequence
    (``"auto"``: decided per sequence).
    """
    thr = _threshold(iou_threshold)
    per_alpha = check_bool("per_alpha", per_alpha)
    gts, ress = [], []
    frame_off = id_off = 0
    for k, (gt, res) in enumerate(pairs):
        g, r = _load_pair(gt, res, rules, k)
        g, r = g[:, :7].copy(), r[:, :7].copy()
        span = int(max(g[:, 0].max(initial=0), r[:, 0].max(initial=0)))
        lo = min(g[:, 1].min(initial=0), r[:, 1].min(initial=0))
        hi = max(g[:, 1].max(initial=0), r[:, 1].max(initial=0))
        g[:, 0] += frame_off
        r[:, 0] += frame_off
        g[:, 1] += id_off - lo
        r[:, 1] += id_off - lo
        gts.append(g)
        ress.append(r)
        frame_off += span
        id_off += int(hi - lo) + 1
    if not gts:
        raise InputError("no sequences to evaluate")
    return _scores(np.vstack(gts), np.vstack(ress), thr, per_alpha)


def format_table(scores: dict, gt=None, results=None, iou_threshold: float = 0.5, rules: str | None = None) -> str:
    """A plain-text table of :func:`evaluate`'s scores (ratios as percentages)."""
    ratio_keys = ("MOTA", "MOTP", "IDF1", "IDP", "IDR", "HOTA", "DetA", "AssA", "Precision", "Recall")
    count_keys = ("GT", "MT", "PT", "ML", "FM", "IDS", "FP", "FN", "TP", "GT_DETS")
    labels = {"Precision": "Prec", "Recall": "Rec", "GT_DETS": "GT boxes"}
    lines = []
    if gt is not None:
        lines.append(f"ground truth: {os.fspath(gt)}" if isinstance(gt, (str, os.PathLike)) else "ground truth: array")
    if results is not None:
        lines.append(f"results:      {os.fspath(results)}" if isinstance(results, (str, os.PathLike)) else "results: array")
    rule = f"   rules: {rules.upper()}" if rules else ""
    lines.append(f"frames: {scores['Frames']}   IoU threshold: {iou_threshold:g}{rule}   (ratios in %)")
    lines.append("")

    def row(keys, fmt):
        heads = [labels.get(k, k) for k in keys]
        vals = [fmt(scores[k]) for k in keys]
        width = [max(len(h), len(v)) for h, v in zip(heads, vals)]
        lines.append("  ".join(h.rjust(w) for h, w in zip(heads, width)))
        lines.append("  ".join(v.rjust(w) for v, w in zip(vals, width)))

    row(ratio_keys, lambda v: f"{100 * v:.1f}")
    lines.append("")
    row(count_keys, lambda v: f"{int(v)}")
    return "\n".join(lines)
