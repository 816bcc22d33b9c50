"""The Python API of the less-used modules with odd arguments (a QA pass, thirty-fourth session):
each case was a silently wrong result, or an error that blamed something else."""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest

from artmotion.errors import InputError


def test_describe_reads_a_generator_of_events_once():
    """The events were checked in one pass and told in a second, which found the generator empty."""
    from artmotion.language.describe import describe

    rows = np.array([[f, 1, 10 + 5 * f, 100, 30, 80, 1, -1, -1, -1] for f in range(1, 41)]
                    + [[f, 2, 400 - 3 * f, 120, 30, 80, 1, -1, -1, -1] for f in range(1, 41)], float)
    evs = [{"type": "enter", "frame": 1, "tracks": [1], "side": "left"},
           {"type": "exit", "frame": 40, "tracks": [2], "side": "left"}]
    assert [t.sentence for t in describe(rows, iter(evs))] == [t.sentence for t in describe(rows, evs)]
    with pytest.raises(InputError, match="events must be a list"):
        describe(rows, 5)


def _run_folder(root):
    import json

    d = root / "r"
    d.mkdir()
    (d / "run.json").write_text(json.dumps({
        "name": "r", "source": "/videos/r.mp4", "sequence": {"length": 50, "fps": 25.0, "width": 640, "height": 480},
        "track_summary": [{"id": 1, "first_frame": 1, "last_frame": 50, "boxes": 50}], "events": [],
        "sentences": [{"sentence": "Person 1 stays in place (frames 1-50).", "subject": "person", "verb": "stays",
                       "adjective": None, "tracks": [1], "frame_start": 1, "frame_end": 50}]}))
    return d


def test_index_add_runs_reads_a_generator_once_and_checks_its_items(tmp_path):
    from artmotion.app import EventIndex, load_run

    run = _run_folder(tmp_path)
    with EventIndex(tmp_path / "i.sqlite") as idx:
        assert len(idx.add_runs(iter([(run, load_run(run))]))) == 1   # (was [] and nothing added)
        assert [v["name"] for v in idx.videos()] == ["r"]
        for bad in (["dir"], [(run, "abc")], [(run,)]):
            with pytest.raises(InputError, match="runs item 1"):
                idx.add_runs(bad)


def test_index_search_takes_a_path_and_names_what_is_wrong(tmp_path):
    """A pathlib.Path as video was SQLite's binding error, reported as "damaged index ... build a
    new one"; so was a number, and a search from another thread."""
    from artmotion.app import EventIndex

    run = _run_folder(tmp_path)
    with EventIndex(tmp_path / "i.sqlite") as idx:
        idx.add_run(run)
        from pathlib import Path

        assert idx.search("person stays", video=Path("/videos/r.mp4"))
        with pytest.raises(InputError, match="video must be a name or a source path, got int"):
            idx.search("person stays", video=3)
        got = []

        def other():
            try:
                idx.search("person stays")
            except InputError as exc:
                got.append(str(exc))

        t = threading.Thread(target=other)
        t.start()
        t.join()
        assert got and "opened in another thread" in got[0] and "damaged" not in got[0]


