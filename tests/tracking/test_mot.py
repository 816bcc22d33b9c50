"""Multi-object tracking with group nodes on a synthetic crossing (thesis Sec. 2.5)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from artmotion.geometry import iou
from artmotion.tracking import TrackerConfig, track
from artmotion.tracking.mot import collapse_group_flicker, side_of

from _synth import H, W, crossing, moving_blob, replay_groups, texture, write_mot_folder

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
    res = track(root, online=True, config=TrackerConfig(confirm_hits=3))
    first, last = _owner(res, truth, 5), _owner(res, truth, N - 1)
    assert set(first) == {1, 2} and last == first
    # online results start only once a track is confirmed (no back-filling of frames 1-2) ...
    assert res.tracks[:, 0].min() == 3
    # ... offline, the frames before the confirmation are part of the track
    assert track(root, config=TrackerConfig(confirm_hits=3)).tracks[:, 0].min() == 1


@pytest.mark.parametrize("online", [False, True])
def test_no_enter_or_exit_for_people_there_at_the_start_and_the_end(crossing_seq, online):
    """Both blobs are in view from frame 1 to the last frame: they neither enter nor exit."""
    root, truth, _ = crossing_seq
    res = track(root, online=online)
    assert res.num_tracks == 2
    assert not [e for e in res.events if e["type"] in ("enter", "exit")], res.events
    for e in res.events:
        assert {"type", "frame", "tracks"} <= set(e) and isinstance(e["frame"], int)
        assert all(isinstance(t, int) for t in e["tracks"])


@pytest.mark.parametrize("online", [False, True])
def test_enter_from_the_left_and_exit_to_the_right(tmp_path, online):
    """A blob walking in from the left and out on the right: one enter (left), one exit (right)."""
    frames, truth = moving_blob(n=60, v=(6.0, 0.0), start=(-40.0, 90.0))
    inside = [k for k, b in enumerate(truth) if b[0] >= -0.3 * b[2] and b[0] + b[2] <= W + 0.3 * b[2]]
    rows = [[k + 1, -1, *truth[k], 0.95] for k in inside]
    root = write_mot_folder(tmp_path / "walk", frames, rows)
    res = track(root, online=online)
    assert res.num_tracks == 1
    enters = [e for e in res.events if e["type"] == "enter"]
    exits = [e for e in res.events if e["type"] == "exit"]
    assert len(enters) == 1 and enters[0]["side"] == "left" and enters[0]["frame"] > 1
    assert len(exits) == 1 and exits[0]["side"] == "right" and exits[0]["frame"] < 60


@pytest.mark.parametrize("online", [False, True])
def test_a_person_who_vanishes_shortly_before_the_end_exits(tmp_path, online):
    """A blob detected on frames 1-30 of 40 and then no more, in the middle of the image: the
    tracker still held its track (lost for 1 s, under ``max_lost``) when the clip ended, and the
    events had said nothing of it, though the output shows nobody after frame 30."""
    frames, truth = moving_blob(n=40, v=(2.0, 0.0), start=(60.0, 80.0))
    rows = [[k + 1, -1, *truth[k], 0.95] for k in range(30)]
    root = write_mot_folder(tmp_path / "vanish", frames, rows)
    res = track(root, online=online)
    assert res.num_tracks == 1
    last = int(res.tracks[:, 0].max())
    assert last < 40
    exits = [e for e in res.events if e["type"] == "exit"]
    assert len(exits) == 1 and exits[0]["frame"] == last and exits[0]["side"] == "inside"


def _jittery_crossing(tmp_path, flicker):
    """The crossing with noisy boxes and a longer occlusion in which the hidden blob's detection
    briefly comes back (frames ``flicker``): the group splits and re-forms at once."""
    frames, truth = crossing(N)
    dx = np.abs(truth[1][:, 0] - truth[2][:, 0])
    hidden = set(np.where(dx < 60)[0]) - set(flicker)
    rng = np.random.default_rng(0)
    rows = []
    for k in range(N):
        for i, boxes in truth.items():
            if i == 2 and k in hidden:
                continue
            rows.append([k + 1, -1, *(boxes[k] + rng.normal(0, 1.0, 4) * [1, 1, 0.5, 0.5]), 0.95])
    return write_mot_folder(tmp_path / "jitter", frames, rows)


def test_one_crossing_gives_one_merge_and_one_split(tmp_path):
    # the hidden blob is detected once at the middle of the crossing (frame 20), while the two
    # boxes still overlap; a low merge threshold lets the group form before and re-form after it
    root = _jittery_crossing(tmp_path, flicker=[19])
    cfg = dict(merge_iou=0.1)
    # without hysteresis the group flickers: split, re-merge, split
    raw = [e for e in track(root, config=TrackerConfig(split_hold=0, **cfg)).events if e["type"] in ("merge", "split")]
    assert len(raw) > 2, raw
    res = track(root, config=TrackerConfig(**cfg))
    assert res.num_tracks == 2
    group = [e for e in res.events if e["type"] in ("merge", "split")]
    assert [e["type"] for e in group] == ["merge", "split"], group
    merge, split = group
    assert merge["group"] == split["group"] and merge["tracks"] == split["tracks"] == [1, 2]
    assert split["frame"] == raw[-1]["frame"], "the split that holds is the last one"


def _g(kind, frame, tracks, group):
    return {"type": kind, "frame": frame, "tracks": tracks, "group": group, "x": 0.0, "y": 0.0}


def test_collapse_group_flicker():
    tud = [_g("merge", 34, [1, 6], 2), _g("split", 37, [1, 6], 2), _g("merge", 37, [1, 6], 3),
           _g("split", 38, [1, 6], 3), _g("merge", 38, [1, 6], 4), _g("split", 40, [1, 6], 4)]
    out = collapse_group_flicker(tud, hold=8)
    assert [(e["type"], e["frame"], e["group"]) for e in out] == [("merge", 34, 2), ("split", 40, 2)]
    # a split that holds longer than the hold time is a new interaction
    apart = [_g("merge", 10, [1, 2], 1), _g("split", 15, [1, 2], 1), _g("merge", 30, [1, 2], 2),
             _g("split", 35, [1, 2], 2)]
    assert collapse_group_flicker(apart, hold=8) == apart
    # other members re-merging is not the same group
    other = [_g("merge", 10, [1, 2], 1), _g("split", 15, [1, 2], 1), _g("merge", 16, [3, 4], 2)]
    assert collapse_group_flicker(other, hold=8) == other
    # a third person joining while the group re-forms: one merge into the old group
    join = [_g("merge", 10, [1, 2], 1), _g("split", 15, [1, 2], 1), _g("merge", 16, [1, 2, 3], 2),
            _g("split", 30, [1, 2, 3], 2)]
    out = collapse_group_flicker(join, hold=8)
    assert [(e["type"], e["frame"], e["tracks"], e["group"]) for e in out] == [
        ("merge", 10, [1, 2], 1), ("merge", 16, [1, 2, 3], 1), ("split", 30, [1, 2, 3], 1)]


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
    """A repeated detection scoring below the birth threshold starts nothing."""
    frames, truth = crossing(12)
    rows = [[k + 1, -1, *truth[1][k], 0.95] for k in range(12)]
    low = TrackerConfig().high - 0.05
    rows += [[k + 1, -1, 250, 20, 28, 60, low] for k in range(3, 6)]     # static, low score
    root = write_mot_folder(tmp_path / "fp", frames, rows)
    res = track(root)
    assert res.num_tracks == 1


def test_side_of():
    assert side_of([0, 100, 20, 40], W, H) == "left"
    assert side_of([W - 21, 100, 20, 40], W, H) == "right"
    assert side_of([150, 100, 20, 40], W, H) == "inside"


def test_collapse_keeps_the_event_stream_consistent_when_someone_briefly_leaves():
    # 4 leaves the group of 1, 4, 5 (split + merge of those who stay) and is back two frames later
    evs = [_g("merge", 10, [1, 4, 5], 1), _g("split", 15, [1, 4, 5], 1), _g("merge", 15, [1, 5], 1),
           _g("merge", 17, [1, 4, 5], 1), _g("split", 30, [1, 4, 5], 1)]
    out = collapse_group_flicker(evs, hold=8)
    assert [(e["type"], e["frame"], e["tracks"]) for e in out] == [
        ("merge", 10, [1, 4, 5]), ("split", 30, [1, 4, 5])]


@pytest.mark.parametrize("online", [False, True])
def test_group_events_replay_consistently(tmp_path, online):
    res = track(_jittery_crossing(tmp_path, flicker=[20, 22]), online=online)
    assert replay_groups(res.events) == {}


def _panning_scene(tmp_path):
    """A person standing still while the camera is still for 20 frames, then pans 8 px/frame;
    the detector misses the person on frames 21-28, exactly when the pan starts."""
    rng = np.random.default_rng(2)
    world = cv2.GaussianBlur(rng.integers(0, 255, (H, W + 400, 3), dtype=np.uint8), (3, 3), 0)
    person = texture(28, 64, (40, 40, 220), seed=4)
    frames, rows = [], []
    for k in range(45):
        pan = 0 if k < 20 else 8 * (k - 19)
        img = world[:, pan:pan + W].copy()
        x = 150 - pan
        if x + 28 > 0:
            img[80:144, max(0, x):x + 28] = person[:, max(0, -x):]
        frames.append(img)
        if not 20 <= k < 28 and x >= 0:
            rows.append([k + 1, -1, x, 80, 28, 64, 0.95])
    return write_mot_folder(tmp_path / "pan", frames, rows)


def test_camera_motion_keeps_a_track_through_a_pan(tmp_path):
    root = _panning_scene(tmp_path)
    with_cam = track(root)
    without = track(root, config=TrackerConfig(camera=False))
    assert with_cam.num_tracks == 1, with_cam.tracks[:, :2]
    assert without.num_tracks == 2          # the prediction stays where the person stood


@pytest.mark.parametrize("every", [2, 3])
def test_detector_on_every_kth_frame_is_carried_between(every):
    """Frames the detector skipped (detections None) are predicted, count no misses and are
    filled by the offline pass: one track with a box on every frame (the detector runs on the
    last frame too); a frame where the detector ran and found nothing is a miss (counted in
    frames of time, so max_lost keeps its meaning)."""
    from artmotion.tracking import MultiObjectTracker, TrackerConfig, run_tracker

    frames, truth = moving_blob(n=30)
    dets = {k + 1: np.array([[*truth[k], 0.95]]) for k in range(30)}
    fps = 10.0
    t = MultiObjectTracker(fps, W, H, config=TrackerConfig())
    n = run_tracker(t, ((k + 1, f) for k, f in enumerate(frames)), dets, detect_every=every)
    rows, _ = t.finish(n)
    assert len(np.unique(rows[:, 1])) == 1
    # the detector runs on the last frame too: the frames after its last k-th frame are boxed
    assert set(rows[:, 0].astype(int)) == set(range(1, 31))
    err = np.abs(rows[np.argsort(rows[:, 0]), 2:6] - np.array(truth)).max()
    assert err < 6.0, err
    # the detector runs but finds nothing after frame 10: the track is lost after max_lost s
    # whatever k is (misses are frames of time, not detector runs)
    gone = {f: (d if f <= 10 else np.zeros((0, 5))) for f, d in dets.items()}
    ends = []
    for k in (1, every):
        t = MultiObjectTracker(fps, W, H, config=TrackerConfig(max_lost=1.0))
        live: list[int] = []
        run_tracker(t, ((j + 1, f) for j, f in enumerate(frames)), gone, detect_every=k,
                    on_frame=lambda _, t=t, live=live: live.append(len(t.tracks)))
        ends.append(max(j + 1 for j, m in enumerate(live) if m))
    # lost after frame 10 for 1 s (10 frames); with k > 1 the end is seen at a detected frame
    assert 19 <= ends[0] <= 22 and abs(ends[1] - ends[0]) < every, ends


def test_collapse_terminates_when_two_groups_continue_each_other():
    """Two groups split at once and each re-forms under the other's id: the renames must not
    form a cycle (they once did, and the next event of either group looped for ever)."""
    import signal

    evs = [_g("split", 10, [3, 4], 2), _g("split", 10, [1, 2], 1), _g("merge", 11, [1, 2], 2),
           _g("merge", 12, [3, 4], 1), _g("split", 30, [1, 2], 2), _g("split", 31, [3, 4], 1)]

    def stuck(signum, frame):
        raise TimeoutError("collapse_group_flicker does not terminate")

    old = signal.signal(signal.SIGALRM, stuck)
    signal.setitimer(signal.ITIMER_REAL, 5.0)
    try:
        out = collapse_group_flicker(evs, hold=8)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    # both splits at frame 10 were undone by the re-merges; each pair splits once, for good
    assert [(e["type"], e["frame"], e["tracks"]) for e in out] == [("split", 30, [1, 2]), ("split", 31, [3, 4])]
    assert [e["group"] for e in out] == [1, 2]   # each pair keeps the id of the group it was
