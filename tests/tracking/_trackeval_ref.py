"""Reference scores from TrackEval's full MOT15 pipeline (folder layout, MotChallenge2DBox), and a
tiny IoU-chaining tracker that turns published detections into pseudo-tracks for cross-checks."""

from __future__ import annotations

import contextlib
import io
import tempfile
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from artmotion.geometry import iou_matrix


def _write(path: Path, rows: np.ndarray, columns: int = 10) -> None:
    # Keep the row order (it decides Hungarian tie-breaks) and full precision.
    rows = np.asarray(rows, float).reshape(-1, np.shape(rows)[-1] if np.size(rows) else 10)
    if rows.shape[1] < 10:
        rows = np.hstack([rows, -np.ones((len(rows), 10 - rows.shape[1]))])
    with open(path, "w") as fh:
        for r in rows:
            fh.write("%d,%d,%s\n" % (r[0], r[1], ",".join(repr(float(v)) for v in r[2:columns])))


def _flat(r: dict) -> dict:
    flat = {}
    for group in r.values():
        for k, v in group.items():
            flat[k] = float(np.mean(v)) if np.ndim(v) else float(v)
    return flat


def _run_trackeval(seqs: dict, threshold: float, benchmark: str = "MOT15") -> dict:
    """TrackEval (``BENCHMARK=benchmark``) on ``{name: (gt, res)}``; its results for the one tracker.

    For MOT17 the ground truth is written with its 9 columns (consider, class, visibility)."""
    import trackeval

    split = f"{benchmark}-train"
    gt_cols = 9 if benchmark != "MOT15" else 10
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        info = {}
        (tmp / "trk" / split / "T" / "data").mkdir(parents=True)
        for seq, (gt, res) in seqs.items():
            gt = np.asarray(gt, float)
            res = np.asarray(res, float).copy()
            if res.shape[1] > 7:  # TrackEval reads column 7 of results as a class (MOT15 gt has world X there)
                res[:, 7:] = -1
            info[seq] = int(max(gt[:, 0].max() if len(gt) else 1, res[:, 0].max() if len(res) else 1))
            (tmp / "gt" / split / seq / "gt").mkdir(parents=True)
            _write(tmp / "gt" / split / seq / "gt" / "gt.txt", gt, gt_cols)
            _write(tmp / "trk" / split / "T" / "data" / f"{seq}.txt", res)
        ev_cfg = dict(trackeval.Evaluator.get_default_eval_config())
        ev_cfg.update(USE_PARALLEL=False, PRINT_RESULTS=False, PRINT_CONFIG=False, TIME_PROGRESS=False,
                      OUTPUT_SUMMARY=False, OUTPUT_DETAILED=False, PLOT_CURVES=False, LOG_ON_ERROR=None)
        ds_cfg = dict(GT_FOLDER=str(tmp / "gt"), TRACKERS_FOLDER=str(tmp / "trk"), BENCHMARK=benchmark,
                      SPLIT_TO_EVAL="train", SEQ_INFO=info, TRACKERS_TO_EVAL=["T"], PRINT_CONFIG=False)
        metric_cfg = {"THRESHOLD": threshold, "PRINT_CONFIG": False}
        with contextlib.redirect_stdout(io.StringIO()):
            out, _ = trackeval.Evaluator(ev_cfg).evaluate(
                [trackeval.datasets.MotChallenge2DBox(ds_cfg)],
                [trackeval.metrics.HOTA(), trackeval.metrics.CLEAR(metric_cfg), trackeval.metrics.Identity(metric_cfg)],
            )
    return out["MotChallenge2DBox"]["T"]


def trackeval_scores(gt: np.ndarray, res: np.ndarray, threshold: float = 0.5, benchmark: str = "MOT15") -> dict:
    """Run TrackEval's full MotChallenge2DBox pipeline on one sequence; flat dict of its summary values."""
    return _flat(_run_trackeval({"SEQ": (gt, res)}, threshold, benchmark)["SEQ"]["pedestrian"])


def trackeval_combined(pairs: list, threshold: float = 0.5) -> dict:
    """TrackEval's combined result (``COMBINED_SEQ``) over several ``(gt, res)`` sequences."""
    seqs = {f"SEQ{k}": pair for k, pair in enumerate(pairs)}
    return _flat(_run_trackeval(seqs, threshold)["COMBINED_SEQ"]["pedestrian"])


#: our key -> TrackEval's key
KEYMAP = {
    "MOTA": "MOTA", "MOTP": "MOTP", "IDF1": "IDF1", "IDP": "IDP", "IDR": "IDR", "HOTA": "HOTA",
    "DetA": "DetA", "AssA": "AssA", "LocA": "LocA", "MT": "MT", "PT": "PT", "ML": "ML", "FM": "Frag",
    "IDS": "IDSW", "FP": "CLR_FP", "FN": "CLR_FN", "TP": "CLR_TP", "Precision": "CLR_Pr", "Recall": "CLR_Re",
    "IDTP": "IDTP", "IDFP": "IDFP", "IDFN": "IDFN",
}


def chain_tracks(det: np.ndarray, min_iou: float = 0.3, min_conf: float = -np.inf) -> np.ndarray:
    """Link detections frame to frame by IoU (Hungarian); unmatched ones start new ids."""
    det = np.asarray(det, float)
    det = det[det[:, 6] >= min_conf]
    det = det[np.argsort(det[:, 0], kind="stable")]
    out = det.copy()
    prev_boxes = np.zeros((0, 4))
    prev_ids = np.zeros(0, int)
    next_id = 1
    for f in np.unique(det[:, 0]):
        idx = np.flatnonzero(det[:, 0] == f)
        boxes = det[idx, 2:6]
        ids = np.zeros(len(idx), int)
        if len(prev_boxes):
            sim = iou_matrix(boxes, prev_boxes)
            rows, cols = linear_sum_assignment(-sim)
            for r, c in zip(rows, cols):
                if sim[r, c] >= min_iou:
                    ids[r] = prev_ids[c]
        for k in np.flatnonzero(ids == 0):
            ids[k] = next_id
            next_id += 1
        out[idx, 1] = ids
        prev_boxes, prev_ids = boxes, ids
    return out