@pytest.mark.parametrize("call", [
    lambda tmp: __import__("artmotion.app.pipeline", fromlist=["x"]).run_pipeline(tmp / "none", tmp / "o", video="no"),
    lambda tmp: __import__("artmotion.app.index", fromlist=["x"]).EventIndex(tmp / "n.sqlite", write="no"),
    lambda tmp: __import__("artmotion.pose.render", fromlist=["x"]).write_dataset(tmp / "d", 2, dark="no"),
    lambda tmp: __import__("artmotion.pose.render", fromlist=["x"]).write_dataset(tmp / "d", 2, frames="no"),
    lambda tmp: __import__("artmotion.pose.render", fromlist=["x"]).render_sequence(3, dark="no"),
    lambda tmp: __import__("artmotion.articulation", fromlist=["x"]).fit_trajectory(tmp / "drawer.log", time="no"),
    lambda tmp: __import__("artmotion.tracking.metrics", fromlist=["x"]).evaluate(np.ones((1, 6)), np.ones((1, 6)),
                                                                                   per_alpha="no"),
    lambda tmp: __import__("artmotion.tracking.metrics", fromlist=["x"]).evaluate_sequences(
        [(np.ones((1, 6)), np.ones((1, 6)))], per_alpha="no"),
])
def test_switches_given_text_are_refused(tmp_path, call):
    """"no" is true to Python: each of these left its switch on (annotated video, a writable index
    created, dark renders, frames written)."""
    with pytest.raises(InputError, match="must be True or False"):
        call(tmp_path)
    assert not (tmp_path / "n.sqlite").exists() and not (tmp_path / "d").exists()


@pytest.mark.parametrize("kw", [{"n": 0}, {"n": 2.5}, {"n": 3, "motion": "x"}, {"n": 3, "scenes": 0},
                                {"n": 3, "seed": -1}, {"n": 3, "style": 5}])
def test_render_sequence_checks_its_arguments_at_the_call(kw):
    """They were checked only at the first next() (cv2.error, KeyError, IndexError), or not at all."""
    from artmotion.pose.render import render_sequence

    with pytest.raises(InputError):
        render_sequence(**kw)


def test_tool_tracker_checks_its_settings_and_its_detections():
    from artmotion.tracking.instruments.track import ToolTracker

    class Fake:
        def __init__(self, rows):
            self.rows = rows

        def detect(self, frame):
            return np.array(self.rows, dtype=float)

    for kw in ({"klt": "no"}, {"gate": -1}, {"birth": 2}, {"coast": -1}, {"max_miss": 2.5}, {"merge": np.inf},
               {"accel": float("nan")}):
        with pytest.raises(InputError):
            ToolTracker(Fake([]), **kw)
    with pytest.raises(InputError, match="detect"):
        ToolTracker(None)
    frame = np.zeros((64, 96, 3), np.uint8)
    for rows in ([[30.0, 20, -5, 0.5, 0.7]], [[30.0, 20, 5, 0.5, 7.0]], [[3e6, 20, 5, 0.5, 0.7]]):
        with pytest.raises(InputError, match="positive size"):
            ToolTracker(Fake(rows)).update(frame)


def test_a_detector_returning_rows_of_another_length_is_refused():
    """(4, 3) boxes were re-cut into three boxes of four numbers."""
    from artmotion.tracking.detectors import Detector

    class Mine(Detector):
        def detect(self, frame):
            return np.arange(1, 13.0).reshape(4, 3), [0.9, 0.8, 0.7]

    with pytest.raises(InputError, match=r"boxes must be an \(N, 4\) array"):
        Mine()(np.zeros((100, 100, 3), np.uint8))


def test_crop_box_refuses_a_box_that_is_not_finite():
    """A NaN box cropped the whole width."""
    from artmotion.pose.features import crop_box

    frame = np.zeros((100, 100, 3), np.uint8)
    for box in ((np.nan, 10, 20, 20), (10, 10, np.inf, 20), (1, 2, 3)):
        with pytest.raises(InputError, match="box must be 4 finite numbers"):
            crop_box(frame, box)
    assert crop_box(frame, (10, 10, 20, 30)).shape == (30, 20, 3)


def test_hog_and_lbp_take_crops_in_their_documented_range():
    """uint8 crops wrapped around in HOG's gradients (0.40 off), 0-255 floats saturated LBP, a cell
    of 0 divided by zero: each gave numbers, or an error from deep inside."""
    from artmotion.pose.features import hog_batch, lbp_batch

    B = np.random.default_rng(0).random((2, 48, 64, 3)).astype(np.float32)
    for f in (hog_batch, lbp_batch):
        for bad in ((B * 255).astype(np.uint8), B * 255, B[..., :1], B[0]):
            with pytest.raises(InputError, match="crops must"):
                f(bad)
        for cell in (0, -8, 100, 2.5):
            with pytest.raises(InputError, match="cell must be"):
                f(B, cell=cell)
        assert np.isfinite(f(B)).all()


