"""Surgical instrument annotations, prediction files and their evaluation (issue #15)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import shared_path

from artmotion.errors import InputError
from artmotion.tracking.instruments import evaluate_tools, read_predictions, read_tools_csv, write_predictions
from artmotion.tracking.instruments.evaluate import format_report

TOOLS_HEADER = "frame,tool,y,x,scale,angle"
PRED_HEADER = "frame,track,x,y,scale,angle,score"


def _write(tmp_path, text, name="f.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


# --- readers -----------------------------------------------------------------------------------

def test_predictions_round_trip(tmp_path):
    pred = {
        12: np.array([[3, 10.04, 20.06, 30.123, 1.23456, 0.98765], [0, -5.0, 7.5, 0.001, -0.5, 0.25]]),
        3: np.array([[7, 100.0, 200.0, 50.0, 7.0, 1.0]]),
        5: np.zeros((0, 6)),
    }
    path = tmp_path / "out" / "pred.csv"
    write_predictions(path, pred)
    lines = path.read_text().splitlines()
    assert lines[0] == PRED_HEADER
    assert lines[1] == f"3,7,100.0,200.0,50.00,{7.0 - 2 * math.pi:.4f},1.0000"
    assert lines[2] == f"12,0,-5.0,7.5,0.001,{2 * math.pi - 0.5:.4f},0.2500"       # tracks ascending
    assert lines[3] == "12,3,10.0,20.1,30.12,1.2346,0.9877"
    assert len(lines) == 4
    assert [p.name for p in path.parent.iterdir()] == ["pred.csv"]                  # no temporary left

    back = read_predictions(path)
    assert list(back) == [3, 12]
    assert back[12].shape == (2, 6) and back[3].shape == (1, 6)
    np.testing.assert_allclose(back[12][:, 0], [0, 3])
    np.testing.assert_allclose(back[12][1], [3, 10.0, 20.1, 30.12, 1.2346, 0.9877])
    np.testing.assert_allclose(back[12][0], [0, -5.0, 7.5, 0.001, 2 * math.pi - 0.5, 0.25], atol=1e-4)
    np.testing.assert_allclose(back[3][0, 4], 7.0 - 2 * math.pi, atol=1e-4)

    write_predictions(path, back)                                                   # stable once rounded
    assert path.read_text().splitlines() == lines


def test_write_predictions_refuses_what_it_could_not_read_back(tmp_path):
    path = tmp_path / "pred.csv"
    for bad in ({1: np.array([[0, 1, 2, 3, 4]])}, {1: np.array([[0, np.nan, 2, 3, 4, 5]])},
                {1: np.array([[-1, 1, 2, 3, 4, 5]])}, {1: np.array([[0.5, 1, 2, 3, 4, 5]])},
                {1: np.array([[0, 1, 2, 0, 4, 5]])}, {1: np.array([[2, 1, 2, 3, 4, 5], [2, 5, 6, 3, 4, 5]])},
                {-1: np.array([[0, 1, 2, 3, 4, 5]])}, {1: np.array([[0, 2e6, 2, 3, 4, 5]])}):
        with pytest.raises(InputError):
            write_predictions(path, bad)
        assert not path.exists()


def test_read_tools_csv_columns_in_any_order_and_angles_wrapped(tmp_path):
    p = _write(tmp_path, "x,angle,frame,scale,y,tool\n\n10,-0.5,4,20,30,1\n11,7,4,21,31,0\n  \n12,0,2,22,32,0\n")
    gt = read_tools_csv(p)
    assert list(gt) == [2, 4]
    np.testing.assert_allclose(gt[2], [[12, 32, 22, 0]])
    np.testing.assert_allclose(gt[4], [[11, 31, 21, 7 - 2 * math.pi], [10, 30, 20, 2 * math.pi - 0.5]])  # by tool
    assert all(np.all((a[:, 3] >= 0) & (a[:, 3] < 2 * math.pi)) for a in gt.values())


def test_read_shared_tools_csv():
    gt = read_tools_csv(shared_path("surgical", "lap-tools", "tools.csv"))
    assert len(gt) == 400
    # 743 rows (744 lines with the header): 343 frames with two instruments, 57 with one
    assert sum(len(a) for a in gt.values()) == 743
    assert min(gt) == 1175 and max(gt) == 1574
    np.testing.assert_allclose(gt[1175][0], [245, 122, 67.521364, 5.852859])      # x before y
    allrows = np.concatenate(list(gt.values()))
    assert np.all(allrows[:, 2] > 0)
    assert np.all((allrows[:, 3] >= 0) & (allrows[:, 3] < 2 * math.pi))
    res = evaluate_tools(gt, {f: np.column_stack([np.arange(len(a)), a[:, :2], a[:, 2:], np.ones(len(a))])
                              for f, a in gt.items()})
    assert res["recall"] == res["precision"] == 1.0
    assert res["median_angle_error_deg"] == 0.0


GOOD_TOOLS = f"{TOOLS_HEADER}\n1175,0,122,245,67.5,5.85\n"
TOOLS_CASES = [
    ("frame,tool,y,x,scale\n1,0,1,1,1\n", 1, "missing column 'angle'"),
    ("frame,tool,y,scale\n1,0,1,1\n", 1, "missing columns 'x', 'angle'"),
    ("frame,tool,y,y,scale,angle\n", 1, "duplicate column 'y'"),
    (GOOD_TOOLS + "\n1176,0,122,245,67.5\n", 4, "expected 6 columns, got 5"),
    (GOOD_TOOLS + "1176,0,122,245,67.5,1,2\n", 3, "expected 6 columns, got 7"),
    (GOOD_TOOLS + "1176,0,abc,245,67.5,1\n", 3, "y is not a number: 'abc'"),
    (GOOD_TOOLS + "1176,0,122,,67.5,1\n", 3, "x is not a number: ''"),
    (GOOD_TOOLS + "1176,0,122,245,67.5,nan\n", 3, "angle is not finite"),
    (GOOD_TOOLS + "1176,0,122,inf,67.5,1\n", 3, "x is not finite"),
    (GOOD_TOOLS + "-1,0,122,245,67.5,1\n", 3, "frame must be a whole number"),
    (GOOD_TOOLS + "1176.5,0,122,245,67.5,1\n", 3, "frame must be a whole number"),
    (GOOD_TOOLS + "1176,0.5,122,245,67.5,1\n", 3, "tool must be a whole number"),
    (GOOD_TOOLS + "1176,-1,122,245,67.5,1\n", 3, "tool must be a whole number"),
    (GOOD_TOOLS + "1176,0,122,245,0,1\n", 3, "scale must be a number in (0"),
    (GOOD_TOOLS + "1176,0,122,245,-3,1\n", 3, "scale must be a number in (0"),
    (GOOD_TOOLS + "1176,0,2e6,245,3,1\n", 3, "y out of range"),
    (GOOD_TOOLS + "1176,0,12,-1000001,3,1\n", 3, "x out of range"),
    (GOOD_TOOLS + "1176,0,12,24,3,1\n1175,0,12,24,3,1\n", 4, "duplicate tool 0 in frame 1175 (first on line 2)"),
]


@pytest.mark.parametrize("text, line, message", TOOLS_CASES)
def test_read_tools_csv_bad_input(tmp_path, text, line, message):
    p = _write(tmp_path, text)
    with pytest.raises(InputError) as info:
        read_tools_csv(p)
    assert info.value.line == line
    assert message in info.value.reason
    assert str(info.value).startswith(f"{p}:{line}: ")


GOOD_PRED = f"{PRED_HEADER}\n1,0,10,20,5,1,0.9\n"
PRED_CASES = [
    ("frame,track,x,y,scale,angle\n", 1, "missing column 'score'"),
    ("frame,tool,x,y,scale,angle,score\n", 1, "unknown column 'tool'"),
    (PRED_HEADER + ",score\n", 1, "duplicate column 'score'"),
    (GOOD_PRED + "2,0,10,20,5,1\n", 3, "expected 7 columns, got 6"),
    (GOOD_PRED + "2,0,10,20,5,1,high\n", 3, "score is not a number"),
    (GOOD_PRED + "2,0,10,20,5,1,-inf\n", 3, "score is not finite"),
    (GOOD_PRED + "2,1.5,10,20,5,1,1\n", 3, "track must be a whole number"),
    (GOOD_PRED + "2,-1,10,20,5,1,1\n", 3, "track must be a whole number"),
    (GOOD_PRED + "-2,1,10,20,5,1,1\n", 3, "frame must be a whole number"),
    (GOOD_PRED + "2,1,10,20,0,1,1\n", 3, "scale must be"),
    (GOOD_PRED + "2,1,1e7,20,1,1,1\n", 3, "x out of range"),
    (GOOD_PRED + "2,1,10,20,5,1,1.5\n", 3, "score must be a number in [0, 1]"),
    (GOOD_PRED + "2,1,10,20,5,1,-3\n", 3, "score must be a number in [0, 1]"),
    (GOOD_PRED + "1,1,10,20,5,1,0.9\n1,0,10,20,5,1,0.9\n", 4, "duplicate track 0 in frame 1 (first on line 2)"),
]


@pytest.mark.parametrize("text, line, message", PRED_CASES)
def test_read_predictions_bad_input(tmp_path, text, line, message):
    p = _write(tmp_path, text)
    with pytest.raises(InputError) as info:
        read_predictions(p)
    assert info.value.line == line
    assert message in info.value.reason


def test_no_rows(tmp_path):
    """Annotations without rows are an error; predictions without rows (what 'tool track' writes
    when it finds nothing) are an answer; a file without a header is neither."""
    for text in ("", "\n\n"):
        for reader in (read_tools_csv, read_predictions):
            p = _write(tmp_path, text)
            with pytest.raises(InputError, match="no header") as info:
                reader(p)
            assert info.value.path == str(p)
    for text in (TOOLS_HEADER + "\n", TOOLS_HEADER + "\n\n  \n"):
        with pytest.raises(InputError, match="no annotations"):
            read_tools_csv(_write(tmp_path, text))
    for text in (PRED_HEADER + "\n", PRED_HEADER + "\n\n  \n"):
        assert read_predictions(_write(tmp_path, text)) == {}


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_tools_csv(tmp_path / "absent.csv")
    with pytest.raises(InputError, match="no such file"):
        read_predictions(tmp_path / "absent.csv")


# --- evaluation --------------------------------------------------------------------------------

def _gt(frames: dict[int, list[tuple[float, float, float]]]) -> dict[int, np.ndarray]:
    """frame -> [(x, y, angle)] as read_tools_csv returns it (scale 20)."""
    return {f: np.array([[x, y, 20.0, a] for x, y, a in heads]).reshape(-1, 4) for f, heads in frames.items()}


def _pred(frames: dict[int, list[tuple[int, float, float, float]]]) -> dict[int, np.ndarray]:
    """frame -> [(track, x, y, angle)] as read_predictions returns it (scale 20, score 1)."""
    return {f: np.array([[t, x, y, 20.0, a, 1.0] for t, x, y, a in heads]).reshape(-1, 6)
            for f, heads in frames.items()}


def _two_tools(n=10):
    return {f: [(100.0 + 2 * f, 50.0, 1.0), (300.0 - 2 * f, 80.0, 4.0)] for f in range(n)}


def test_perfect_predictions():
    heads = _two_tools()
    res = evaluate_tools(_gt(heads), _pred({f: [(i, *h) for i, h in enumerate(hs)] for f, hs in heads.items()}), fps=25)
    assert res["frames"] == 10 and res["gt"] == res["pred"] == res["matched"] == 20
    assert res["recall"] == res["precision"] == 1.0
    assert res["median_angle_error_deg"] == 0.0
    assert res["id_switches"] == 0
    assert res["radius"] == 15.0 and res["fps"] == 25.0
    text = format_report(res)
    assert "heads within 15 px: recall 1.000 (20/20), precision 1.000 (20/20)" in text
    assert "shaft angle: median error 0.0° over 20 matched heads" in text
    assert "identity switches: 0" in text
    assert "speed: 25.0 frames/s" in text


def test_prediction_20px_off_is_no_match():
    gt = _gt({1: [(100, 100, 0.0)]})
    res = evaluate_tools(gt, _pred({1: [(0, 120, 100, 0.0)]}))
    assert res["matched"] == 0 and res["recall"] == 0.0 and res["precision"] == 0.0
    assert res["median_angle_error_deg"] is None
    assert "shaft angle: no matched heads" in format_report(res)
    assert "speed" not in format_report(res)
    assert evaluate_tools(gt, _pred({1: [(0, 112, 109, 0.0)]}))["matched"] == 1       # 15 px: within
    assert evaluate_tools(gt, _pred({1: [(0, 120, 100, 0.0)]}), radius=25)["matched"] == 1


def test_one_to_one():
    res = evaluate_tools(_gt({1: [(100, 100, 0.0)]}), _pred({1: [(0, 102, 100, 0.0), (1, 98, 101, 0.0)]}))
    assert res["matched"] == 1 and res["recall"] == 1.0 and res["precision"] == 0.5
    # the most pairs within the radius, not the least total distance: (A, p0) at 0 px leaves B to p1 at 19.8 px
    gt = _gt({1: [(0, 0, 0.0), (14, 0, 0.0)]})
    res = evaluate_tools(gt, _pred({1: [(0, 0, 0, 0.0), (1, 0, 14, 0.0)]}))
    assert res["matched"] == 2


def test_frames_missing_on_one_side():
    # frame 3 is not annotated: its prediction is not scored, only counted
    res = evaluate_tools(_gt({1: [(10, 10, 0.0)], 2: [(10, 10, 0.0)]}), _pred({2: [(0, 10, 10, 0.0)], 3: [(0, 5, 5, 0.0)]}))
    assert res["frames"] == 2 and res["gt"] == 2 and res["pred"] == 1 and res["matched"] == 1
    assert res["unscored_frames"] == 1 and res["unscored_pred"] == 1
    # a frame given as annotated with no instrument (an empty array: the API can say it, tools.csv cannot) is scored
    res = evaluate_tools({**_gt({1: [(10, 10, 0.0)]}), 3: np.zeros((0, 4))}, _pred({1: [(0, 10, 10, 0.0)], 3: [(0, 5, 5, 0.0)]}))
    assert res["frames"] == 2 and res["pred"] == 2 and res["precision"] == 0.5 and res["unscored_frames"] == 0
    res = evaluate_tools(_gt({1: [(10, 10, 0.0)]}), {})
    assert res["recall"] == 0.0 and res["precision"] is None
    assert "precision n/a (0/0)" in format_report(res)
    res = evaluate_tools({}, {})
    assert res["frames"] == 0 and res["recall"] is None and res["precision"] is None


def test_angle_wraps_around():
    res = evaluate_tools(_gt({1: [(100, 100, 0.05)]}), _pred({1: [(0, 100, 100, 2 * math.pi - 0.05)]}))
    assert res["median_angle_error_deg"] == pytest.approx(math.degrees(0.1))
    res = evaluate_tools(_gt({1: [(100, 100, 0.0)]}), _pred({1: [(0, 100, 100, math.pi + 0.2)]}))
    assert res["median_angle_error_deg"] == pytest.approx(180 - math.degrees(0.2))
    gt = _gt({1: [(0, 0, 0.0), (100, 0, 0.0), (200, 0, 0.0)]})
    res = evaluate_tools(gt, _pred({1: [(0, 0, 0, 0.1), (1, 100, 0, 0.2), (2, 200, 0, 0.9)]}))
    assert res["median_angle_error_deg"] == pytest.approx(math.degrees(0.2))


def test_track_change_is_one_switch():
    heads = {f: [(100.0 + 3 * f, 50.0, 1.0)] for f in range(10)}
    pred = _pred({f: [(1 if f < 5 else 2, x, y, a) for x, y, a in hs] for f, hs in heads.items()})
    res = evaluate_tools(_gt(heads), pred)
    assert res["id_switches"] == 1 and res["matched"] == 10
    assert "identity switches: 1" in format_report(res)
    pred = _pred({f: [(1 if f % 2 else 2, x, y, a) for x, y, a in hs] for f, hs in heads.items()})
    assert evaluate_tools(_gt(heads), pred)["id_switches"] == 9
    # an unmatched frame in between keeps the last track: back on track 1 is no switch
    pred = _pred({f: [(1, x + (30 if f == 4 else 0), y, a) for x, y, a in hs] for f, hs in heads.items()})
    res = evaluate_tools(_gt(heads), pred)
    assert res["matched"] == 9 and res["id_switches"] == 0


def test_swapped_tool_order_is_no_switch():
    heads = _two_tools()
    gt = _gt({f: (hs[::-1] if f % 2 else hs) for f, hs in heads.items()})        # tool 0 / 1 swap every frame
    pred = _pred({f: [(7, *hs[0]), (9, *hs[1])] for f, hs in heads.items()})
    res = evaluate_tools(gt, pred)
    assert res["matched"] == 20 and res["id_switches"] == 0
    # the tracker swapping its two tracks half-way is two switches, whatever the tool order
    pred = _pred({f: [(7 if f < 5 else 9, *hs[0]), (9 if f < 5 else 7, *hs[1])] for f, hs in heads.items()})
    assert evaluate_tools(gt, pred)["id_switches"] == 2


def test_gt_identity_breaks_beyond_link():
    # the instrument jumps 60 px between frames 4 and 5: a new true identity, so a new track is no switch
    heads = {f: [(100.0 + (60 if f >= 5 else 0), 50.0, 1.0)] for f in range(10)}
    pred = _pred({f: [(1 if f < 5 else 2, x, y, a) for x, y, a in hs] for f, hs in heads.items()})
    assert evaluate_tools(_gt(heads), pred)["id_switches"] == 0
    assert evaluate_tools(_gt(heads), pred, link=80)["id_switches"] == 1


def test_continuing_track_preferred():
    # two tracks within the radius of one head, the nearer alternating: the head keeps its first track
    heads = {f: [(100.0, 50.0, 1.0)] for f in range(6)}
    pred = _pred({f: [(1, 100 + (2 if f % 2 else 1), 50, 1.0), (2, 100 - (1 if f % 2 else 2), 50, 1.0)]
                  for f in range(6)})
    res = evaluate_tools(_gt(heads), pred)
    assert res["matched"] == 6 and res["id_switches"] == 0


@pytest.mark.parametrize("kwargs", [{"radius": 0}, {"radius": -1}, {"radius": math.nan}, {"link": 0}, {"fps": 0},
                                    {"fps": math.inf}])
def test_bad_parameters(kwargs):
    with pytest.raises(InputError):
        evaluate_tools(_gt({1: [(1, 1, 0.0)]}), {}, **kwargs)


def test_bad_arrays():
    with pytest.raises(InputError, match=r"\(k, 4\)"):
        evaluate_tools({1: np.zeros((2, 3))}, {})
    with pytest.raises(InputError, match=r"\(k, 6\)"):
        evaluate_tools({}, {1: np.zeros((2, 4))})


def test_no_frame_in_common_is_an_error(tmp_path, run_cli):
    """Predictions numbered from 1 against annotations numbered by file name: recall 0 would blame
    the predictor; the frame numbers do not match."""
    with pytest.raises(InputError, match=r"annotated frames 1-2, predicted 101-102"):
        evaluate_tools(_gt({1: [(10, 10, 0.0)], 2: [(10, 10, 0.0)]}),
                       _pred({101: [(0, 10, 10, 0.0)], 102: [(0, 10, 10, 0.0)]}))
    gt = _write(tmp_path, f"{TOOLS_HEADER}\n1,0,10,10,20,0\n", "gt.csv")
    pred = _write(tmp_path, f"{PRED_HEADER}\n101,0,10,10,20,0,1\n", "pred.csv")
    code, out, err = run_cli("tool", "eval", str(gt), str(pred))
    assert code == 2 and err.count("\n") == 1 and "pred.csv: no predicted frame is an annotated one" in err


def test_sparse_annotations_score_only_the_annotated_frames(tmp_path, run_cli):
    """Annotations of every 5th frame against perfect predictions on every frame scored a precision
    of 0.2 (every prediction on a frame without annotation a false one); the frames without
    annotation are not scored, and the report says how many predictions were left out."""
    heads = _two_tools(30)
    pred = _pred({f: [(i, *h) for i, h in enumerate(hs)] for f, hs in heads.items()})
    gt = _gt({f: hs for f, hs in heads.items() if f % 5 == 0})
    res = evaluate_tools(gt, pred)
    assert res["frames"] == 6 and res["gt"] == res["pred"] == res["matched"] == 12
    assert res["recall"] == res["precision"] == 1.0
    assert res["unscored_frames"] == 24 and res["unscored_pred"] == 48
    assert "not scored: 48 predicted heads on 24 frames that are not annotated" in format_report(res)
    assert "not scored" not in format_report(evaluate_tools(gt, {f: p for f, p in pred.items() if f % 5 == 0}))
    # the same through 'tool eval'
    write_predictions(tmp_path / "pred.csv", pred)
    rows = "".join(f"{f},{k},{y},{x},20,{a}\n" for f, hs in heads.items() if f % 5 == 0 for k, (x, y, a) in enumerate(hs))
    gt_csv = _write(tmp_path, f"{TOOLS_HEADER}\n{rows}", "gt.csv")
    code, out, err = run_cli("tool", "eval", gt_csv, tmp_path / "pred.csv")
    assert code == 0, err
    assert "precision 1.000 (12/12)" in out and "not scored: 48 predicted heads on 24 frames" in out


def test_a_row_off_the_annotations_grid_is_said(tmp_path, run_cli):
    """Annotations of every 5th frame plus one stray row (frame 12) made every frame count as
    annotated and the empty ones as showing no instrument (precision 1.0 -> 0.25) without a word:
    tool eval now says which frame lies off the grid most frames share."""
    from artmotion.tracking.instruments.evaluate import grid_note

    heads = _two_tools(40)
    every5 = {f: hs for f, hs in heads.items() if f % 5 == 0}
    assert grid_note(_gt(every5)) == "" and grid_note(_gt(heads)) == ""
    assert grid_note(_gt({0: heads[0], 10: heads[10], 25: heads[0]})) == ""   # (no gap most share)
    first = grid_note(_gt({**{f: h for f, h in every5.items() if f}, 3: heads[3]}))    # the stray row first
    assert first.startswith("most annotated frames are 5 apart, but frame 3 lies off that grid"), first
    note = grid_note(_gt({**every5, 12: heads[12]}))
    assert note.startswith("most annotated frames are 5 apart, but frame 12 lies off that grid: every 1 frame(s) "
                           "from 0 to 35 count as annotated (27 without a row"), note
    rows = "".join(f"{f},{k},{y},{x},20,{a}\n" for f, hs in sorted({**every5, 12: heads[12]}.items())
                   for k, (x, y, a) in enumerate(hs))
    gt_csv = _write(tmp_path, f"{TOOLS_HEADER}\n{rows}", "gt.csv")
    write_predictions(tmp_path / "pred.csv", _pred({f: [(i, *h) for i, h in enumerate(hs)] for f, hs in heads.items()}))
    code, out, err = run_cli("tool", "eval", gt_csv, tmp_path / "pred.csv")
    assert code == 0 and f"note: {gt_csv}: most annotated frames are 5 apart, but frame 12" in err, err


def test_a_frame_on_the_annotations_grid_without_a_row_shows_no_instrument():
    """Annotations of every frame with a gap (no instrument in view): a prediction there is a false
    one, as it is on an every-5th frame without rows; frames off the grid are not scored."""
    from artmotion.tracking.instruments.evaluate import annotated_frames

    heads = _two_tools(12)
    pred = _pred({f: [(i, *h) for i, h in enumerate(hs)] for f, hs in heads.items()})
    gt = _gt({f: hs for f, hs in heads.items() if f != 6})
    res = evaluate_tools(gt, pred)
    assert res["precision"] == pytest.approx(22 / 24) and res["unscored_frames"] == 0
    assert annotated_frames(_gt({0: heads[0], 10: heads[10], 25: heads[0]})) == [0, 5, 10, 15, 20, 25]
    assert annotated_frames({}) == []
