"""artmotion.tracking.metrics: known answers on small cases, and agreement with TrackEval."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.io import read_mot, write_mot
from artmotion.tracking.metrics import HOTA_ALPHAS, evaluate, evaluate_sequences, gt_rules

sys.path.insert(0, str(Path(__file__).parent))
from _trackeval_ref import KEYMAP, chain_tracks, trackeval_combined, trackeval_scores  # noqa: E402

SHARED = Path(__file__).resolve().parents[2].parent / "shared" / "data"


def shared_path(*parts: str) -> Path:
    """A path under ../shared/data; the test is skipped when it is absent."""
    p = SHARED.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"shared data not available: {p}")
    return p


def track(tid, frames, box=(10.0, 20.0, 30.0, 60.0), conf=1.0, step=(5.0, 0.0)):
    """Rows of one object moving by ``step`` per frame."""
    rows = []
    for f in frames:
        x, y, w, h = box
        rows.append([f, tid, x + step[0] * f, y + step[1] * f, w, h, conf, -1, -1, -1])
    return np.array(rows, float).reshape(-1, 10)


def two_people(n=10):
    return np.vstack([track(1, range(1, n + 1)), track(2, range(1, n + 1), box=(300, 20, 30, 60), step=(-5, 0))])


# ---------------------------------------------------------------- known answers


def test_perfect_tracking_scores_one():
    gt = two_people()
    s = evaluate(gt, gt.copy())
    assert s["MOTA"] == 1.0 and s["IDF1"] == 1.0 and s["HOTA"] == pytest.approx(1.0)
    assert s["MOTP"] == pytest.approx(1.0) and s["Precision"] == 1.0 and s["Recall"] == 1.0
    assert (s["IDS"], s["FP"], s["FN"], s["FM"]) == (0, 0, 0, 0)
    assert (s["MT"], s["PT"], s["ML"], s["GT_DETS"], s["GT"]) == (2, 0, 0, 20, 2)


@pytest.mark.parametrize("thr", [0.5, 1.0])
def test_results_identical_to_the_ground_truth_are_perfect_at_every_threshold(thr):
    """At ``--iou 1`` too: a box's IoU with itself is exactly 1 (boxes with decimals, such as
    x = 0.1, w = 0.2, gave 1 - 6e-15 and missed the threshold)."""
    rng = np.random.default_rng(3)
    rows = [[f, i, *np.round(rng.uniform(0, 600, 2), 2), *np.round(rng.uniform(0.1, 90, 2), 2), 1, -1, -1, -1]
            for f in range(1, 31) for i in range(1, 8)]
    gt = np.array(rows, dtype=float)
    r = evaluate(gt, gt, iou_threshold=thr)
    assert r["MOTA"] == r["IDF1"] == r["HOTA"] == r["MOTP"] == 1.0


def test_renumbered_ids_are_still_perfect():
    gt = two_people()
    res = gt.copy()
    res[:, 1] = np.where(res[:, 1] == 1, 77, 5)
    s = evaluate(gt, res)
    assert s["MOTA"] == 1.0 and s["IDF1"] == 1.0 and s["IDS"] == 0


def test_one_id_switch():
    gt = track(1, range(1, 11))
    res = gt.copy()
    res[5:, 1] = 2  # the tracker changes id from frame 6 on
    s = evaluate(gt, res)
    assert s["IDS"] == 1 and s["FP"] == 0 and s["FN"] == 0 and s["FM"] == 0
    assert s["MOTA"] == pytest.approx(0.9)  # (10 - 0 - 1) / 10
    assert s["IDF1"] == pytest.approx(0.5)  # IDTP 5, IDFP 5, IDFN 5
    assert s["IDP"] == pytest.approx(0.5) and s["IDR"] == pytest.approx(0.5)


def test_swap_between_two_people_counts_two_switches():
    gt = two_people()
    res = gt.copy()
    late = res[:, 0] > 5
    res[late, 1] = 3 - res[late, 1]
    s = evaluate(gt, res)
    assert s["IDS"] == 2 and s["MOTA"] == pytest.approx(18 / 20)


def test_gap_is_a_fragmentation_not_a_switch():
    gt = two_people()
    gap = (gt[:, 1] == 1) & np.isin(gt[:, 0], [5, 6])  # person 1 missed in frames 5, 6; same id after
    s = evaluate(gt, gt[~gap])
    assert (s["FM"], s["IDS"], s["FN"], s["FP"]) == (1, 0, 2, 0)
    assert s["MOTA"] == pytest.approx(18 / 20)
    assert (s["MT"], s["PT"], s["ML"]) == (1, 1, 0)  # tracked 80%: MT needs more than 80%


def test_frames_without_any_result_do_not_break_continuity():
    # TrackEval's CLEAR skips frames with no result box at all before updating the previous
    # frame's matches, so a gap where the tracker output nothing is no fragmentation (FM 0).
    gt = track(1, range(1, 11))
    s = evaluate(gt, gt[(gt[:, 0] < 5) | (gt[:, 0] > 6)])
    assert (s["FM"], s["IDS"], s["FN"]) == (0, 0, 2)


def test_mostly_lost_and_false_positive():
    gt = two_people()
    res = np.vstack([gt[gt[:, 1] == 1], track(9, [3], box=(600, 400, 20, 20))])
    s = evaluate(gt, res)
    assert (s["MT"], s["PT"], s["ML"]) == (1, 0, 1)
    assert (s["FP"], s["FN"], s["TP"]) == (1, 10, 10)
    assert s["MOTA"] == pytest.approx((10 - 1) / 20)
    assert s["Precision"] == pytest.approx(10 / 11) and s["Recall"] == pytest.approx(0.5)


def test_iou_threshold_and_motp():
    gt = track(1, range(1, 6), box=(0, 0, 10, 10), step=(0, 0))
    res = gt.copy()
    res[:, 5] = 8.2  # IoU 0.82 in every frame
    s = evaluate(gt, res, per_alpha=True)
    assert s["MOTP"] == pytest.approx(0.82) and s["MOTA"] == 1.0
    strict = evaluate(gt, res, iou_threshold=0.9)
    assert strict["TP"] == 0 and strict["FP"] == 5 and strict["FN"] == 5 and strict["IDF1"] == 0.0
    # HOTA: a perfect association, detected at the 16 alphas 0.05..0.80, not at 0.85..0.95.
    assert sum(HOTA_ALPHAS <= 0.82) == 16
    assert s["HOTA"] == pytest.approx(16 / 19) and s["DetA"] == pytest.approx(16 / 19)
    assert s["HOTA_alpha"][-1] == 0.0 and s["HOTA_alpha"][0] == pytest.approx(1.0)


def test_zero_marked_ground_truth_is_ignored():
    gt = track(1, range(1, 6))
    ignored = track(2, range(1, 6), box=(300, 20, 30, 60), conf=0)
    s = evaluate(np.vstack([gt, ignored]), gt)
    assert s["FN"] == 0 and s["GT_DETS"] == 5 and s["GT"] == 1 and s["MOTA"] == 1.0
    # MOT15 has no distractor classes: a result box on an ignored object is a false positive.
    s2 = evaluate(np.vstack([gt, ignored]), np.vstack([gt, ignored]))
    assert s2["FP"] == 5


def test_empty_results_and_empty_gt():
    gt = two_people()
    s = evaluate(gt, np.zeros((0, 10)))
    assert (s["FN"], s["ML"], s["TP"], s["FP"]) == (20, 2, 0, 0)
    assert s["MOTA"] == 0.0 and s["IDF1"] == 0.0 and s["HOTA"] == 0.0
    s = evaluate(np.zeros((0, 10)), gt)
    assert s["FP"] == 20 and s["MOTA"] == 0.0


def test_paths_and_arrays_agree(tmp_path):
    gt = two_people()
    res = gt.copy()
    res[gt[:, 0] > 7, 2] += 8
    write_mot(tmp_path / "gt.txt", gt)
    write_mot(tmp_path / "res.txt", res)
    a = evaluate(gt, res[:, :6])  # 6 columns are enough
    b = evaluate(str(tmp_path / "gt.txt"), tmp_path / "res.txt")
    for k in ("MOTA", "MOTP", "IDF1", "HOTA", "IDS", "FP", "FN"):
        assert a[k] == pytest.approx(b[k], abs=1e-6)
    assert all(type(v) in (int, float) for v in a.values())  # plain numbers: float(v) and JSON work


@pytest.mark.parametrize(
    "bad, message",
    [
        (np.zeros((3, 5)), "shape"),
        (np.array([[1, 1, 0, 0, 10, np.nan, 1]]), "NaN"),
        (np.array([[0, 1, 0, 0, 10, 10, 1]]), r"frames must be whole numbers in \[1"),
        (np.array([[1, 1, 0, 0, 0, 10, 1]]), "box size"),
        (np.array([[1, 1, 0, 0, 10, 10, 1], [1, 1, 5, 5, 10, 10, 1]]), "more than once"),
        (np.array([[1, 1.5, 0, 0, 10, 10, 1]]), "track ids must be whole numbers"),
    ],
)
def test_bad_arrays_raise_input_error(bad, message):
    with pytest.raises(InputError, match=message):
        evaluate(two_people(), bad)


def test_bad_files_raise_input_error(tmp_path):
    good = tmp_path / "gt.txt"
    write_mot(good, two_people())
    bad = tmp_path / "bad.txt"
    bad.write_text("1,1,0,0,10,10,1,-1,-1,-1\n2,1,0,zero,10,10\n")
    with pytest.raises(InputError) as err:
        evaluate(good, bad)
    assert err.value.path == str(bad) and err.value.line == 2
    with pytest.raises(InputError, match="no such file"):
        evaluate(tmp_path / "missing.txt", good)
    with pytest.raises(InputError, match="threshold"):
        evaluate(good, good, iou_threshold=0)


# ------------------------------------------------------------- agreement with TrackEval

TOL = 1e-6


@pytest.fixture(autouse=False)
def needs_trackeval():
    pytest.importorskip("trackeval")


def assert_agrees(ours: dict, ref: dict):
    for ours_key, ref_key in KEYMAP.items():
        assert math.isclose(ours[ours_key], ref[ref_key], rel_tol=0, abs_tol=TOL), (ours_key, ours[ours_key], ref[ref_key])


@pytest.mark.parametrize("seq", ["PETS09-S2L1", "TUD-Campus"])
def test_agrees_with_trackeval_on_mot15(seq, needs_trackeval):
    root = shared_path("mot15", seq)
    gt = read_mot(root / "gt" / "gt.txt")
    det = read_mot(root / "det" / "det.txt")
    cases = {
        "chained detections": chain_tracks(det),
        "confident chained": chain_tracks(det, min_iou=0.5, min_conf=0.5),
        "ground truth (zero-marked rows become FPs)": gt,
    }
    for name, res in cases.items():
        ours = evaluate(root / "gt" / "gt.txt", res)
        ref = trackeval_scores(gt, res)
        assert_agrees(ours, ref)
        if name.startswith("chained"):
            assert ours["IDS"] > 0 and 0 < ours["MOTA"] < 1 and 0 < ours["HOTA"] < 1  # a non-trivial case
    ours = evaluate(gt, cases["chained detections"], iou_threshold=0.3)
    assert_agrees(ours, trackeval_scores(gt, cases["chained detections"], threshold=0.3))


def test_mot17_rules_agree_with_trackeval_on_mot16_09(needs_trackeval):
    """9-column ground truth: pedestrians with consider = 1 only, boxes on distractors removed."""
    root = shared_path("mot16", "MOT16-09")
    gt = read_mot(root / "gt" / "gt.txt")
    det = read_mot(root / "det" / "det.txt")
    det = det[np.argsort(det[:, 0], kind="stable")]
    # pseudo-tracks: chained detections plus ground-truth boxes of distractors (class 8, 12) and of
    # consider = 0 pedestrians, so that the removal and the class filter both matter
    extra = gt[np.isin(gt[:, 7], [8, 12]) | ((gt[:, 7] == 1) & (gt[:, 6] == 0))].copy()
    extra[:, 1] += 10_000
    extra[:, 6:] = -1
    res = np.vstack([chain_tracks(det), extra])
    ours = evaluate(root / "gt" / "gt.txt", res)
    assert gt_rules(gt) == "mot17"
    ref = trackeval_scores(gt, res, benchmark="MOT17")
    for ours_key, ref_key in KEYMAP.items():
        tol = 1e-3 if ours[ours_key] <= 1.0 else 0.5   # within 0.1 point (ratios) / exact counts
        assert abs(ours[ours_key] - ref[ref_key]) <= tol, (ours_key, ours[ours_key], ref[ref_key])
    # the rules matter here: MOT15 rules count the distractor boxes as false positives
    assert evaluate(gt, res, rules="mot15")["FP"] > ours["FP"] + 100


def test_distractor_matches_are_removed():
    gt = np.array([[1, 1, 0, 0, 10, 20, 1, 1, 1.0],      # pedestrian
                   [1, 2, 50, 0, 10, 20, 0, 8, 1.0],     # distractor
                   [1, 3, 100, 0, 10, 20, 0, 1, 0.2]])   # pedestrian, not considered
    res = np.array([[1, 1, 0, 0, 10, 20, 1], [1, 2, 50, 0, 10, 20, 1], [1, 3, 100, 0, 10, 20, 1]])
    s = evaluate(gt, res)
    assert (s["TP"], s["FP"], s["FN"]) == (1, 1, 0)   # the box on the distractor is removed
    assert evaluate(gt, res, rules="mot15")["FP"] == 2
    with pytest.raises(InputError, match="rules"):
        evaluate(gt, res, rules="mot20")


def _random_case(rng):
    nf = int(rng.integers(3, 25))
    gt, res = [], []
    for i in range(int(rng.integers(1, 7))):
        s, e = sorted(rng.integers(1, nf + 1, 2))
        x, y = rng.uniform(0, 200, 2)
        vx, vy = rng.normal(0, 5, 2)
        w, h = rng.uniform(10, 40, 2)
        for f in range(s, e + 1):
            if rng.random() < 0.1:
                continue
            conf = 0.0 if rng.random() < 0.05 else 1.0
            gt.append([f, i + 1, x + vx * f, y + vy * f, w, h, conf, -1, -1, -1])
            if rng.random() < 0.2:
                continue
            tid = i + 1 + (10 if rng.random() < 0.15 else 0) + (20 if f > nf / 2 and rng.random() < 0.5 else 0)
            j = rng.normal(0, rng.choice([1, 4, 8]), 4)
            res.append([f, tid, x + vx * f + j[0], y + vy * f + j[1], max(1, w + j[2]), max(1, h + j[3]), 1, -1, -1, -1])
    for k in range(int(rng.integers(0, 6))):
        res.append([rng.integers(1, nf + 1), 100 + k, *rng.uniform(0, 200, 2), *rng.uniform(10, 40, 2), 1, -1, -1, -1])
    gt = np.array(gt, float).reshape(-1, 10)
    res = np.array(res, float).reshape(-1, 10)
    if len(res):
        _, first = np.unique(res[:, :2], axis=0, return_index=True)
        res = res[np.sort(first)]
        res = res[rng.permutation(len(res))]
    return gt, res


@pytest.mark.parametrize("seed", range(40))
def test_agrees_with_trackeval_on_random_cases(seed, needs_trackeval):
    rng = np.random.default_rng(seed)
    gt, res = _random_case(rng)
    thr = float(rng.choice([0.3, 0.5, 0.7]))
    assert_agrees(evaluate(gt, res, iou_threshold=thr), trackeval_scores(gt, res, threshold=thr))


def test_combined_sequences_agree_with_trackeval(needs_trackeval):
    pairs = []
    for seed in (101, 102, 103):
        gt, res = _random_case(np.random.default_rng(seed))
        pairs.append((gt, res))
    root = shared_path("mot15", "TUD-Campus")
    pairs.append((root / "gt" / "gt.txt", chain_tracks(read_mot(root / "det" / "det.txt"))))
    ours = evaluate_sequences(pairs)
    ref = trackeval_combined([(read_mot(g) if isinstance(g, Path) else g, r) for g, r in pairs])
    assert_agrees(ours, ref)
    single = [evaluate(g, r) for g, r in pairs]
    assert ours["IDS"] == sum(s["IDS"] for s in single) and ours["FP"] == sum(s["FP"] for s in single)