def test_box_views_never_gives_infinities():
    from artmotion.pose.features import box_views

    for boxes, size in (([[1e308] * 4], (640, 480)), ([[1, 1, 1e-300, 1e-300]], (1e-300, 1e-300)),
                        ([[1, 1, 5, 5]] * 3, [[640, 480]] * 2), ([[1, 2, 3, 4, 5]], (640, 480))):
        with pytest.raises(InputError):
            box_views(boxes, size)
    assert np.isfinite(box_views([[1, 1, 1e-300, 5]], (640, 480))).all()


def test_point_tracks_checks_its_settings():
    from artmotion.articulation.video.tracks import point_tracks

    frames = [np.zeros((40, 40), np.uint8)] * 3
    for kw in ({"fps": "25"}, {"reseed": 0}, {"max_points": 0}, {"fb_max": float("nan")}, {"min_eig": -1},
               {"spacing": -1}):
        with pytest.raises(InputError):
            point_tracks(frames, **{"fps": 25.0, **kw})


def test_more_odd_arguments_are_input_errors(tmp_path):
    """Each was a bare KeyError, AttributeError, TypeError or NumPy ValueError from deep inside."""
    from artmotion.app import EventIndex
    from artmotion.app.pipeline import run_pipeline
    from artmotion.language.describe import describe, events_from_tracks

    rows = np.array([[f, 1, 10 + 5 * f, 100, 30, 80, 1, -1, -1, -1] for f in range(1, 11)], float)
    assert describe(rows, [], image_size=np.array([640, 480]))       # (an array: "ambiguous")
    for size in (640, "ab", (0, 480)):
        with pytest.raises(InputError, match="image size must be"):
            describe(rows, [], image_size=size)
    for bad in (rows[:, :3], np.where(rows == 1, np.nan, rows), "text"):
        with pytest.raises(InputError):
            events_from_tracks(bad, (640, 480))
    with pytest.raises(InputError, match="image size must be"):
        events_from_tracks(rows, (0, 0))
    run = _run_folder(tmp_path)
    with EventIndex(tmp_path / "i.sqlite") as idx:
        with pytest.raises(InputError, match="corrupt manifest: no 'track_summary'"):
            idx.add_run(run, run={"name": "x"})
    with pytest.raises(InputError, match="object_class must be a class name"):
        run_pipeline(tmp_path / "none", tmp_path / "o", object_class=3)


def test_a_zero_direction_is_no_direction():
    """A prismatic joint along [0, 0, 0] predicted its origin for every q."""
    from artmotion.articulation.models import PrismaticModel, RevoluteModel

    with pytest.raises(InputError, match="direction must be a direction, not a zero vector"):
        PrismaticModel(origin=[0, 0, 0], direction=[0, 0, 0])
    with pytest.raises(InputError, match="axis must be a direction"):
        RevoluteModel(centre=[0, 0, 0], axis=[0, 0, 0], radius=1.0, u=[1, 0, 0])
    assert np.allclose(PrismaticModel(origin=[0, 0, 0], direction=[0, 0, 2]).predict([1.0]), [[0, 0, 1]])


def test_odd_use_of_fitted_things_is_an_input_error():
    from artmotion.articulation.online import OnlineEstimator
    from artmotion.language.grounding.model import Grounder

    with pytest.raises(InputError, match="no fitted model 'static'"):
        OnlineEstimator().fitted("static")
    with pytest.raises(InputError, match="Grounder is not fitted"):
        Grounder().speech_to_visual(np.zeros(3), np.zeros(3))
    with pytest.raises(InputError, match="feature dictionary"):
        Grounder().fit({})


