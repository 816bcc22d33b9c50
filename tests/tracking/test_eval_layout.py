"""`eval` on ground truth whose lines disagree on the layout (found by a fuzzing review)."""


def _gt(tmp_path, extra=""):
    gt = tmp_path / "gt.txt"
    gt.write_text("".join(f"{f},1,10,10,20,40,1,1,1\n{f},2,100,10,20,40,1,1,0.5\n" for f in range(1, 6)) + extra)
    res = tmp_path / "res.txt"
    res.write_text("".join(f"{f},1,10,10,20,40,1,-1,-1,-1\n" for f in range(1, 6)))
    return gt, res


def test_a_10_value_line_in_9_column_ground_truth_is_an_error(tmp_path, run_cli):
    """One such line switched the whole file from MOT17's rules to MOT15's, in silence."""
    gt, res = _gt(tmp_path)
    code, out, err = run_cli("eval", gt, res)
    assert code == 0 and "MOT17" in out, err
    gt, res = _gt(tmp_path, "5,9,1,1,10,10,1,-1,-1,-1\n")
    code, out, err = run_cli("eval", gt, res)
    assert code == 2 and err.count("\n") == 1
    assert "gt.txt:11: 10 values on this line but 9 on line 1" in err


def test_a_consider_flag_other_than_0_or_1_is_an_error(tmp_path, run_cli):
    gt, res = _gt(tmp_path)
    gt.write_text(gt.read_text().replace("3,1,10,10,20,40,1,1,1", "3,1,10,10,20,40,5,1,1"))
    code, out, err = run_cli("eval", gt, res)
    assert code == 2 and "consider flag 5 (frame 3) is neither 0 nor 1" in err
