"""``artmotion eval GT RESULTS [--json] [--iou]``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from artmotion.io import write_mot
from artmotion.tracking.metrics import evaluate


@pytest.fixture
def files(tmp_path):
    frames = np.arange(1, 11)
    gt = np.vstack([
        np.column_stack([frames, np.full(10, 1), 10 + 5 * frames, np.full(10, 20), np.full(10, 30), np.full(10, 60)]),
        np.column_stack([frames, np.full(10, 2), 300 - 5 * frames, np.full(10, 20), np.full(10, 30), np.full(10, 60)]),
    ])
    res = gt.copy()
    res[(res[:, 1] == 1) & (res[:, 0] > 5), 1] = 7  # one identity switch
    res = res[~((res[:, 1] == 2) & (res[:, 0] == 3))]  # one miss
    write_mot(tmp_path / "gt.txt", gt)
    write_mot(tmp_path / "res.txt", res)
    return tmp_path / "gt.txt", tmp_path / "res.txt"


def test_table(run_cli, files):
    gt, res = files
    code, out, err = run_cli("eval", gt, res)
    assert code == 0, err
    lines = out.splitlines()
    head = next(i for i, l in enumerate(lines) if l.split()[:1] == ["MOTA"])
    values = dict(zip(lines[head].split(), lines[head + 1].split()))
    assert values["MOTA"] == "90.0"  # (20 - 1 FN - 1 IDS) / 20
    counts_head = next(i for i, l in enumerate(lines) if l.split()[:1] == ["GT"])
    heads = lines[counts_head].replace("GT boxes", "GT_boxes").split()
    counts = dict(zip(heads, map(int, lines[counts_head + 1].split())))
    assert counts == {"GT": 2, "MT": 2, "PT": 0, "ML": 0, "FM": 1, "IDS": 1, "FP": 0, "FN": 1, "TP": 19, "GT_boxes": 20}


def test_json_matches_api(run_cli, files):
    gt, res = files
    code, out, _ = run_cli("eval", gt, res, "--json", "--iou", "0.6")
    assert code == 0
    got = json.loads(out)
    want = evaluate(gt, res, iou_threshold=0.6)
    assert set(got) == set(want) | {"rules"}
    assert got["rules"] == "mot15"
    for k in ("MOTA", "MOTP", "IDF1", "HOTA", "IDS", "FP", "FN", "MT", "PT", "ML", "FM"):
        assert got[k] == pytest.approx(want[k])
    assert got["IDS"] == 1 and got["FN"] == 1


@pytest.mark.parametrize(
    "content, needle",
    [
        ("1,1,10,20,30,60,1\n2,1,10,20,30\n", ":2: expected 6 to 10 values"),
        ("1,1,10,20,30,60,1\n2,1,10,nan,30,60,1\n", ":2: NaN"),
        ("1,1,10,20,30,60,1\n1,1,12,20,30,60,1\n", "appears more than once in frame 1"),
    ],
)
def test_bad_results_file_is_one_line_exit_2(run_cli, files, tmp_path, content, needle):
    gt, _ = files
    bad = tmp_path / "bad.txt"
    bad.write_text(content)
    code, out, err = run_cli("eval", gt, bad)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("artmotion: error: ") and needle in err
    assert "Traceback" not in err


def test_missing_file_and_bad_threshold(run_cli, files, tmp_path):
    gt, res = files
    code, _, err = run_cli("eval", tmp_path / "nope.txt", res)
    assert code == 2 and "nope.txt: no such file" in err and err.count("\n") == 1
    code, _, err = run_cli("eval", gt, res, "--iou", "1.5")
    assert code == 2 and "--iou must be a number in (0, 1], got 1.5" in err


def test_api_threshold_that_is_not_a_number():
    """``evaluate(iou_threshold="abc")`` was a bare ValueError from ``float()``."""
    from artmotion.errors import InputError
    from artmotion.tracking import evaluate

    gt = np.array([[1, 1, 0, 0, 10, 10, 1, -1, -1, -1]], dtype=float)
    for bad in ("abc", None, True, float("nan")):
        with pytest.raises(InputError, match="iou_threshold must be a number"):
            evaluate(gt, gt, iou_threshold=bad)


def test_unknown_mot17_class_under_mot17_rules(run_cli, tmp_path):
    """A class MOT16/17 does not know (99) is an error under ``--rules mot17``, as in TrackEval, not
    a silently ignored box; ``auto`` takes 9-column ground truth for MOT16/17's (the code before
    read it as MOT15's when one class was unknown, and scored distractors as false positives)."""
    gt = tmp_path / "gt.txt"
    gt.write_text("1,1,10,10,20,40,1,99,1\n2,1,10,10,20,40,1,1,1\n")
    for rules in ("mot17", "auto"):
        code, out, err = run_cli("eval", gt, gt, "--rules", rules)
        assert code == 2 and out == "" and "gt.txt: class 99 (frame 1) is not a MOT16/17 class" in err
    gt.write_text("1,1,10,10,20,40,1,1,-7\n2,1,10,10,20,40,1,1,1\n")
    code, out, err = run_cli("eval", gt, gt)
    assert code == 2 and "gt.txt: visibility -7 (frame 1) is not a share in [0, 1]" in err
    gt.write_text("1,1,10,10,20,40,1,7,1\n2,1,10,10,20,40,1,1,1\n")      # 7: a static person (distractor)
    code, out, err = run_cli("eval", gt, gt, "--json")
    assert code == 0 and '"rules": "mot17"' in out and '"FP": 0' in out, out
    gt.write_text("1,1,10,10,20,40,1,7,1,-1\n2,1,10,10,20,40,1,1,1,-1\n")  # 10 columns: MOT15's world coordinates
    code, out, err = run_cli("eval", gt, gt, "--json")
    assert code == 0 and '"rules": "mot15"' in out
    gt.write_text("1,1,10,10,20,40,1\n")  # MOT15's 7 columns: no class column to apply MOT17's rules to
    code, out, err = run_cli("eval", gt, gt, "--rules", "mot17")
    assert code == 2 and "no class column" in err