def test_a_drawer_log_read_with_time_given_as_text_is_refused(tmp_path):
    """time="no" was true: the first column was read as time and a drawer came out undecided."""
    from artmotion.articulation import fit_trajectory

    log = tmp_path / "drawer.log"
    log.write_text("".join(f"{0.01 * i:.2f} 0 0\n" for i in range(12)))
    assert fit_trajectory(log, time=False)["model"] == "prismatic"
    with pytest.raises(InputError, match="time must be True or False"):
        fit_trajectory(log, time="no")


def test_pose_predict_return_std_and_zero_feature_columns():
    """return_std="no" returned the tuple; a matrix of no columns was fitted (predicting the
    labels' mean for anything)."""
    from artmotion.pose.model import PoseRegressor

    rng = np.random.default_rng(0)
    X, y = rng.normal(size=(12, 3)), rng.uniform(0, 1, (12, 1))
    reg = PoseRegressor().fit(X, y)
    assert reg.predict(X[:2]).shape == (2, 1)
    with pytest.raises(InputError, match="return_std must be True or False"):
        reg.predict(X[:2], return_std="no")
    with pytest.raises(InputError, match="no columns"):
        PoseRegressor().fit(np.zeros((12, 0)), y)


def test_beliefs_and_likelihoods_must_be_symmetric():
    """A covariance [[1, 5], [0, 1]] passed (determinant 1) and fused into one that is not
    positive definite; gaussian_loglik read one triangle of S only."""
    from artmotion.filters import gaussian_loglik
    from artmotion.tracking.experts import Gaussian, belief_problem
    from artmotion.tracking.pote import fuse

    odd = Gaussian([1.0, 0.0], [[1.0, 5.0], [0.0, 1.0]])
    with pytest.raises(InputError, match="not symmetric: its off-diagonal entries 5 and 0 differ"):
        fuse([odd])
    assert "not symmetric (off-diagonal entries 5 and 0)" in belief_problem(odd)
    assert belief_problem(Gaussian([1.0, 0.0], [[1.0, 0.2], [0.2, 1.0]])) is None
    with pytest.raises(InputError, match="mean of 2 numbers"):
        Gaussian([1.0, 2.0, 3.0], np.eye(2))
    with pytest.raises(InputError, match="S and its transpose differ by up to 0.9"):
        gaussian_loglik([0.5, 0.1], [[1.0, 0.9], [0.0, 1.0]])
    with pytest.raises(InputError, match="square covariance"):
        gaussian_loglik(np.zeros(0), np.zeros((0, 0)))
    # symmetric only to float32's rounding (J P J^T): accepted, by the filter's fusion too
    J = np.array([[1.3, 0.4], [-0.7, 2.1]], np.float32)
    C = J @ np.array([[4.0, 1.1], [1.1, 3.0]], np.float32) @ J.T
    assert np.isfinite(gaussian_loglik(np.zeros(2, np.float32), C))
    assert belief_problem(Gaussian([10.0, 20.0], C)) is None and fuse([Gaussian([10.0, 20.0], C)]) is not None
    with pytest.raises(InputError, match="too far out"):       # (was -inf for m > 1, an error for m = 1)
        gaussian_loglik(np.array([1e200, 0.0]), np.eye(2))
    with pytest.raises(InputError, match="must hold 2 values"):
        gaussian_loglik(np.array([[0.5], [0.1]]), np.eye(2))
    with pytest.raises(InputError, match="real numbers"):
        gaussian_loglik(np.array(["0.5", "0.1"]), np.eye(2))
    with pytest.raises(InputError, match="square covariance"):
        gaussian_loglik(np.zeros(3), np.zeros((3, 2)))
    assert gaussian_loglik([0.0, 0.0], np.eye(2)) == pytest.approx(-np.log(2 * np.pi))


