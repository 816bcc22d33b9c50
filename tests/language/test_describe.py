"""The sentence grammar on hand-made tracks, events and pose sequences."""

import json

import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.io import write_events, write_mot
from artmotion.language.describe import (
    describe,
    direction_word,
    parse_classes,
    pose_changes,
    read_pose,
)
from artmotion.language.grammar import Triplet, render

W, H = 640, 480


def box_rows(tid, frames, xs, ys, w=40, h=100):
    return [[f, tid, x, y, w, h, 1, -1, -1, -1] for f, x, y in zip(frames, xs, ys)]


def scene():
    """Track 1 enters from the left and walks right, leaving at the right border; tracks 2 and 3
    walk together upwards; track 4 stands still; all within a 640x480 image, frames 1..100."""
    rows = []
    f = np.arange(10, 91)
    rows += box_rows(1, f, np.linspace(0, W - 40, len(f)), np.full(len(f), 200))
    f = np.arange(1, 101)
    rows += box_rows(2, f, np.full(100, 100), np.linspace(370, 10, 100))
    rows += box_rows(3, f, np.full(100, 150), np.linspace(375, 15, 100))
    rows += box_rows(4, f, np.full(100, 400), np.full(100, 300))
    return np.array(rows, float)


def sentences(triplets):
    return [t.sentence for t in triplets]


def test_enter_left_move_right_exit_right_derived_from_tracks():
    out = describe(scene(), image_size=(W, H))
    s = sentences(out)
    assert "Person 1 enters from the left at frame 10." in s
    assert "Person 1 moves right from frame 10 to frame 90." in s
    assert "Person 1 exits to the right at frame 90." in s
    assert "Person 4 stays in place from frame 1 to frame 100." in s
    # tracks present from the first frame to the last neither enter nor exit
    assert not any(t.verb in ("enters", "exits", "appears", "vanishes") and t.tracks == [4] for t in out)
    # every sentence names its tracks
    for t in out:
        assert t.tracks and all(f"erson {i}" in t.sentence for i in t.tracks)


def test_walk_together_and_directions():
    s = sentences(describe(scene(), image_size=(W, H)))
    assert "Person 2 and person 3 walk together upwards from frame 1 to frame 100." in s
    assert "Person 2 moves upwards from frame 1 to frame 100." in s
    # the still person never walks with anybody
    assert not any("person 4" in x.lower() and "together" in x for x in s)


def test_a_chain_of_people_walking_side_by_side():
    """Ten people side by side, each beside the next for 85 frames and the first and last never
    together: the group had no common frame, its span became the union, and reading members
    outside their own frames was an IndexError (or, before their first frame, a wrapped index)."""
    rows = []
    for k in range(10):
        f = np.arange(max(1, 1 + 15 * (k - 1)), 101 + 15 * k)
        rows += box_rows(k + 1, f, 100 + 2 * f + 20 * k, np.full(len(f), 200))
    tracks = np.array(rows, float)
    together = [t for t in describe(tracks, image_size=(1200, 600)) if t.verb == "walk together"]
    assert together
    for t in together:
        for m in t.tracks:          # every member is there on every frame of its sentence
            frames = tracks[tracks[:, 1] == m, 0]
            assert frames.min() <= t.frames[0] and t.frames[1] <= frames.max(), t.sentence
        assert t.adjective == "right", t.sentence


def test_pairs_left_out_could_never_be_together(monkeypatch):
    """Pairs of tracks far apart or never on one frame are not compared (a long video has many
    tracks); what is said is the same as when every pair is compared. Random walkers, some close."""
    from artmotion.language import describe as mod

    rng = np.random.default_rng(3)
    rows = []
    for tid in range(1, 41):
        first = int(rng.integers(1, 150))
        f = np.arange(first, first + int(rng.integers(20, 120)))
        x0, y0 = rng.uniform(0, 500, 2)
        vx, vy = rng.normal(0, 1.5, 2)
        rows += box_rows(tid, f, x0 + vx * (f - first), y0 + vy * (f - first) + rng.normal(0, 1, len(f)))
    rows += box_rows(41, np.arange(1, 100), np.linspace(100, 400, 99), np.full(99, 200))
    rows += box_rows(42, np.arange(1, 100), np.linspace(140, 440, 99), np.full(99, 205))
    rows = np.array(rows, float)
    fast = sentences(describe(rows))
    ids = lambda tracks, near: ((a.tid, b.tid) for k, a in enumerate(tracks) for b in tracks[k + 1:])  # noqa: E731
    monkeypatch.setattr(mod, "_near_pairs", ids)
    every = sentences(describe(rows))
    assert fast == every
    assert any(" and " in s for s in every)           # pairs were said something of


