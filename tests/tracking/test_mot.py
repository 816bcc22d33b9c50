"""Multi-object tracking with group nodes on a synthetic crossing (thesis Sec. 2.5)."""

from __future__ import annotations

import numpy as np
import pytest

from artmotion.geometry import iou
from artmotion.tracking import track
from artmotion.tracking.mot import side_of

from _synth import H, W, crossing, write_mot_folder

N = 40


def _dets(truth, hidden):
    rows = []
    for k in range(N):
        for i, boxes in truth.items():
            if i == 2 and k in hidden:
                continue            # the detector misses the blob that is behind
            rows.append([k + 1, -1, *boxes[k], 0.95])
    return rows


@pytest.fixture(scope="module")
def crossing_seq(tmp_path_factory):
    frames, truth = crossing(N)
    dx = np.abs(truth[1][:, 0] - truth[2][:, 0])
    hidden = set(np.where(dx < 40)[0])
    root = write_mot_folder(tmp_path_factory.mktemp("cross") / "cross", frames, _dets(truth, hidden))
    return root, truth, hidden


def _owner(res, truth, k):
    """Track ids whose box on frame k+1 matches each truth blob (IoU >= 0.5)."""
    rows = res.tracks[res.tracks[:, 0] == k + 1]
    out = {}
    for i, boxes in truth.items():
        ious = [iou(r[2:6], boxes[k]) for r in rows]
        if ious and max(ious) >= 0.5:
            out[i] = int(rows[int(np.argmax(ious)), 1])
    return out


@pytest.mark.parametrize("experts", [("det", "klt", "blob", "motion", "flow"), ("det", "motion")])
def test_identities_survive_the_crossing(crossing_seq, experts):
    root, truth, hidden = crossing_seq
    res = track(root, experts=experts)
    first, last = _owner(res, truth, 2), _owner(res, truth, N - 1)
    assert set(first) == {1, 2} and first[1] != first[2]
    assert last == first, "identities swapped by the crossing"
    assert res.num_tracks == 2
    # through the occlusion, every frame still has both blobs (group interpolation, Sec. 2.5.3)
    covered = sum(len(_owner(res, truth, k)) for k in range(N))
    assert covered >= 2 * N - 6
    types = [e["type"] for e in res.events]
    assert "merge" in types and "split" in types
    merge = next(e for e in res.events if e["type"] == "merge")
    split = next(e for e in res.events if e["type"] == "split")
    assert sorted(merge["tracks"]) == sorted(first.values()) == sorted(split["tracks"])
    assert merge["group"] == split["group"] and merge["frame"] < split["frame"]
    assert min(hidden) <= merge["frame"] + 1 and split["frame"] >= max(hidden)


def test_online_mode_is_causal_and_keeps_identities(crossing_seq):
    root, truth, _ = crossing_seq
    res = track(root, online=True)
    first, last = _owner(res, truth, 5), _owner(res, truth, N - 1)
    assert set(first) == {1, 2} and last == first
    # online results start only once a track is confirmed (no back-filling of frames 1-2)
    assert res.tracks[:, 0].min() >= 3


def test_enter_and_exit_events(crossing_seq):
    root, truth, _ = crossing_seq
    res = track(root)
    enters = [e for e in res.events if e["type"] == "enter"]
    assert len(enters) == 2 and all(e["frame"] == 1 for e in enters)
    for e in res.events:
        assert {"type", "frame", "tracks"} <= set(e) and isinstance(e["frame"], int)
        assert all(isinstance(t, int) for t in e["tracks"])


def test_result_rows_are_mot_format(crossing_seq):
    root, _, _ = crossing_seq
    res = track(root)
    t = res.tracks
    assert t.shape[1] == 10 and len(t)
    assert np.all(t[:, 7:] == -1) and np.all(t[:, 4:6] > 0)
    assert np.all(np.diff(t[:, 0]) >= 0)
    # one box per id and frame
    keys = {(int(f), int(i)) for f, i in t[:, :2]}
    assert len(keys) == len(t)


def test_false_detection_without_support_is_not_a_track(tmp_path):
    """An isolated low-score detection on static background starts nothing."""
    frames, truth = crossing(12)
    rows = [[k + 1, -1, *truth[1][k], 0.95] for k in range(12)]
    rows += [[k + 1, -1, 250, 20, 28, 60, 0.6] for k in range(3, 6)]     # static, low score
    root = write_mot_folder(tmp_path / "fp", frames, rows)
    res = track(root)
    assert res.num_tracks == 1


def test_side_of():
    assert side_of([0, 100, 20, 40], W, H) == "left"
    assert side_of([W - 21, 100, 20, 40], W, H) == "right"
    assert side_of([150, 100, 20, 40], W, H) == "inside"