def test_pose_filter_step_and_views_take_numbers_only():
    """step() parsed text and dropped an imaginary part (filter() refused both); views and
    keypoints given as text crashed inside NumPy."""
    from artmotion.pose.filter import PoseFilter
    from artmotion.pose.model import check_keypoints, check_views

    for mean, std in ((["10", "20"], ["1", "1"]), (np.array([10 + 5j, 20]), [1, 1])):
        with pytest.raises(InputError, match="mean must be an array of numbers"):
            PoseFilter([1.0, 1.0]).step(mean, std)
    with pytest.raises(InputError, match="std must be an array of numbers"):
        PoseFilter([1.0, 1.0]).step([10, 20], ["a", "b"])
    np.testing.assert_allclose(PoseFilter([1.0, 1.0]).step([10, 20], [1, 1])[0], [10, 20])
    with pytest.raises(InputError, match="views must be an array of numbers"):
        check_views("abc", 2)
    with pytest.raises(InputError, match="keypoints must be an array of numbers"):
        check_keypoints("abc", 2)


def test_grounding_features_of_no_dimensions_and_an_unfitted_scaler():
    from artmotion.language.grounding.sparse import BlockScaler, PairedSparse

    with pytest.raises(InputError, match="no dimensions"):
        PairedSparse().fit(np.zeros((12, 0)), np.ones((12, 2)))
    with pytest.raises(InputError, match="BlockScaler is not fitted"):
        BlockScaler().transform(np.ones((2, 2)))
    np.testing.assert_allclose(BlockScaler().fit(np.eye(2)).transform(np.eye(2)).sum(axis=0), 0.0, atol=1e-12)


def test_box_helpers_refuse_rows_that_are_not_boxes():
    """A MOTChallenge row (10 columns) was read as the box frame, id, x, y (box_area 5000, iou 1);
    a box of 3 numbers was broadcast; clip_box with no width did not clip; fit_size took a
    negative width."""
    from artmotion.geometry import box_area, box_center, box_from_center, clip_box, fit_size, intersection, iou

    mot = np.array([[1, 7, 100.0, 50, 20, 40, 0.9, -1, -1, -1]])
    for call in (lambda: box_area(mot), lambda: iou(mot, mot), lambda: box_center([[0, 0, 10]]),
                 lambda: intersection(mot, mot), lambda: box_from_center([1, 2, 3], [4, 5])):
        with pytest.raises(InputError, match="shape"):
            call()
    with pytest.raises(InputError, match="must be numbers"):
        box_area(["a", "b", "c", "d"])
    for w, h in ((None, 480), (np.nan, 480), (640, -1)):
        with pytest.raises(InputError, match="clip_box"):
            clip_box([700, 0, 10, 10], w, h)
    for args in ((-640, 480, 320, 240), (np.nan, 480, 320, 240), (640, 480, 0, 240)):
        with pytest.raises(InputError, match="fit_size"):
            fit_size(*args)
    np.testing.assert_allclose(clip_box([600, -5, 100, 20], 640, 480), [600, 0, 40, 15])
    assert fit_size(640, 480, 320, 240) == (0.5, (320, 240))
    assert box_area(np.zeros((0, 4))).shape == (0,) and box_area(np.zeros(0)).shape == (0,)
    assert iou([0, 0, 10, 10], [0, 0, 10, 10]) == 1.0


def test_track_and_report_never_write_over_their_inputs(tmp_path):
    """track(video=...) replaced the input video (or gt.txt, det.txt) with the annotated one, and
    write_report an input video with its page: the CLI refused both, the Python API did not."""
    import shutil

    from artmotion.app.report import write_report
    from artmotion.io.sequence import open_sequence
    from artmotion.tracking import track

    seq_dir = tmp_path / "TUD-Campus"
    shutil.copytree(Path(__file__).resolve().parents[1] / "data" / "TUD-Campus", seq_dir)
    before = {p: p.read_bytes() for p in seq_dir.rglob("*") if p.is_file()}
    for victim in [p for p in before if p.suffix in (".mp4", ".txt", ".ini")]:
        with pytest.raises(InputError, match="is also an input|inside the input folder"):
            track(seq_dir, video=victim)
        with pytest.raises(InputError, match="is also an input|inside the input folder"):
            write_report(victim, open_sequence(seq_dir), np.zeros((0, 10)), {"events": []})
    assert {p: p.read_bytes() for p in seq_dir.rglob("*") if p.is_file()} == before