def test_image_size_inferred_from_extents():
    s = sentences(describe(scene()))
    assert "Person 1 exits to the right at frame 90." in s


def test_direction_changes_split_the_motion():
    f = np.arange(1, 81)
    x = np.where(f <= 40, 100 + 5 * f, 300 - 5 * (f - 40))
    rows = np.array(box_rows(7, f, x, np.full(80, 200)), float)
    s = sentences(describe(rows, image_size=(W, H)))
    moves = [x for x in s if "moves" in x]
    assert len(moves) == 2, s
    assert moves[0].startswith("Person 7 moves right from frame 1 to frame")
    assert moves[1].startswith("Person 7 moves left from frame")


def test_direction_words():
    assert direction_word(10, 1) == "right"
    assert direction_word(-10, 0) == "left"
    assert direction_word(0, 10) == "downwards"
    assert direction_word(1, -10) == "upwards"
    assert direction_word(10, 8) == "right and downwards"


def test_events_merge_split_and_sides():
    events = [
        {"type": "enter", "frame": 10, "tracks": [1], "side": "left"},
        {"type": "merge", "frame": 40, "tracks": [2, 3], "group": 9},
        {"type": "split", "frame": 60, "tracks": [2, 3], "group": 9},
        {"type": "exit", "frame": 90, "tracks": [1], "side": "right"},
        {"type": "enter", "frame": 5, "tracks": [4], "side": "inside"},
        {"type": "teleport", "frame": 7, "tracks": [4]},
    ]
    out = describe(scene(), events, classes=parse_classes(["person", "4=cart"]))
    s = sentences(out)
    assert "Person 1 enters from the left at frame 10." in s
    assert "Person 2 and person 3 merge into one group at frame 40." in s
    assert "Person 2 and person 3 split from their group at frame 60." in s
    assert "Person 1 exits to the right at frame 90." in s
    assert "Cart 4 appears inside the image at frame 5." in s
    assert not any("teleport" in x for x in s)
    merge = next(t for t in out if t.verb == "merge")
    assert merge.tracks == [2, 3] and merge.object == "group 9" and merge.frames == (40, 40)
    # sentences are in time order
    assert [t.frames[0] for t in out] == sorted(t.frames[0] for t in out)


def test_class_names_in_any_script():
    """--class takes letters of any script (it took ASCII only: "café" was refused), not digits
    or underscores."""
    f = np.arange(1, 61)
    rows = box_rows(1, f, 100 + 3 * f, np.full(60, 200)) + box_rows(2, f, 130 + 3 * f, np.full(60, 220), w=60, h=80)
    out = describe(np.array(rows, float), classes=parse_classes(["Überwagen", "2=café"]), image_size=(W, H))
    assert "Überwagen 1 interacts with café 2 from frame 1 to frame 60." in sentences(out)
    for bad in ("a1", "a_b", "-a", "2=3"):
        with pytest.raises(InputError, match="--class"):
            parse_classes([bad])


def test_interaction_between_classes():
    f = np.arange(1, 61)
    rows = box_rows(1, f, 100 + 3 * f, np.full(60, 200)) + box_rows(2, f, 130 + 3 * f, np.full(60, 220), w=60, h=80)
    out = describe(np.array(rows, float), classes=parse_classes(["2=cart"]), image_size=(W, H))
    assert "Person 1 interacts with cart 2 from frame 1 to frame 60." in sentences(out)


def test_times_with_fps():
    out = describe(scene(), image_size=(W, H), fps=10)
    t = next(t for t in out if t.verb == "enters")
    assert t.sentence == "Person 1 enters from the left at 0.9 s (frame 10)."
    assert t.to_dict()["times"] == [0.9, 0.9]


