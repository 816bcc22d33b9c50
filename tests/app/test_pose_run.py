"""`artmotion run --pose-model`: the tool's opening and closing become sentences (thesis 5.1.2)."""

import csv

import numpy as np

from artmotion.language.describe import pose_changes


def test_run_with_pose_model_says_when_the_tool_opens_and_closes(tmp_path, run_cli):
    train, seq = tmp_path / "train", tmp_path / "seq"
    assert run_cli("pose", "render", train, "--poses", "200", "--seed", "6", "--no-frames")[0] == 0
    assert run_cli("pose", "train", train / "crops", train / "labels.csv", "--model", tmp_path / "m.npz")[0] == 0
    assert run_cli("pose", "render", seq, "--poses", "120", "--seed", "5")[0] == 0
    boxes = list(csv.DictReader(open(seq / "boxes.csv")))
    det = tmp_path / "det.txt"
    det.write_text("".join(f"{i},-1,{r['x']},{r['y']},{r['w']},{r['h']},1,-1,-1,-1\n" for i, r in enumerate(boxes, 1)))
    code, out, err = run_cli("run", seq / "frames", "--det", det, "--class", "tool", "--pose-model",
                             tmp_path / "m.npz", "--out", tmp_path / "run", "--no-video")
    assert code == 0, err
    said = [(int(line.split("frame ")[-1].rstrip(").")), "opens" if " opens " in line else "closes")
            for line in (tmp_path / "run" / "sentences.txt").read_text().splitlines()
            if line.startswith("Tool 1 opens") or line.startswith("Tool 1 closes")]
    labels = list(csv.DictReader(open(seq / "labels.csv")))
    truth = pose_changes(np.arange(1, len(labels) + 1), np.array([float(r["opening"]) for r in labels]))
    assert len(truth) >= 2, "the rendered sequence should open and close"
    # Every sentence matches a true change, in order and within 20 frames (the filter lags); the
    # last change may go unsaid when too few frames follow it.
    assert {v for _, v in said} == {"opens", "closes"}
    j = 0
    for f, verb in said:
        while j < len(truth) and not (truth[j][1] == verb and abs(truth[j][0] - f) <= 20):
            j += 1
        assert j < len(truth), f"'{verb}' at frame {f} matches no true change {truth}"
        j += 1