def test_part_video_leaves_a_file_it_cannot_write_as_it_was(tmp_path):
    """A name OpenCV has no writer for left the user's file empty and returned success."""
    from artmotion.articulation.synthetic import part_video

    notes = tmp_path / "notes.txt"
    notes.write_text("my notes\n")
    with pytest.raises(InputError, match="cannot write an MJPG video"):
        part_video(notes, frames=6, size=(64, 48))
    assert notes.read_text() == "my notes\n" and sorted(tmp_path.iterdir()) == [notes]
    with pytest.raises(InputError, match="unknown motion"):
        part_video(tmp_path / "v.avi", "wobble")
    assert part_video(tmp_path / "v.avi", frames=6, size=(64, 48)).stat().st_size > 0


def test_an_index_that_fails_while_it_is_created_leaves_nothing(tmp_path, monkeypatch):
    """EventIndex(path) made the file in place: a failure part-way left a file that was no index
    (every later command then refused it), and the folders it had made."""
    import artmotion.app.index as index

    monkeypatch.setattr(index, "SCHEMA", index.SCHEMA + "\nCREATE TABLE broken (;")
    with pytest.raises(InputError, match="cannot create index"):
        index.EventIndex(tmp_path / "a" / "b" / "new.sqlite")
    assert list(tmp_path.iterdir()) == []
    monkeypatch.undo()
    with index.EventIndex(tmp_path / "a" / "new.sqlite") as idx:
        assert idx.write
    index.check_index(tmp_path / "a" / "new.sqlite")