def test_a_stretch_of_two_frames_is_not_told_as_an_instant():
    """At 25 frames/s, frames 63-64 were "from 2.5 s to 2.5 s"; as many decimals as tell the ends apart."""
    t = Triplet("Person 12", "stays", None, frames=(63, 64), times=(62 / 25, 63 / 25))
    assert render(t) == "Person 12 stays in place from 2.48 s to 2.52 s (frames 63-64)."
    t = Triplet("Person 1", "stays", None, frames=(10, 40), times=(0.9, 3.9))
    assert "from 0.9 s to 3.9 s" in render(t)
    assert "from 0.000 s to 0.001 s" in render(Triplet("Person 1", "stays", None, frames=(1, 2), times=(0.0, 0.001)))


def test_grammar_rejects_words_outside_it():
    with pytest.raises(ValueError):
        render(Triplet("Person 1", "flies", None))
    with pytest.raises(ValueError):
        render(Triplet("Person 1", "moves", "sideways"))


def test_pose_hysteresis(tmp_path):
    ang = [5, 6, 20, 31, 35, 28, 22, 28, 33, 14, 9, 12, 16, 8]
    frames = np.arange(1, len(ang) + 1)
    ch = pose_changes(frames, ang, open_above=30, close_below=10)
    # 22 and 28 inside the band do not close it; 14 and 12/16 do not reopen it
    assert [(f, v) for f, v, _ in ch] == [(4, "opens"), (11, "closes")]
    p = tmp_path / "PRED.csv"
    p.write_text("image,tip_open,tip_open_std,roll,roll_std\n" + "".join(
        f"frame_{i:04d}.png,{a},1.0,0,0\n" for i, a in zip(frames, ang)))
    fr, a, col = read_pose(p)
    assert col == "tip_open" and list(fr) == list(frames)
    out = describe(np.zeros((0, 10)), pose=(fr, a), open_above=30, close_below=10)
    assert sentences(out) == ["Tool opens at frame 4.", "Tool closes at frame 11."]