def test_image_and_figure_writers_name_a_format_they_cannot_write(tmp_path):
    """cv2.error and matplotlib's ValueError, not one line naming the file."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from artmotion.io.atomic import save_figure
    from artmotion.io.media import write_image

    with pytest.raises(InputError, match=r"cannot write \.txt images"):
        write_image(tmp_path / "x.txt", np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(InputError, match=r"cannot write \.xyz figures"):
        save_figure(plt.figure(), tmp_path / "f.xyz")
    assert list(tmp_path.iterdir()) == []
    assert save_figure(plt.figure(), tmp_path / "f.png").stat().st_size > 0


def test_pose_filter_has_its_model_before_the_first_step():
    """F and Q (filterpy's names) existed only after the first step: an AttributeError before."""
    from artmotion.pose.filter import PoseFilter

    f = PoseFilter([1.0, 2.0], dt=0.04)
    np.testing.assert_allclose(f.F, [[1.0, 0.04], [0.0, 1.0]])
    assert f.Q.shape == (2, 2, 2) and f.Q[1, 0, 0] == pytest.approx(2 * f.Q[0, 0, 0])


def test_a_second_video_never_goes_into_a_sequence_of_one_video(tmp_path):
    """track(video=...) and run_pipeline wrote annotated.mp4 into a folder whose single video is
    the sequence (the CLI's track refused): the folder then did not open ("several video files");
    from SEQ/img1 the seqinfo.ini read is the parent's, which an output replaced."""
    import shutil

    from artmotion.app.pipeline import run_pipeline
    from artmotion.io.sequence import open_sequence
    from artmotion.tracking import track

    sample = Path(__file__).resolve().parents[1] / "data" / "TUD-Campus"
    seq_dir = tmp_path / "TUD"
    shutil.copytree(sample, seq_dir)
    assert open_sequence(seq_dir).video_home == seq_dir
    with pytest.raises(InputError, match="inside the input folder"):
        track(seq_dir, video=seq_dir / "annotated.mp4")
    with pytest.raises(InputError, match="inside the input folder"):
        run_pipeline(seq_dir, seq_dir)
    assert open_sequence(seq_dir).length == 71 and not (seq_dir / "annotated.mp4").exists()
    mot = tmp_path / "MOT"
    (mot / "img1").mkdir(parents=True)
    import cv2

    cv2.imwrite(str(mot / "img1" / "000001.jpg"), np.zeros((48, 64, 3), np.uint8))
    (mot / "seqinfo.ini").write_text("[Sequence]\nname=MOT\nframeRate=25\nseqLength=1\nimWidth=64\nimHeight=48\n")
    assert open_sequence(mot / "img1").inputs()[-1] == mot / "seqinfo.ini"
    with pytest.raises(InputError, match="is also an input"):
        track(mot / "img1", video=mot / "seqinfo.ini")


def test_review_of_the_new_checks(tmp_path):
    """Valid input the first checks refused, and bad input they let through."""
    from artmotion.app.index import EventIndex
    from artmotion.articulation.synthetic import part_video
    from artmotion.geometry import box_area, box_overlap, clip_box, fit_size
    from artmotion.io.media import write_image

    assert fit_size(640, 480, float("inf"), 240) == (0.5, (320, 240))        # no width limit
    assert fit_size(np.array(640), 480, 320, 240) == (0.5, (320, 240))       # a 0-d array
    np.testing.assert_allclose(clip_box([600, -5, 100, 20], float("inf"), 480), [600, 0, 100, 15])
    with pytest.raises(InputError, match="width must be a number"):
        fit_size(True, 480, 320, 240)
    with pytest.raises(InputError, match=r"got shape \(3, 0\)"):               # rows of no columns
        box_area(np.zeros((3, 0)))
    with pytest.raises(InputError, match="box_overlap"):
        box_overlap([[0, 0], [10, 10]], [0, 0, 10, 10])
    with pytest.raises(InputError, match=r"cannot encode the image as \.png \(a uint8 array of shape \(0, 0, 3\)"):
        write_image(tmp_path / "e.png", np.zeros((0, 0, 3), np.uint8))
    with pytest.raises(InputError, match="frames must be"):
        part_video(tmp_path / "v.avi", frames=0)
    long = tmp_path / ("n" * 233 + ".sqlite")                                 # (its journal's name is too long)
    with EventIndex(long) as idx:
        assert idx.write
    assert sorted(p.name for p in tmp_path.iterdir()) == [long.name]


def test_save_figure_takes_what_matplotlib_writes_whatever_the_backend(tmp_path):
    import subprocess
    import sys

    code = ("import matplotlib.pyplot as plt, sys\nfrom artmotion.io.atomic import save_figure\n"
            "save_figure(plt.figure(), sys.argv[1])")
    done = subprocess.run([sys.executable, "-c", code, str(tmp_path / "x.png")], env={**__import__("os").environ,
                          "MPLBACKEND": "pdf"}, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "x.png").stat().st_size > 0


@pytest.mark.parametrize("make", ["EventIndex", "building"])
def test_an_index_name_leaves_room_for_its_journal(tmp_path, make):
    """Names of 227-247 bytes failed ("unable to open database file": the temporary name plus
    "-journal" was too long); longer ones were made and then failed at the first write."""
    import contextlib

    import artmotion.app.index as index

    def opened(path):
        return index.EventIndex(path) if make == "EventIndex" else index.building(path)

    for n in (233, 247):
        with contextlib.ExitStack() as stack:
            stack.enter_context(opened(tmp_path / ("n" * (n - 7) + ".sqlite")))
    with pytest.raises(InputError, match="at most 247 bytes"):
        with opened(tmp_path / ("n" * 241 + ".sqlite")):
            pass
    assert sorted(len(p.name) for p in tmp_path.iterdir()) == [233, 247]