def test_pose_automatic_thresholds_ignore_a_still_jaw():
    frames = np.arange(1, 200)
    rng = np.random.default_rng(0)
    still = 40 + rng.normal(0, 1.5, frames.size)  # held open, GP noise only
    assert pose_changes(frames, still) == []
    moving = np.where((frames // 50) % 2 == 0, 10.0, 60.0) + rng.normal(0, 1.5, frames.size)
    assert [v for _, v, _ in pose_changes(frames, moving)] == ["opens", "closes", "opens"]


def test_cli_describe(tmp_path, run_cli):
    res = tmp_path / "results.txt"
    ev = tmp_path / "events.jsonl"
    write_mot(res, scene())
    write_events(ev, [{"type": "merge", "frame": 40, "tracks": [2, 3], "group": 9}])
    code, out, err = run_cli("describe", res, "--events", ev, "--size", "640x480")
    assert code == 0, err
    lines = out.strip().splitlines()
    assert "Person 2 and person 3 merge into one group at frame 40." in lines
    assert all(line.endswith(".") for line in lines)
    code, out, err = run_cli("describe", res, "--json")
    assert code == 0, err
    data = json.loads(out)
    assert {"subject", "verb", "adjective", "object", "frames", "tracks", "sentence"} <= set(data[0])
    enter = [d for d in data if d["verb"] == "enters"]
    assert enter and enter[0]["tracks"] == [1] and enter[0]["adjective"] == "left"


def test_cli_describe_bad_input(tmp_path, run_cli):
    code, out, err = run_cli("describe", tmp_path / "missing.txt")
    assert code == 2 and "missing.txt" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    bad = tmp_path / "bad.txt"
    bad.write_text("1,1,10,10,20,20,1,-1,-1,-1\n2,1,ten,10,20,20,1,-1,-1,-1\n")
    code, out, err = run_cli("describe", bad)
    assert code == 2 and "bad.txt:2" in err
    res = tmp_path / "r.txt"
    write_mot(res, scene())
    ev = tmp_path / "ev.jsonl"
    ev.write_text('{"type": "enter", "frame": 3}\n')
    code, out, err = run_cli("describe", res, "--events", ev)
    assert code == 2 and "ev.jsonl:1" in err
    for line, needle in (('{"type": "enter", "frame": 3, "tracks": [99], "side": "left"}', "track 99"),
                         ('{"type": "enter", "frame": 100000, "tracks": [1], "side": "left"}', "after the results end"),
                         ('{"type": "merge", "frame": 3, "end_frame": 9000000, "tracks": [1, 2]}', "ends at frame 9000000")):
        ev.write_text(line + "\n")  # (events of other results: not a person 99 entering)
        code, out, err = run_cli("describe", res, "--events", ev)
        assert code == 2 and "ev.jsonl" in err and needle in err and err.count("\n") == 1
    pose = tmp_path / "PRED.csv"
    pose.write_text("image,roll,roll_std\na.png,1,0\n")
    code, out, err = run_cli("describe", res, "--pose", pose)
    assert code == 2 and "PRED.csv" in err and "open" in err
    code, out, err = run_cli("describe", res, "--pose-track", "99")
    assert code == 2 and "--pose-track 99" in err
    code, out, err = run_cli("describe", res, "--size", "640by480")
    assert code == 2 and "--size" in err
    code, out, err = run_cli("describe", res, "--class", "3=")
    assert code == 2 and "--class" in err
    last = int(scene()[:, 0].max())
    pose.write_text("image,opening,opening_std\n" + "".join(f"{last + k:06d}.png,{10 * k},1\n" for k in range(1, 21)))
    code, out, err = run_cli("describe", res, "--pose", pose)    # (the code before: "Tool closes at frame ...")
    assert code == 2 and "PRED.csv" in err and "not within the results' frames" in err and err.count("\n") == 1
    dup = tmp_path / "dup.txt"    # the second box of a track on a frame was dropped unsaid
    dup.write_text("1,1,10,10,20,20,1,-1,-1,-1\n1,1,50,10,20,20,1,-1,-1,-1\n")
    code, out, err = run_cli("describe", dup)
    assert code == 2 and "dup.txt" in err and "id 1 appears more than once in frame 1" in err



def test_cli_describe_refuses_what_it_would_guess(tmp_path, run_cli):
    """Inputs that contradict themselves or name what is not there were taken without a word: an
    events line with a key twice (the last value won), a track given two classes (the last won),
    a class for a track the results do not hold (ignored), the image column or a std column as the
    opening angle (read as NaN, or a std read as an angle), detections (id -1) told as person -1."""
    res = tmp_path / "r.txt"
    write_mot(res, scene())
    ev = tmp_path / "ev.jsonl"
    ev.write_text('{"type": "enter", "frame": 12, "tracks": [1], "side": "left", "frame": 13}\n')
    pose = tmp_path / "PRED.csv"
    pose.write_text("image,opening,opening_std\n" + "".join(f"{k:06d}.png,{10 * k},1\n" for k in range(1, 21)))
    dets = tmp_path / "det.txt"
    dets.write_text("".join(f"{f},-1,{10 + f},10,20,40,0.9,-1,-1,-1\n" for f in range(1, 11)))
    for args, needle in (((res, "--events", ev), "ev.jsonl:1: not JSON: key 'frame' given twice in one object"),
                         ((res, "--class", "1=tool", "--class", "1=car"), "track 1 was given the class 'tool' already"),
                         ((res, "--class", "tool", "--class", "car"), "every track was given the class 'tool' already"),
                         ((res, "--class", "999=tool"), "--class 999=tool: no such track in the results"),
                         ((res, "--pose", pose, "--pose-column", "image"), "PRED.csv:1: not an angle column: 'image'"),
                         ((res, "--pose", pose, "--pose-column", "opening_std"), "not an angle column: 'opening_std'"),
                         ((dets,), "det.txt: id -1 on 10 rows: MOTChallenge's 'no identity'")):
        code, out, err = run_cli("describe", *args)
        assert code == 2 and needle in err and err.count("\n") == 1, (args, err)
    code, out, err = run_cli("describe", res, "--class", "1=tool", "--class", "1=tool", "--class", "cart")
    assert code == 0 and "Tool 1" in out, err
    gt17 = tmp_path / "gt17.txt"     # MOT16/17 ground truth: track 7 is a car, left out of what is described
    gt17.write_text("".join(f"{f},1,{10 + f},10,20,40,1,1,1.0\n{f},7,{50 + f},10,20,40,1,3,1.0\n" for f in range(1, 9)))
    code, out, err = run_cli("describe", gt17, "--class", "7=car")
    assert code == 2 and "--class 7=car: no such track among the pedestrians described" in err, err
    # an angle named '..._std' is an angle when its own std column is there (pose train takes it)
    pose.write_text("image,open_std,open_std_std\n" + "".join(f"{k:06d}.png,{10 * k},1\n" for k in range(1, 21)))
    code, out, err = run_cli("describe", res, "--pose", pose, "--pose-column", "open_std")
    assert code == 0, err
    code, out, err = run_cli("describe", res, "--pose", pose, "--pose-column", "open_std_std")
    assert code == 2 and "not an angle column: 'open_std_std' (angle columns: open_std)" in err, err


def test_parse_classes():
    assert parse_classes(["tool", "2=cart"]) == ("tool", {2: "cart"})
    assert parse_classes(["tool", "2=cart", "tool", "2=cart"]) == ("tool", {2: "cart"})
    for bad in (["x=cart"], [""], ["car1"], ["2=car1"], ["2=a=b"]):  # a bare name is checked like ID=NAME's
        with pytest.raises(InputError, match="expected NAME or ID=NAME"):
            parse_classes(bad)


def test_three_walking_together_form_one_group():
    f = np.arange(1, 61)
    rows = []
    for tid, dy in ((1, 0), (2, 30), (3, 60)):
        rows += box_rows(tid, f, 100 + 4 * f, np.full(60, 150 + dy))
    out = describe(np.array(rows, float), image_size=(W, H))
    together = [t for t in out if t.verb == "walk together"]
    assert len(together) == 1, sentences(out)
    assert together[0].tracks == [1, 2, 3]
    assert together[0].sentence == "Person 1, person 2 and person 3 walk together right from frame 1 to frame 60."


def test_move_towards_each_other_and_apart():
    """Two tools close in from either side, meet, and part; a third one walks past a still one."""
    f = np.arange(1, 121)
    meet = np.r_[np.linspace(0, 1, 60), np.linspace(1, 0, 60)]
    rows = box_rows(1, f, 100 + 200 * meet, np.full(120, 200), w=50, h=50)
    rows += box_rows(2, f, 500 - 200 * meet, np.full(120, 200), w=50, h=50)
    rows += box_rows(3, f, np.full(120, 300), np.full(120, 400), w=50, h=50)  # still
    rows += box_rows(4, f, np.linspace(0, 590, 120), np.full(120, 420), w=50, h=50)  # passes track 3
    out = describe(np.array(rows, float), classes=("tool", {}), image_size=(W, H))
    pairs = [(t.verb, t.frames) for t in out if t.verb in ("move towards each other", "move apart")]
    assert [v for v, _ in pairs] == ["move towards each other", "move apart"]
    (_, (a0, a1)), (_, (b0, b1)) = pairs
    assert a0 < 20 and 50 <= a1 <= 62 and 58 <= b0 <= 70 and b1 > 100
    assert "Tool 1 and tool 2 move towards each other" in next(t.sentence for t in out if t.verb == "move towards each other")
    assert not any(set(t.tracks) & {3, 4} for t in out if t.verb in ("move towards each other", "move apart"))


def test_describe_api_checks_what_the_command_line_checks():
    """The API is given arrays no file reader checked: a NaN once turned "moves left" into "moves
    upwards", a negative frame rate said negative times, and an event without a frame raised KeyError."""
    rows = scene()
    rows[5, 3] = np.nan
    for bad, kw, needle in ((rows, {}, "NaN"),
                            (scene()[:, :4], {}, "shape"),
                            (np.vstack([scene(), scene()[:1]]), {}, "more than once"),
                            (scene(), {"fps": -25.0}, "fps"),
                            (scene(), {"fps": float("nan")}, "fps"),
                            (scene(), {"image_size": (0, 480)}, "image size must be"),
                            (scene(), {"image_size": (64, 48)}, r"centre \(\d+, \d+\) lies far outside the 64x48"),
                            (scene(), {"classes": "person"}, "classes")):
        with pytest.raises(InputError, match=needle):
            describe(bad, **kw)
    with pytest.raises(InputError, match="event 1: an event needs keys"):
        describe(scene(), [{"type": "enter", "tracks": [1]}])
    huge = scene()
    huge[:, 0] *= 1e15
    with pytest.raises(InputError, match="frames must be whole numbers"):
        describe(huge)


def test_writers_never_write_what_their_readers_refuse(tmp_path):
    from artmotion.io import read_events, read_mot

    rows = scene()
    rows[3, 3] = np.nan
    with pytest.raises(InputError, match="NaN"):
        write_mot(tmp_path / "r.txt", rows)
    with pytest.raises(InputError, match="track ids must be whole"):
        write_mot(tmp_path / "r.txt", np.array([[1, 2.5, 0, 0, 10, 10, 1]]))
    with pytest.raises(InputError, match="event 2 for"):
        write_events(tmp_path / "e.jsonl", [{"type": "enter", "frame": 1, "tracks": [1]}, 2])
    with pytest.raises(InputError, match="'frame' must be"):
        write_events(tmp_path / "e.jsonl", [{"type": "enter", "frame": float("nan"), "tracks": [1]}])
    assert list(tmp_path.iterdir()) == []
    write_mot(tmp_path / "r.txt", scene())
    write_events(tmp_path / "e.jsonl", [{"type": "enter", "frame": 1, "tracks": [1]}])
    assert len(read_mot(tmp_path / "r.txt")) == len(scene()) and len(read_events(tmp_path / "e.jsonl")) == 1


def test_cli_describes_only_the_people_of_mot16_ground_truth(tmp_path, run_cli):
    """MOT16/17 ground truth (9 columns: consider, class, visibility) holds occluders, distractors
    and reflections: they were described as people ("Person 25 stays in place", an occluder)."""
    gt = tmp_path / "gt.txt"
    lines = []
    for f in range(1, 21):
        lines.append(f"{f},1,{100 + 5 * f},200,50,120,1,1,1.0")     # a pedestrian walking right
        lines.append(f"{f},2,600,220,60,130,0,9,1.0")                # an occluder (consider 0)
        lines.append(f"{f},3,{400 - 5 * f},210,50,120,1,12,0.8")     # a reflection
    gt.write_text("\n".join(lines) + "\n")
    code, out, err = run_cli("describe", gt, "--size", "1920x1080", "--fps", "30")
    assert code == 0, err
    assert "20 of 60 rows described" in err
    assert "Person 1" in out and "Person 2" not in out and "Person 3" not in out, out


def test_read_pose_refuses_a_repeated_row_and_non_finite_columns(tmp_path):
    """A row of PRED.csv given twice shifted every later frame by one (the frames fell back to row
    numbers), and NaN or infinity in a column describe does not read was taken in silence."""
    rows = [f"frame_{i:04d}.png,{10 * i},1.0,0,0.5\n" for i in range(1, 8)]
    head = "image,tip_open,tip_open_std,roll,roll_std\n"
    p = tmp_path / "PRED.csv"
    p.write_text(head + "".join(rows[:3] + [rows[2]] + rows[3:]))
    with pytest.raises(InputError, match=r"image 'frame_0003.png' twice \(lines 4 and 5\)"):
        read_pose(p)
    for bad in ("inf", "nan", "-1"):          # roll: any finite angle; a std: not negative
        p.write_text(head + "".join(rows[:2]) + f"frame_0003.png,30,1.0,{bad if bad != '-1' else 0},"
                     f"{bad if bad == '-1' else 0.5}\n" + "".join(rows[3:]))
        with pytest.raises(InputError, match="roll"):
            read_pose(p)
    p.write_text(head + "".join(rows))
    assert list(read_pose(p)[0]) == list(range(1, 8))
